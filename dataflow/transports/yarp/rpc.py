"""Operations answered on a YARP RPC port, as ``yarp rpc /scart/COMP/rpc`` calls them:
the command is a bottle whose first word names the operation and whose other items are
its arguments; the reply is a bottle.

* :func:`serve_task` — a task's operations (each argument checked as on every other entry:
  :meth:`~dataflow.TaskContext.check_arguments`; an ``own_thread`` operation runs in the
  task's thread, waited for ≤ ``timeout`` s);
* :func:`serve_calls` — any named callables (an SCA service's operations), their
  arguments checked against their annotations the same way.

Arguments arrive by the bottle rules of :mod:`.convert` (a model as the list of its
fields), results leave by them; ``None`` is answered ``[ok]``, a failure ``[fail] "why"``
(YARP's own words for it). ``help`` lists the operations with their parameters.
"""

from __future__ import annotations

import inspect
import logging
import typing
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from dataflow.transports import TransportError

from .convert import Unfit, item_reader, plan

if TYPE_CHECKING:
    from scart_yarp.bottle import Item

    from dataflow.task import TaskContext

__all__ = ["RpcPort", "call_rpc", "check_port_name", "rpc_port_name", "serve_calls", "serve_task"]

log = logging.getLogger(__name__)


def check_port_name(name: str) -> str:
    """``name`` if it is a YARP port name; ``ValueError`` saying the form otherwise."""
    from scart_yarp.names import check_name

    return check_name(name)


def call_rpc(port: str, values: Sequence[object], server: str | None = None, timeout: float = 5.0) -> list[object]:
    """Call the YARP RPC port ``port`` with the bottle ``values``, as ``yarp rpc`` does; the
    reply as plain data (a vocab as its text). ``server``: the name server ``HOST:PORT``
    (default YARP's configuration). Raises ``ValueError`` saying what went wrong — also for
    a reply that starts with the vocab ``fail``, YARP's convention for a refused command."""
    from scart_yarp import NameClient, Vocab, parse_address, rpc_call
    from scart_yarp.bottle import BottleError

    try:
        names = NameClient(parse_address(server) if server else None, timeout=timeout)
        reply = rpc_call(names, port, values)
    except (OSError, BottleError) as exc:
        raise ValueError(f"yarp:{port}: {exc}") from None
    if reply and reply[0] == Vocab("fail"):
        why = " ".join(str(_plain(v)) for v in reply[1:])[:1000]
        raise ValueError(f"yarp:{port} answered [fail]{' ' + why if why else ''}")
    return [_plain(v) for v in reply]


def _plain(value: Item) -> object:
    from scart_yarp import Vocab

    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value.text if isinstance(value, Vocab) else value


def rpc_port_name(component: str) -> str:
    """``/scart/COMPONENT/rpc``: where a component's operations are answered by default."""
    return f"/scart/{component}/rpc"


class RpcPort:
    """A served RPC port; :meth:`close` withdraws it (idempotent)."""

    def __init__(self, name: str, label: str, close: Callable[[], None]) -> None:
        self.name = name
        self.label = label
        self._close = close
        self._closed = False

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._close()


def serve_task(task: TaskContext, name: str = "", options: dict[str, str] | None = None, timeout: float = 5.0) -> RpcPort:
    """Answer ``task``'s operations on the YARP RPC port ``name`` (default
    :func:`rpc_port_name`). Raises :class:`TransportError` when the port cannot be opened."""
    ops = {op: _task_call(task, op, timeout) for op in task.operations()}
    hints = {op: _hints(getattr(type(task), task._operation_attrs[op])) for op in ops}  # noqa: SLF001
    return _serve(name or rpc_port_name(task.name), ops, hints, f"task {task.name}", options or {})


def serve_calls(calls: Mapping[str, Callable[..., object]], name: str, label: str,
                options: dict[str, str] | None = None) -> RpcPort:
    """Answer the callables ``calls`` (by operation name) on the YARP RPC port ``name``,
    each argument checked against its annotation. Raises :class:`TransportError`."""
    from scart_wire.bounds import check_argument

    def checked(op: str, fn: Callable[..., object]) -> Callable[..., object]:
        params = list(_hints(fn).items())

        def call(*args: object) -> object:
            values = [check_argument(f"{label}.{op}({p})", hint, v) for (p, hint), v in zip(params, args)]
            return fn(*values)
        return call

    ops = {op: checked(op, fn) for op, fn in calls.items()}
    return _serve(name, ops, {op: _hints(fn) for op, fn in calls.items()}, label, options or {})


def _task_call(task: TaskContext, op: str, timeout: float) -> Callable[..., object]:
    def call(*args: object) -> object:
        return task.send(op, *task.check_arguments(op, list(args))).result(timeout)
    return call


def _hints(fn: Callable[..., object]) -> dict[str, object]:
    """``{parameter: annotation}`` of ``fn`` (``self`` left out; ``Any`` where unannotated)."""
    try:
        hints = typing.get_type_hints(fn, include_extras=True)
    except Exception:  # noqa: BLE001 - unresolvable annotations: as if there were none
        hints = {}
    params = [p for p in inspect.signature(fn).parameters.values()
              if p.name != "self" and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    return {p.name: hints.get(p.name, Any) for p in params}


def _serve(name: str, ops: Mapping[str, Callable[..., object]], hints: Mapping[str, Mapping[str, object]], label: str,
           options: dict[str, str]) -> RpcPort:
    from scart_yarp import Vocab

    from . import YarpTransport
    from dataflow.transports import load

    transport = load("yarp")
    assert isinstance(transport, YarpTransport)
    readers = {op: [item_reader(h) for h in params.values()] for op, params in hints.items()}

    def respond(cmd: list[Item]) -> list[Item]:
        word = cmd[0].text if cmd and isinstance(cmd[0], Vocab) else (cmd[0] if cmd else "")
        if word == "help" or not cmd:
            return [Vocab("many"), *(f"{op} {' '.join(hints[op])}".strip() for op in sorted(ops))]
        if not isinstance(word, str) or word not in ops:  # (an operation's name is a string)
            return [Vocab("fail"), f"no operation {str(word)[:80]!r}; {label} has: {', '.join(sorted(ops))}"]
        args, wanted = cmd[1:], readers[word]
        if len(args) != len(wanted):
            return [Vocab("fail"), f"{word} takes {len(wanted)} argument(s) ({', '.join(hints[word])}), "
                                   f"got {len(args)}"]
        try:
            values = [read(v) for read, v in zip(wanted, args)]
            return _reply(ops[word](*values))
        except Unfit as exc:
            return [Vocab("fail"), f"{word}: {exc}"]
        except Exception as exc:  # noqa: BLE001 - the caller gets the failure as its reply
            return [Vocab("fail"), f"{type(exc).__name__}: {exc}"[:1000]]

    network = transport.acquire(options)
    try:
        port = network.open_port(name, responder=respond)
    except (ValueError, OSError) as exc:
        transport.release(network)
        raise TransportError(f"yarp: RPC port {name}: {exc}") from None
    log.info("YARP RPC port %s answers %s's operations: %s", name, label, ", ".join(sorted(ops)) or "none")

    def close() -> None:
        port.close()
        transport.release(network)

    return RpcPort(name, label, close)


def _reply(result: object) -> list[Item]:
    from scart_yarp import Vocab

    if result is None:
        return [Vocab("ok")]
    conv, problems = plan(type(result))
    if conv is None:
        raise TypeError(f"the result, a {type(result).__name__}, has no bottle form: {'; '.join(problems)}")
    return conv.to_bottle(result)
