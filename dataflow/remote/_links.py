"""Links between deployers, as their deployers keep them (private; the control plane
side of :mod:`dataflow.transports`).

* :class:`RemoteLink` — at the **source**: the link's writer end on the output port and
  the thread that finds the sink (through the name service), offers the channel to the
  transports (``auto``: ipc on one host, else gRPC), and reconnects after a failure or
  when the sink's deployer restarted.
* :class:`LinkKeeper` — at the **sink**: each incoming link is remembered with where its
  source is served; when the source's deployer restarts (a new boot id in the name
  service) the keeper asks the new process to make the link again, counting the writes
  it made before the link was back (``resume``). So a link made with ``scart connect``
  survives either end restarting; both at once, and it is gone.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING, Protocol

import grpc

from dataflow.errors import DeploymentError, NotFoundError
from dataflow.introspection import LinkDescription
from dataflow.policy import ConnPolicy
from dataflow.transports.flow import waits
from dataflow.remote import errors
from scart_wire import rpc
from dataflow.remote._convert import policy_to_msg
from dataflow.remote._proto import df as pb
from dataflow.remote._proto import df_grpc
from dataflow.threads import OwnedThread
from dataflow.transports import LinkRefused, NoTransportError, Peer, TransportError, carry
from dataflow.transports.ends import WriterEnd, attach, detach
from dataflow.transports.sinks import LINGER_S, IncomingLink, Sinks

if TYPE_CHECKING:
    from dataflow.ports import OutputPort
    from dataflow.remote.server import DeployerServer
    from dataflow.transports import Transport
    from scart_wire.security import Security

__all__ = ["LinkKeeper", "LinkSource", "PEER_FAILURES", "RemoteLink", "SOURCE_GONE"]

log = logging.getLogger(__name__)

#: What a peer's failure looks like to a link's thread (it backs off and reconnects).
PEER_FAILURES = (grpc.RpcError, grpc.FutureCancelledError, errors.RemoteError, NotFoundError, OSError)
SETTLE_S = 2.0  #: how long making a link waits for its first connection (it then says how it went)
#: What a link listed by its sink says while its source's deployer is gone (a client
#: listing every deployer shows the source's own row instead, once it is back).
SOURCE_GONE = "its source's deployer is gone; the sink waits for it to come back"
CLOSE_S = LINGER_S + 1.0  #: how long closing a link waits for the sink's last report


class LinkSource(Protocol):
    """What a link asks of the side of its source: a deployer's server, or ``scart play``'s
    process (``boot_id``: its process's, for the sink; ``resolve``: a task's address)."""

    boot_id: str
    security: Security
    ns_timeout: float
    ns_address: str

    def resolve(self, component: str) -> str: ...


class RemoteLink:
    """An output port of this deployer feeding an input port of another (see the module
    docstring). ``resume``: count every write of this process (the link is made again
    after this deployer restarted), not only those after the link was made."""

    def __init__(self, server: LinkSource, out: OutputPort[object], sink_task: str, sink_port: str, policy: ConnPolicy,
                 name: str, serial: int, *, resume: bool = False) -> None:
        self.server = server
        self.out = out
        self.sink_task = sink_task
        self.sink_port = sink_port
        self.policy = policy
        self.name = name
        self.channel = f"{server.boot_id}/{serial}"
        self.end = WriterEnd(out, policy, f"link {name}", held=True)
        if resume:
            self.end.start = 0
        self.state = "waiting"
        self.detail = "not connected yet"
        self.refusal: BaseException | None = None  #: why the sink refused it (retrying will not help)
        self.settled = threading.Event()  #: the first attempt is over (connected, or failed)
        self._peer: Peer | None = None
        self.end.on_connected = self._connected
        attach(out, self.end)
        self._thread = OwnedThread(self._run, f"scart-link-{name}"[:60], wake=self._cancel)
        self._thread.start()

    @property
    def source(self) -> str:
        return self.out.qualname

    @property
    def sink(self) -> str:
        return f"{self.sink_task}.{self.sink_port}"

    def describe(self) -> LinkDescription:
        """What ``scart links`` shows of it."""
        transport = self.end.transport
        return LinkDescription(name=self.name, source=self.source, sink=self.sink, policy=str(self.policy),
                               transport=transport or f"{self.policy.transport}?", samples=self.out.last_sample()[0],
                               dropped=self.end.dropped, kind="link",
                               state="connected" if transport else self.state,
                               detail="" if transport else self.detail, pending=self.end.undelivered())

    def _cancel(self) -> None:
        peer = self._peer
        if peer is not None:
            peer.cancel()

    def _run(self, stopping: threading.Event) -> None:
        backoff = 0.05
        while not stopping.is_set():
            try:
                self._connect(stopping)
                backoff = 0.05
            except LinkRefused as exc:
                self._failed("refused", str(exc), exc)
                backoff = 2.0
            except NoTransportError as exc:
                self._failed("waiting", str(exc), exc)
            except TransportError as exc:  # a plug-in that cannot be loaded, or a transport's refusal
                self._failed("refused", str(exc), exc)
                backoff = 1.0
            except PEER_FAILURES as exc:
                refusal = None
                if isinstance(exc, grpc.RpcError) and exc.code() == grpc.StatusCode.RESOURCE_EXHAUSTED:
                    refusal = DeploymentError(f"link {self.name}: {exc.details()} (a limit of the sink's deployer, "
                                              f"{self.sink_task}'s)")
                self._failed("waiting" if refusal is None else "refused", failure_reason(exc), refusal)
            except Exception as exc:  # noqa: BLE001 - the link's thread must not die: log, back off, retry
                if not stopping.is_set():
                    log.exception("link %s failed; retrying", self.name)
                self._failed("waiting", failure_reason(exc), None)
            self.settled.set()
            if stopping.wait(backoff):
                return
            backoff = min(1.0, backoff * 2)

    def _connect(self, stopping: threading.Event) -> None:
        server = self.server
        address = server.resolve(self.sink_task)
        with server.security.channel(address, rpc.channel_options()) as channel:
            peer = Peer(address, self.sink_task, self.sink_port, df_grpc.DeployerServiceStub(channel),
                        server.ns_timeout, policy_msg=policy_to_msg(self.policy), channel_of=channel,
                        channel=self.channel, name=self.name, boot_id=server.boot_id, source_ns=server.ns_address)
            self._peer = peer
            if stopping.is_set():
                return
            carry(self.policy.transport, lambda t: self._attempt(t, peer), f"link {self.name}",
                  PEER_FAILURES, "link")
        if not stopping.is_set():
            log.info("link %s: the sink's deployer went away; reconnecting", self.name)

    def _attempt(self, transport: Transport, peer: Peer) -> bool:
        if waits(self.policy) and not transport.waits:  # auto goes on; a named one is refused at connect
            self.detail = f"{transport.name} carries no writer that waits ({self.policy.wait.value})"
            return False
        self.detail = f"connecting over {transport.name}"
        return transport.link(self.end, peer)

    def _connected(self) -> None:  # the transport's thread, once the channel is up
        self.state, self.refusal = "connected", None
        self.settled.set()

    def _failed(self, state: str, detail: str, refusal: BaseException | None) -> None:
        if (state, detail) != (self.state, self.detail):
            (log.warning if state == "refused" else log.info)("link %s: %s", self.name, detail)
        self.state, self.detail, self.refusal = state, detail, refusal

    def stop(self, deadline: float) -> int:
        """This deployer stops; the link is not undone (the sink keeps it, and has this
        deployer make it again once back): what was written before the stop is delivered
        first — sent, and reported by the sink — until ``deadline`` (``time.monotonic()``);
        then the connection ends. Returns the samples the stop left undelivered (in flight,
        or not sent), and says how many when any. Idempotent; joins its thread."""
        upto = self.out.last_sample()[0]
        if self.end.transport:
            self.end.flush()
            while self.end.transport and self.end.undelivered_upto(upto) and time.monotonic() < deadline:
                self._thread.stopping.wait(0.01)  # reports come every REPORT_S at most: a bounded poll
        self._thread.stop()
        detach(self.out, self.end)
        lost = self.end.unconfirmed
        if lost:
            log.warning("link %s: this deployer stops; %d sample(s) written were not delivered", self.name, lost)
        return lost

    def close(self, graceful: bool = True) -> int:
        """Undo the link: with ``graceful``, what waits is delivered first and the sink's
        task may read what its buffer holds (at most :data:`CLOSE_S` s). Returns the
        samples written and not delivered (logged when any). Idempotent; joins its thread."""
        peer = self._peer
        confirmed = peer.finish(CLOSE_S) if graceful and peer is not None and self.end.transport else False
        self._thread.stop()
        detach(self.out, self.end)
        lost = self.end.dropped + (0 if confirmed else self.end.undelivered())
        if lost and graceful:
            log.warning("link %s closed: %d sample(s) written were not delivered", self.name, lost)
        return lost


def failure_reason(exc: BaseException) -> str:
    """A peer's failure in one line: a gRPC status by its code and details, else the
    exception's type and text (what ``scart links`` shows a waiting link or subscription)."""
    if isinstance(exc, grpc.RpcError) and hasattr(exc, "code"):
        return f"{exc.code().name}: {exc.details()}"
    return f"{type(exc).__name__}: {exc}"


