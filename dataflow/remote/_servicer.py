"""The DeployerService implementation (private; see :mod:`dataflow.remote.server`):
the control plane — introspection, lifecycle, operations, properties, single writes,
and making, listing and undoing links and streams. The sample path's RPCs (subscriptions
and links carried over gRPC or ipc) are answered by the transports' serving halves,
which :mod:`dataflow.remote._channels` dispatches to.

Every RPC runs on a worker of the server's pool, never on a task's thread. ReadPort
attaches nothing to the task (it reads ``last_sample()``), and the one connection the
server keeps per input port for plain remote writes is not counted in DescribeTask, so
introspection shows only the connections users made.
"""

from __future__ import annotations

import json
import logging
import secrets
import threading
import time
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal, TypeVar, cast, overload

import grpc

from scart_wire import codec
from dataflow.errors import NotFoundError, PortTypeError, PortValueError
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote import _convert as cv
from dataflow.remote._channels import Channels
from dataflow.remote._proto import df as pb
from dataflow.remote._proto import df_grpc
from scart_wire.rpc import Abort, abort, peer_key
from dataflow.threads import OwnedThread
from dataflow.transports.sinks import LINGER_S

if TYPE_CHECKING:
    from dataflow.introspection import LinkDescription, OperationDescription
    from dataflow.ports import Port
    from dataflow.properties import BoundProperty
    from dataflow.remote.server import DeployerServer
    from dataflow.task import TaskContext

log = logging.getLogger(__name__)
K = TypeVar("K")

WRITER_IDLE_S = 60.0  #: a remote writer unused this long is reclaimed (its client may be gone)
WRITERS_PER_PORT = 2_048  #: remote writers open on one input port, at most
WRITERS_PER_PEER = 2_048  #: remote writers one peer may have open, at most
MAX_WRITERS = 8_192  #: remote writers open on one deployer, at most
#: A port's last value larger than this (encoded) is left out of DescribeTask, whose reply
#: must stay under gRPC's 4 MiB: a camera's frame is read by subscribing (shm, on one host).
MAX_DESCRIBED_VALUE = 512 << 10
#: A port's last value larger than this (encoded) is refused by ReadPort (RESOURCE_EXHAUSTED,
#: saying so) rather than failing at gRPC's 4 MiB bound with no word of why.
MAX_READ_VALUE = (4 << 20) - (64 << 10)

_TRANSITIONS = MappingProxyType({
    pb.Transition.Value("TRANSITION_CONFIGURE"): "configure",
    pb.Transition.Value("TRANSITION_START"): "start",
    pb.Transition.Value("TRANSITION_STOP"): "stop",
    pb.Transition.Value("TRANSITION_CLEANUP"): "cleanup",
    pb.Transition.Value("TRANSITION_RECOVER"): "recover",
})



def _count_down(table: dict[K, int], key: K) -> None:
    """One less of ``key`` in ``table`` (forgotten at none)."""
    left = table.get(key, 1) - 1
    if left > 0:
        table[key] = left
    else:
        table.pop(key, None)


class _Seen:
    """ReadPort bookkeeping of one output port without any connection: the port's write
    number last seen and when it was first seen (any write since — even of the same
    object — is a new sample)."""

    __slots__ = ("written", "stamp")

    def __init__(self) -> None:
        self.written = 0
        self.stamp = 0


class _Writer:
    """A free OutputPort connected to a task's input port (a remote writer)."""

    def __init__(self, task: str, port: InputPort, policy: ConnPolicy, owner: str = "") -> None:
        self.task = task
        self.target = port
        self.owner = owner  # the peer that opened it (only it may use it)
        self.used = time.monotonic()
        self.out: OutputPort = OutputPort(port.type, name=f"remote_{port.name}")
        self.out.connect_to(port, policy)

    @property
    def key(self) -> tuple[str, str]:
        return self.task, self.target.name

    def close(self, linger: float = 0.0) -> int:
        """Undo the writer: first, for at most ``linger`` s, let the task read what its
        connection still holds; returns the samples it never read (counted as dropped)."""
        conn = next((c for c in self.out.connections() if c.input is self.target), None)
        deadline = time.monotonic() + linger
        while conn is not None and conn.storage.size() and time.monotonic() < deadline:
            time.sleep(0.01)  # the task's thread reads; nothing here can wake on it
        left = conn.storage.size() if conn is not None else 0
        self.out.disconnect(self.target)
        return left


