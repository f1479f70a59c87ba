"""ipc's connections at the side that asked for them (private): a link going out (the
carrier of its writer end; reports come back) and a subscription coming in (frames into
the reader ends of its shared feed). Both are read by the process's one io thread."""

from __future__ import annotations

import socket
import threading

from dataflow.transports import frames
from dataflow.transports._shared import SharedFeed
from dataflow.transports.ends import WriterEnd
from dataflow.transports.ipc._hub import Conn, Encode, Hub
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb

__all__ = ["LinkOut", "SubIn"]


class LinkOut(Conn):
    """A link going out: the carrier of its writer end; reports come back."""

    def __init__(self, hub: Hub, sock: socket.socket, end: WriterEnd) -> None:
        super().__init__(hub, sock, end.label)
        self.encode: Encode = frames.encoder(end.port.type)
        self.end = end
        self.final = threading.Event()

    send = Conn.send_sample  # the carrier's send: the writer's thread (or the io thread's flush)

    def drained(self) -> None:
        self.end.flush()

    def message(self, data: bytes) -> None:
        report = pb.LinkResponse.FromString(data)
        self.end.report(report.last, report.lost, report.pending)
        if report.final:
            self.final.set()

    def finish(self, timeout: float) -> bool:
        """Close gracefully: what waits goes, the sink lets its task read what it holds,
        and reports (True) — or ``timeout`` s pass (False). Then the connection ends."""
        self.end.flush()
        self.put(pb.LinkRequest(closing=True).SerializeToString())
        done = self.final.wait(timeout)
        self.close()
        return done

    def ended_hook(self) -> None:
        self.final.set()


class SubIn(Conn):
    """A subscription coming in: frames into the reader ends of its shared feed."""

    def __init__(self, hub: Hub, sock: socket.socket, feed: SharedFeed, label: str) -> None:
        super().__init__(hub, sock, label)
        self.feed = feed

    def readable(self) -> None:
        self.feed.alive()  # any byte: alive (a large sample is many frames)
        super().readable()

    def message(self, data: bytes) -> None:
        self.feed.feed(pb.SubscribeResponse.FromString(data))

    def ended_hook(self) -> None:
        self.feed.ended()