class LinkKeeper:
    """The sink's side of links surviving restarts (see the module docstring): one owned
    thread that looks, every :data:`PERIOD_S`, at the incoming links whose source is
    gone, and asks a restarted source to make them again."""

    PERIOD_S = 0.5
    GONE_S = 0.5  #: a link without a carrier this long has lost its source

    def __init__(self, server: DeployerServer, sinks: Sinks) -> None:
        self.server = server
        self.sinks = sinks
        self._thread = OwnedThread(self._run, "scart-link-keeper")
        self._thread.start()

    def _run(self, stopping: threading.Event) -> None:
        while not stopping.wait(self.PERIOD_S):
            now = time.monotonic()
            for link in self.sinks.links():
                if link.carriers == 0 and now - link.seen >= self.GONE_S and not stopping.is_set():
                    try:
                        self._revive(link)
                    except Exception as exc:  # noqa: BLE001 - one link's trouble never stops the others
                        log.debug("link %s: its source is not back yet: %s", link.name, exc)

    def _revive(self, link: IncomingLink) -> None:
        task = link.source.rpartition(".")[0]
        entry = self.server.resolve_entry(task, link.source_ns)
        sink = link.port.task
        if not entry.boot_id or entry.boot_id == link.boot_id or sink is None:
            return  # the same process (reconnecting by itself), one that cannot say, or a port gone from its task
        given = "" if link.name == f"{link.source}->{link.port.qualname}" else link.name  # the default is no name
        request = pb.ConnectPortsRequest(
            source_task=task, source_port=link.source.rpartition(".")[2], sink_task=sink.name,
            sink_port=link.port.name, policy=policy_to_msg(link.policy), name=given, resume=True)
        with self.server.security.channel(entry.address, rpc.channel_options()) as channel:
            df_grpc.DeployerServiceStub(channel).ConnectPorts(request, timeout=self.server.ns_timeout)
        log.info("link %s: its source restarted; made again", link.name)
        self.sinks.finish(link)

    def waiting(self) -> list[LinkDescription]:
        """The incoming links whose source has been gone :data:`GONE_S` or more (its
        deployer stopped or died), as ``scart links`` shows them from here: ``waiting``,
        as a link whose sink is gone shows at its source (the source lists it once back)."""
        now = time.monotonic()
        return [LinkDescription(name=link.name or f"{link.source}->{link.port.qualname}", source=link.source,
                                sink=link.port.qualname, policy=str(link.policy), transport=f"{link.policy.transport}?",
                                samples=link.end.last, dropped=link.end.lost, kind="link", state="waiting",
                                detail=SOURCE_GONE)
                for link in self.sinks.links() if link.carriers == 0 and now - link.seen >= self.GONE_S]

    def stop(self) -> None:
        self._thread.stop()

