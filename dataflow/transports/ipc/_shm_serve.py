"""shm's connections at the deployer's side (private): a link coming in and a
subscription served, ipc's (:mod:`._serve`) with large samples in shared-memory slots
(:mod:`._shm_conns`); what an ipc ticket asking for shm opens (:class:`ShmFlavour`)."""

from __future__ import annotations

import socket

from dataflow.transports.ipc._hub import Conn, Hub
from dataflow.transports.ipc._serve import Flavour, IpcServer, _LinkIn, _ReaderOut
from dataflow.transports.ipc._shm_conns import SlotReader, SlotSender
from dataflow.transports.served import Served
from dataflow.transports.sinks import IncomingLink
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb

__all__ = ["ShmFlavour", "ShmLinkIn", "ShmReaderOut"]


class ShmReaderOut(SlotSender, _ReaderOut):
    """A subscription served on shm: ipc's, with its large samples in slots."""

    def __init__(self, hub: Hub, sock: socket.socket, server: IpcServer, served: Served, heartbeat: float) -> None:
        _ReaderOut.__init__(self, hub, sock, server, served, heartbeat)
        self.init_slots(served.port, served.policy)
        self.encode = self.encode_large  # the instance's own: slots are this channel's

    def message(self, data: bytes) -> None:
        try:
            self.released(pb.LinkResponse.FromString(data))
        except Exception:  # noqa: BLE001 - not a release: counted with the malformed ones
            self._assembler.dropped += 1

    def ended_hook(self) -> None:
        super().ended_hook()
        self.close_slots()


class ShmLinkIn(SlotReader, _LinkIn):
    """A link coming in on shm: ipc's, with large samples viewed in shared memory."""

    def __init__(self, hub: Hub, sock: socket.socket, server: IpcServer, link: IncomingLink, known: bool) -> None:
        _LinkIn.__init__(self, hub, sock, server, link, known)
        self.init_maps()
        self.link.end.transport = "shm"

    def message(self, data: bytes) -> None:
        frame = self.request(data)
        if frame is None:
            return
        values = self.slot_values(frame) if frame.slots or frame.samples else None
        if frame.samples or not frame.slots:
            self.took(frame, values)


class ShmFlavour(Flavour):
    """What an ipc ticket asking for shm opens at the deployer (see
    :class:`~dataflow.transports.ipc._serve.Flavour`)."""

    def link_in(self, hub: Hub, sock: socket.socket, server: IpcServer, link: IncomingLink, known: bool) -> Conn:
        return ShmLinkIn(hub, sock, server, link, known)

    def reader_out(self, hub: Hub, sock: socket.socket, server: IpcServer, served: Served, heartbeat: float) -> Conn:
        return ShmReaderOut(hub, sock, server, served, heartbeat)