class _Writers:
    """The open remote writers of one server, by secret id: bounded per port, per peer and
    in total; each reclaimed when unused for ``idle`` s (:meth:`sweep`). O(1) open, use and
    close. Thread-safe."""

    def __init__(self, idle: float, per_port: int, per_peer: int, total: int) -> None:
        self.idle = idle
        self.per_port, self.per_peer, self.total = per_port, per_peer, total
        self._lock = threading.Lock()
        self._by_id: dict[str, _Writer] = {}
        self._ports: dict[tuple[str, str], int] = {}
        self._peers: dict[str, int] = {}

    def __len__(self) -> int:
        return len(self._by_id)

    def add(self, writer: _Writer) -> str:
        """Register ``writer``; returns its id. Raises ``Abort`` (RESOURCE_EXHAUSTED) past a bound."""
        with self._lock:
            if len(self._by_id) >= self.total:
                raise Abort("RESOURCE_EXHAUSTED", f"this deployer has {self.total} remote writers open")
            if self._ports.get(writer.key, 0) >= self.per_port:
                raise Abort("RESOURCE_EXHAUSTED", f"{'.'.join(writer.key)} has {self.per_port} remote writers open")
            if self._peers.get(writer.owner, 0) >= self.per_peer:
                raise Abort("RESOURCE_EXHAUSTED", f"at most {self.per_peer} remote writers per peer")
            wid = secrets.token_hex(16)
            self._by_id[wid] = writer
            self._ports[writer.key] = self._ports.get(writer.key, 0) + 1
            self._peers[writer.owner] = self._peers.get(writer.owner, 0) + 1
            return wid

    def get(self, wid: str, peer: str) -> _Writer:
        """The writer ``wid`` of ``peer`` (marked used); ``NotFoundError`` otherwise (never
        saying whether it exists for another peer)."""
        writer = self._by_id.get(wid)
        if writer is None or writer.owner != peer:
            raise NotFoundError("writer unknown or expired on this deployer; open a new one")
        writer.used = time.monotonic()
        return writer

    def pop(self, wid: str, peer: str | None) -> _Writer | None:
        """Remove and return ``wid`` (of ``peer``; None: any peer), or None."""
        with self._lock:
            writer = self._by_id.get(wid)
            if writer is None or (peer is not None and writer.owner != peer):
                return None
            del self._by_id[wid]
            _count_down(self._ports, writer.key)
            _count_down(self._peers, writer.owner)
            return writer

    def sweep(self) -> int:
        """Close the writers unused for ``idle`` s; returns how many."""
        cutoff = time.monotonic() - self.idle
        stale = [wid for wid, w in list(self._by_id.items()) if w.used < cutoff]
        closed = 0
        for wid in stale:
            writer = self.pop(wid, None)
            if writer is not None:
                writer.close()
                closed += 1
        if closed:
            log.info("closed %d remote writer(s) unused for %.0f s", closed, self.idle)
        return closed

    def close_all(self) -> None:
        for wid in list(self._by_id):
            writer = self.pop(wid, None)
            if writer is not None:
                writer.close()


