"""A Foxglove WebSocket client in the standard library only, so that another local user
(:mod:`support.users`) can run it from its source: ``python3 -c SOURCE HOST PORT ORIGIN
SECONDS [PATH]`` with ACTIONS (JSON) on stdin (``PATH``: the request's, default ``/``; a
token goes there as ``/?token=...``). It opens a WebSocket (``foxglove.sdk.v1``; ``ORIGIN`` sent
unless empty), waits for the server's advertisements, sends each action (a JSON op as
text, or ``{"call": SERVICE, "id": N, "body": {...}}`` as a binary service call), reads
for ``SECONDS`` and prints one JSON object: the HTTP status of the handshake, its body if
refused, the JSON messages received, the service call answers by id, the services seen,
whether the actions were sent.
"""

import base64
import json
import os
import select
import socket
import struct
import sys
import time


def frame(opcode, payload):
    """A masked client frame."""
    mask = os.urandom(4)
    n = len(payload)
    head = bytes([0x80 | opcode])
    if n < 126:
        head += bytes([0x80 | n])
    elif n < 65536:
        head += bytes([0x80 | 126]) + struct.pack(">H", n)
    else:
        head += bytes([0x80 | 127]) + struct.pack(">Q", n)
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


class Buffered:
    """A socket read from a buffer first (bytes that came with the handshake's answer)."""

    def __init__(self, sock, data):
        self.sock, self.data = sock, data

    def ready(self, timeout):
        return bool(self.data) or bool(select.select([self.sock], [], [], timeout)[0])

    def recv(self, n):
        if self.data:
            chunk, self.data = self.data[:n], self.data[n:]
            return chunk
        return self.sock.recv(n)


def read_exact(sock, n):
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise EOFError
        data += chunk
    return data


def read_frame(sock):
    b0, b1 = read_exact(sock, 2)
    n = b1 & 0x7F
    if n == 126:
        n = struct.unpack(">H", read_exact(sock, 2))[0]
    elif n == 127:
        n = struct.unpack(">Q", read_exact(sock, 8))[0]
    return b0 & 0x0F, read_exact(sock, n)


def main(host, port, origin, actions, seconds, path="/"):
    out = {"status": None, "messages": [], "calls": {}, "services": {}, "sent": False}
    sock = socket.create_connection((host, port), timeout=5)
    key = base64.b64encode(os.urandom(16)).decode()
    request = (f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
               f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
               "Sec-WebSocket-Protocol: foxglove.sdk.v1, foxglove.websocket.v1\r\n"
               + (f"Origin: {origin}\r\n" if origin else "") + "\r\n")
    sock.sendall(request.encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = sock.recv(4096)
        if not chunk:
            break
        head += chunk
    head, _, rest = head.partition(b"\r\n\r\n")
    out["status"] = int(head.split()[1]) if head else 0
    if out["status"] != 101:
        out["body"] = rest.decode(errors="replace")
        print(json.dumps(out))
        return
    sent = False
    deadline = time.monotonic() + seconds
    reader = Buffered(sock, rest)
    started = time.monotonic()
    while time.monotonic() < deadline:
        if not sent and (out["services"] or time.monotonic() - started > 1.0):
            for action in actions:
                if "call" in action:
                    service = out["services"].get(action["call"])
                    if service is None:
                        out["calls"][str(action["id"])] = "no such service advertised"
                        continue
                    body = json.dumps(action["body"]).encode()
                    sock.sendall(frame(2, struct.pack("<BIII", 2, service, action["id"], 4) + b"json" + body))
                else:
                    sock.sendall(frame(1, json.dumps(action).encode()))
            sent = out["sent"] = True
        if not reader.ready(0.1):
            continue
        try:
            opcode, payload = read_frame(reader)
        except (EOFError, OSError):
            break
        if opcode == 1:
            message = json.loads(payload)
            out["messages"].append(message)
            if message.get("op") == "advertiseServices":
                out["services"].update({s["name"]: s["id"] for s in message["services"]})
            if message.get("op") == "serviceCallFailure":
                out["calls"][str(message["callId"])] = {"failure": message["message"]}
        elif opcode == 2 and payload[:1] == b"\x03":
            _service, call, size = struct.unpack_from("<III", payload, 1)
            out["calls"][str(call)] = json.loads(payload[13 + size:])
        elif opcode == 8:
            break
    sock.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3], json.loads(sys.stdin.read() or "[]"), float(sys.argv[4]),
         *sys.argv[5:6])
