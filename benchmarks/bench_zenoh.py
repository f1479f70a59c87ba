"""Benchmark of the Zenoh transport against bare zenoh-python pub/sub, same payload,
measured in the same run.

Usage: ``python benchmarks/bench_zenoh.py [--quick | --smoke]`` (needs ``scart[zenoh]``). Two peer
sessions in this process, connected over a Unix socket: a scart output port published
with :class:`ZenohPublisher` and read with :class:`ZenohSubscription`, against a bare
``declare_publisher``/``declare_subscriber`` pair sending the same bytes (the encoded
youBot status). A third row is bare zenoh-python carrying scart's codec (each sample
encoded before ``put`` and decoded, so checked, in the callback): the floor of a transport
that checks what it receives. Latency is from the write (or ``put``) to the subscriber's
callback, at 100 Hz and 1 kHz on absolute deadlines. Prints one markdown table. Not a test.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "composites" / "youbot"))

from _common import paced, pct, wait_until  # noqa: E402
from youbot_model import JointStatus, YouBotStatus  # noqa: E402

from dataflow import Deployer, OutputPort, TaskContext  # noqa: E402
from scart_wire import codec  # noqa: E402
from dataflow.transports.zenoh import (  # noqa: E402
    ZenohPublisher,
    ZenohSubscription,
    open_session,
)

STATUS = YouBotStatus(joints=[JointStatus(position=0.1 * i, velocity=0.01, current=0.2, temperature=30.5)
                              for i in range(5)], timestamp=1.0, sequence=1)


class Arm(TaskContext):
    status = OutputPort(YouBotStatus)


def bare_pair(a: Any, b: Any, key: str, lock: threading.Lock, with_codec: bool,
              payload: bytes) -> tuple[Callable[[int], None], dict[int, float], dict[int, float], tuple[Any, Any]]:
    """A bare publisher on ``a`` and subscriber on ``b`` for ``key``, matched: ``(send,
    sent, got, (subscriber, publisher))``, ``send(k)`` putting sample ``k`` (``payload``, or
    with ``with_codec`` the status encoded then, and decoded on arrival), ``sent``/``got``
    the times by ``k``."""
    sent: dict[int, float] = {}
    got: dict[int, float] = {}

    def received(sample: Any) -> None:
        if with_codec:
            codec.decode(codec.Value.FromString(sample.payload.to_bytes()))
        k = int.from_bytes(sample.attachment.to_bytes(), "little")
        with lock:
            got[k] = time.perf_counter()

    publisher = a.declare_publisher(key)
    subscriber = b.declare_subscriber(key, received)
    wait_until(lambda: publisher.matching_status.matching, 10)

    def send(k: int) -> None:
        sent[k] = time.perf_counter()
        data = codec.encode(STATUS, YouBotStatus).SerializeToString() if with_codec else payload
        publisher.put(data, attachment=k.to_bytes(8, "little"))

    return send, sent, got, (subscriber, publisher)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer samples")
    parser.add_argument("--smoke", action="store_true", help="a few samples: that every path runs")
    args = parser.parse_args()
    n100, n1k = (20, 100) if args.smoke else (200, 1000) if args.quick else (500, 3000)
    folder = tempfile.TemporaryDirectory()
    here = f"unixsock-stream/{folder.name}/a.sock"
    a = open_session(listen=[here])
    b = open_session(connect=[here], listen=[f"unixsock-stream/{folder.name}/b.sock"])
    rows = []
    try:
        payload = codec.encode(STATUS, YouBotStatus).SerializeToString()
        lock = threading.Lock()
        # bare zenoh-python: the same bytes, one put per sample
        bare_send, sent, got, bare = bare_pair(a, b, "bench/bare", lock, with_codec=False, payload=payload)
        # bare zenoh-python carrying scart's codec: encode each sample, decode (and so check)
        # each one received. No port, no counting: the floor any checked transport stands on.
        codec_send, c_sent, c_got, with_codec = bare_pair(a, b, "bench/codec", lock, with_codec=True, payload=payload)

        # scart: a port published by ZenohPublisher, read by ZenohSubscription
        deployer = Deployer()
        arm = deployer.add(Arm("arm"))
        publisher = ZenohPublisher(deployer, a)
        s_sent: dict[int, float] = {}
        s_got: dict[int, float] = {}

        def on_event(event: object) -> None:
            with lock:
                s_got[event.sequence] = time.perf_counter()  # type: ignore[attr-defined]

        sub = ZenohSubscription(b, "arm", "status", on_event)
        wait_until(lambda: arm.status.write(STATUS) and sub.delivered, 10)  # matched: samples arrive

        def scart_send(k: int) -> None:
            s_sent[arm.status.last_sample()[0] + 1] = time.perf_counter()
            arm.status.write(STATUS)

        for rate, n in ((100.0, n100), (1000.0, n1k)):
            results = {}
            for name, send, s, g in (("bare zenoh-python put → callback", bare_send, sent, got),
                                     ("bare zenoh-python + scart codec (encode, decode)", codec_send, c_sent, c_got),
                                     ("scart ZenohPublisher → ZenohSubscription", scart_send, s_sent, s_got)):
                s.clear()
                g.clear()
                paced(min(50, n), rate, send)  # warm-up
                s.clear()
                g.clear()
                paced(n, rate, send)
                wait_until(lambda s=s, g=g: len(g) >= len(s), 2.0)  # the last ones arrive (or 2 s pass)
                with lock:
                    lat = [g[k] - t for k, t in s.items() if k in g]
                results[name] = (pct(lat, 0.5), pct(lat, 0.99), len(lat))
            base = results["bare zenoh-python put → callback"][0]
            floor = results["bare zenoh-python + scart codec (encode, decode)"][0]
            for name, (p50, p99, count) in results.items():
                rows.append((name, f"{rate:g} Hz", p50, p99, f"{count}/{n}", f"{p50 / base:.2f}", f"{p50 / floor:.2f}"))
        sub.close()
        publisher.close()
        for declared in (*with_codec, *bare):
            declared.undeclare()
    finally:
        b.close()
        a.close()
        folder.cleanup()
    print("\nZenoh transport vs bare zenoh-python (two peer sessions, Unix socket, youBot status payload)\n")
    print("| path | rate | p50 | p99 | received | p50 vs bare | p50 vs bare + codec |")
    print("|---|---|---|---|---|---|---|")
    for name, rate, p50, p99, count, ratio, floor_ratio in rows:
        print(f"| {name} | {rate} | {p50 * 1e6:.1f} µs | {p99 * 1e6:.1f} µs | {count} | {ratio} | {floor_ratio} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