class DeployerServicer(df_grpc.DeployerServiceServicer):
    """Implements every method of ``scart.dataflow.v1.DeployerService`` for one server."""

    def __init__(self, owner: DeployerServer, heartbeat_ms: int, max_streams: int) -> None:
        self.owner = owner
        self.deployer = owner.deployer
        self.heartbeat_ms = heartbeat_ms
        self.max_streams = max_streams
        self._lock = threading.Lock()
        self._seen: dict[tuple[str, str], _Seen] = {}
        self._defaults: dict[tuple[str, str], _Writer] = {}
        self._writers = _Writers(WRITER_IDLE_S, WRITERS_PER_PORT, WRITERS_PER_PEER, MAX_WRITERS)
        self._stopping = threading.Event()
        # started with the first remote writer: reclaims those of clients gone away
        self._sweeper = OwnedThread(self._sweep, "scart-writer-sweeper")
        self.channels = Channels(owner, heartbeat_ms, max_streams)  #: the sample path, by transport

    def _sweep(self, stopping: threading.Event) -> None:
        """Reclaim the writers of clients that went away (bounded: idle + a quarter of it)."""
        while not stopping.wait(self._writers.idle / 4):
            self._writers.sweep()

    # ---- lookup helpers -------------------------------------------------------------
    def _task(self, name: str) -> TaskContext:
        return self.deployer.task(name)

    @overload
    def _port(self, task: str, port: str, want_input: Literal[True]) -> InputPort[object]: ...
    @overload
    def _port(self, task: str, port: str, want_input: Literal[False]) -> OutputPort[object]: ...
    def _port(self, task: str, port: str, want_input: bool | None = None) -> Port[object]:
        p = self._task(task).port(port)
        if want_input is not None and p.is_input != want_input:
            kind = "an input" if p.is_input else "an output"
            need = "input" if want_input else "output"
            raise Abort("INVALID_ARGUMENT", f"{task}.{port} is {kind} port; this needs an {need} port")
        return p

    def _value_for(self, where: str, py_type: object, type_name: str, msg: codec.Value | None,
                   json_text: str) -> object:
        """A written value as the port's type; a field its model does not declare is
        refused (INVALID_ARGUMENT), never dropped."""
        from scart_wire.bounds import unknown_field
        from scart_wire.types import registry

        if json_text:
            try:
                obj = json.loads(json_text)
            except json.JSONDecodeError as exc:
                raise Abort("INVALID_ARGUMENT", f"{where}: value is not valid JSON ({exc})") from None
            said = unknown_field(py_type, obj)
            if said is not None:
                raise Abort("INVALID_ARGUMENT", f"{where} expects {type_name}: unknown field {said}")
            try:
                return registry.from_jsonable(py_type, obj)
            except (PortTypeError, TypeError, ValueError) as exc:
                raise Abort("INVALID_ARGUMENT", f"{where} expects {type_name}, got {json_text!r}: {exc}") from None
        assert msg is not None  # no JSON text: a Value was given
        given = msg.type_name or "None"
        try:
            value = codec.decode(msg)
            if type(value) is py_type:  # decoded as the port's own type: nothing to coerce
                return value
            said = unknown_field(py_type, value)
            if said is not None:
                raise PortTypeError(f"unknown field {said}")
            return registry.validate(py_type, value)
        except (PortTypeError, TypeError, ValueError) as exc:
            raise Abort("INVALID_ARGUMENT", f"{where} expects {type_name}, given {given}: {exc}") from None

    def stop(self) -> None:
        """End every channel; close taps and writers; end the sweeper (idempotent)."""
        self._stopping.set()
        with self._lock:
            for item in self._defaults.values():
                item.close()
            self._seen.clear()
            self._defaults.clear()
        self._writers.close_all()
        self.channels.stop()
        self._sweeper.stop()

    # ---- introspection and lifecycle ---------------------------------------------------
    @staticmethod
    def _summary(task: TaskContext) -> pb.TaskSummary:
        act = task.activity
        cycles, last_cycle = getattr(act, "stamp", (0, 0.0))
        if not last_cycle:
            cycles = getattr(act, "cycles", 0)
        return pb.TaskSummary(
            name=task.name,
            state=task.state.name,
            activity=getattr(act, "kind", "") if act is not None else "",
            period=float(getattr(act, "period", 0.0) or 0.0),
            cycles=int(cycles or 0),
            overruns=int(getattr(act, "overruns", 0) or 0),
            last_cycle=float(last_cycle),
        )

    def ListTasks(self, request: pb.ListTasksRequest, context: grpc.ServicerContext) -> pb.ListTasksResponse:  # noqa: N802
        return pb.ListTasksResponse(tasks=[self._summary(t) for t in self.deployer.tasks()])

    def DescribeTask(self, request: pb.DescribeTaskRequest, context: grpc.ServicerContext) -> pb.DescribeTaskResponse:  # noqa: N802
        try:
            task = self._task(request.task)
            d = task.describe()
            with self._lock:
                internal = {port for (t, port) in self._defaults if t == task.name}
            ports = []
            for p in d.ports:
                hidden = 1 if p.direction == "in" and p.name in internal else 0
                info = pb.PortInfo(
                    name=p.name, direction=p.direction, type_name=p.type_name, doc=p.doc,
                    connections=max(0, p.connections - hidden), event=p.event, bounds=p.bounds,
                    writes=p.writes, check=p.check,
                    streams=[pb.PortStreamInfo(**s.model_dump()) for s in p.streams],
                )
                if p.direction == "out":
                    port = cast("OutputPort[object]", task.port(p.name))  # its direction is "out"
                    last = port.last_written_value()
                    if last is not None:
                        value = codec.encode(last, port.type)
                        if value.ByteSize() <= MAX_DESCRIBED_VALUE:
                            info.last_value.CopyFrom(value)
                            info.has_last_value = True
                ports.append(info)
            props = [
                pb.PropertyInfo(name=p.name, type_name=p.type_name, json_value=json.dumps(p.value), doc=p.doc,
                                bounds=p.bounds)
                for p in d.properties
            ]
            ops = [
                pb.OperationInfo(
                    name=o.name, params=[pb.Parameter(name=n, type_name=t) for n, t in o.params],
                    returns=o.returns, doc=o.doc, own_thread=o.own_thread, signature=o.signature,
                )
                for o in d.operations
            ]
            return pb.DescribeTaskResponse(task=pb.TaskInfo(summary=self._summary(task), ports=ports,
                                                            properties=props, operations=ops))
        except Exception as exc:  # noqa: BLE001 - mapped to a status
            abort(context, exc)

    def ChangeState(self, request: pb.ChangeStateRequest, context: grpc.ServicerContext) -> pb.ChangeStateResponse:  # noqa: N802
        try:
            task = self._task(request.task)
            name = _TRANSITIONS.get(request.transition)
            if name is None:
                raise Abort("INVALID_ARGUMENT", f"unknown transition {request.transition}")
            accepted = bool(getattr(task, name)())
            return pb.ChangeStateResponse(accepted=accepted, state=task.state.name)
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    # ---- writing ---------------------------------------------------------------------
    def _default_writer(self, task: str, port: InputPort[object]) -> _Writer:
        key = (task, port.name)
        with self._lock:
            writer = self._defaults.get(key)
            if writer is None:
                writer = self._defaults[key] = _Writer(task, port, ConnPolicy.data())
            return writer

    def WritePort(self, request: pb.WritePortRequest, context: grpc.ServicerContext) -> pb.WritePortResponse:  # noqa: N802
        try:
            if request.writer:
                writer = self._writers.get(request.writer, peer_key(context))
                port = writer.target
                task = writer.task
                where = f"{task}.{port.name}"
                value = self._admitted(port, self._value_for(where, port.type, port.type_name, request.value,
                                                             request.json), context)
            else:
                task = request.task
                port = self._port(task, request.port, want_input=True)
                where = f"{task}.{port.name}"
                # validate first: a refused value must leave no connection behind
                value = self._admitted(port, self._value_for(where, port.type, port.type_name, request.value,
                                                             request.json), context)
                writer = self._default_writer(task, port)
            status = writer.out.write(value)
            return pb.WritePortResponse(status=cv.write_to_msg(status))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    @staticmethod
    def _admitted(port: InputPort[object], value: object, context: grpc.ServicerContext) -> object:
        """``value`` within ``port``'s bounds; a refusal is logged (who, what) and raised
        (OUT_OF_RANGE to the writer)."""
        try:
            return port.admit(value)
        except PortValueError as exc:
            log.warning("a write from %s refused: %s", context.peer(), exc)
            raise

    def OpenWriter(self, request: pb.OpenWriterRequest, context: grpc.ServicerContext) -> pb.OpenWriterResponse:  # noqa: N802
        try:
            port = self._port(request.task, request.port, want_input=True)
            policy = cv.policy_from_msg(request.policy)
            writer = _Writer(request.task, port, policy, owner=peer_key(context))
            try:
                wid = self._writers.add(writer)
            except Abort:
                writer.close()
                raise
            self._sweeper.start()
            return pb.OpenWriterResponse(writer=wid, idle_seconds=self._writers.idle)
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def CloseWriter(self, request: pb.CloseWriterRequest, context: grpc.ServicerContext) -> pb.CloseWriterResponse:  # noqa: N802
        writer = self._writers.pop(request.writer, peer_key(context))
        left = writer.close(LINGER_S) if writer is not None else 0
        if writer is not None and left:
            log.warning("a remote writer of %s closed with %d sample(s) its task never read",
                        ".".join(writer.key), left)
        return pb.CloseWriterResponse(undelivered=left)

    # ---- reading and subscribing -------------------------------------------------------
    def ReadPort(self, request: pb.ReadPortRequest, context: grpc.ServicerContext) -> pb.ReadPortResponse:  # noqa: N802
        try:
            port = self._port(request.task, request.port, want_input=False)
            key = (request.task, port.name)
            with self._lock:  # value, sequence and stamp taken together
                written, value = port.last_sample()
                if written == 0:
                    return pb.ReadPortResponse(flow_status=cv.flow_to_msg(FlowStatus.NO_DATA),
                                               boot_id=self.owner.boot_id)
                seen = self._seen.get(key)
                if seen is None:
                    seen = self._seen[key] = _Seen()
                if seen.written != written:  # a write since the last read: stamp it now
                    seen.written, seen.stamp = written, time.time_ns()
                stamp = seen.stamp
            encoded = codec.encode(value, port.type)
            if encoded.ByteSize() > MAX_READ_VALUE:
                raise Abort("RESOURCE_EXHAUSTED", f"{request.task}.{port.name}'s last value is {encoded.ByteSize()} "
                            f"bytes, more than a read carries ({MAX_READ_VALUE}): subscribe to it")
            return pb.ReadPortResponse(
                flow_status=cv.flow_to_msg(FlowStatus.NEW_DATA), value=encoded,
                sequence=written, source_time_ns=stamp, boot_id=self.owner.boot_id,
            )
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    # ---- operations and properties -----------------------------------------------------
    def CallOperation(self, request: pb.CallOperationRequest, context: grpc.ServicerContext) -> pb.CallOperationResponse:  # noqa: N802
        from scart_wire.types import registry

        try:
            task = self._task(request.task)
            ops = task.operations()
            if request.operation not in ops:
                raise NotFoundError(
                    f"{task.name} has no operation {request.operation!r}; operations: {', '.join(sorted(ops)) or '(none)'}"
                )
            desc = ops[request.operation]
            given: list[Any] = list(request.json_args) if request.use_json else list(request.args)  # texts or Values
            if len(given) != len(desc.params):
                raise Abort(
                    "INVALID_ARGUMENT",
                    f"{task.name}.{desc.signature or desc.name} takes {len(desc.params)} argument(s), got {len(given)}",
                )
            # the one check of every entry (types, bounds, finiteness) on the values as they came
            task.check_arguments(desc.name, [self._raw_argument(task, desc, p, a)
                                             for (p, _), a in zip(desc.params, given, strict=True)])
            args = []
            for (pname, tname), arg in zip(desc.params, given, strict=True):
                py_type = registry.python_type(tname)
                where = f"{task.name}.{desc.name}({pname})"
                if request.use_json:
                    args.append(self._value_for(where, py_type if py_type is not None else tname, tname, None, arg))
                elif py_type is not None:
                    args.append(self._value_for(where, py_type, tname, arg, ""))
                else:
                    args.append(codec.decode(arg))
            try:
                result = task.call(desc.name, *args)
            except (NotFoundError, PortTypeError, Abort):
                raise
            except Exception as exc:  # noqa: BLE001 - the operation's own failure
                raise Abort("UNKNOWN", f"{task.name}.{desc.name} raised {type(exc).__name__}: {exc}") from None
            return pb.CallOperationResponse(result=codec.encode(result))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    @staticmethod
    def _raw_argument(task: TaskContext, desc: OperationDescription, param: str, arg: str | codec.Value) -> object:
        """An operation argument decoded, not converted (JSON text, or a ``Value``)."""
        try:
            return json.loads(arg) if isinstance(arg, str) else codec.decode(arg)
        except (ValueError, PortTypeError) as exc:
            raise Abort("INVALID_ARGUMENT", f"{task.name}.{desc.name}({param}): not a value: {exc}") from None

    def _property(self, task: TaskContext, name: str) -> BoundProperty:
        props = task.properties()
        if name not in props:
            raise NotFoundError(f"{task.name} has no property {name!r}; properties: {', '.join(sorted(props)) or '(none)'}")
        return props[name]

    def GetProperty(self, request: pb.GetPropertyRequest, context: grpc.ServicerContext) -> pb.GetPropertyResponse:  # noqa: N802
        try:
            task = self._task(request.task)
            prop = self._property(task, request.name)
            value = task.get_property(request.name)
            return pb.GetPropertyResponse(value=codec.encode(value, prop.type), json_value=cv.to_json_text(value))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def SetProperty(self, request: pb.SetPropertyRequest, context: grpc.ServicerContext) -> pb.SetPropertyResponse:  # noqa: N802
        try:
            task = self._task(request.task)
            prop = self._property(task, request.name)
            where = f"{task.name}.{request.name}"
            value = self._value_for(where, prop.type, prop.type_name, request.value, request.json)
            task.set_property(request.name, value)
            return pb.SetPropertyResponse(json_value=cv.to_json_text(task.get_property(request.name)))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    # ---- connections (delegated to the server, which owns the links) -------------------
    def ConnectPorts(self, request: pb.ConnectPortsRequest, context: grpc.ServicerContext) -> pb.ConnectPortsResponse:  # noqa: N802
        try:
            local, address, note, link = self.owner.connect_ports(
                request.source_task, request.source_port, request.sink_task, request.sink_port,
                cv.policy_from_msg(request.policy), name=request.name or None, resume=request.resume,
            )
            return pb.ConnectPortsResponse(local=local, sink_address=address, note=note,
                                           link=_link_info(link) if link is not None else None)
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def DisconnectPorts(self, request: pb.DisconnectPortsRequest, context: grpc.ServicerContext) -> pb.DisconnectPortsResponse:  # noqa: N802
        try:
            if request.name:
                lost = self.owner.disconnect_link_counted(request.name)
            else:
                lost = self.owner.disconnect_counted(
                    request.source_task, request.source_port, request.sink_task, request.sink_port
                )
            return pb.DisconnectPortsResponse(disconnected=lost is not None, undelivered=lost or 0)
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def ListLinks(self, request: pb.ListLinksRequest, context: grpc.ServicerContext) -> pb.ListLinksResponse:  # noqa: N802
        try:
            served = [pb.SubscriptionInfo(**info) for info in self.channels.served.info()[:MAX_LINKS_LISTED]]
            return pb.ListLinksResponse(links=[_link_info(lk) for lk in self.owner.links()[:MAX_LINKS_LISTED]],
                                        subscriptions=served)
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def RerouteLink(self, request: pb.RerouteLinkRequest, context: grpc.ServicerContext) -> pb.RerouteLinkResponse:  # noqa: N802
        try:
            link = self.owner.reroute(request.name, request.sink_task, request.sink_port)
            return pb.RerouteLinkResponse(link=_link_info(link))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def StreamPort(self, request: pb.StreamPortRequest, context: grpc.ServicerContext) -> pb.StreamPortResponse:  # noqa: N802
        try:
            link = self.owner.stream(request.task, request.port, cv.policy_from_msg(request.policy),
                                     dict(request.options), name=request.name or None)
            return pb.StreamPortResponse(link=_link_info(link))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)

    def UnstreamPort(self, request: pb.UnstreamPortRequest, context: grpc.ServicerContext) -> pb.UnstreamPortResponse:  # noqa: N802
        try:
            return pb.UnstreamPortResponse(removed=self.owner.unstream(request.name))
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)


MAX_LINKS_LISTED = 2000  # with names of at most ~600 bytes: well under the message bound


def _link_info(link: LinkDescription) -> pb.LinkInfo:
    return pb.LinkInfo(name=link.name, source=link.source, sink=link.sink, policy=link.policy,
                       transport=link.transport, samples=link.samples, dropped=link.dropped, kind=link.kind,
                       state=link.state, detail=link.detail[:300], pending=link.pending)
