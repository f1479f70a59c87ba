"""TaskContext: a data-flow component with RTT 2.9's lifecycle (``TaskCore``).

States (ordered as RTT's enum): ``INIT < PRE_OPERATIONAL < FATAL_ERROR < EXCEPTION <
STOPPED < RUNNING < RUN_TIME_ERROR``. A task starts in its *initial state*: ``STOPPED``,
or ``PRE_OPERATIONAL`` when created as needing configuration.

Transitions (✓ allowed; ✗ refused: returns False and logs task, state and transition):

================  ===========  =========  ========  =========  ==============  ============
state             configure    start      stop      cleanup    recover         error
================  ===========  =========  ========  =========  ==============  ============
INIT              ✗            ✗          ✗         ✗          ✗               ✗ (ignored)
PRE_OPERATIONAL   ✓ →STOPPED   ✗          ✗         ✗          ✗               ✗ (ignored)
FATAL_ERROR       ✗            ✗          ✗         ✗          ✗               ✗
EXCEPTION         ✗            ✗          ✗         ✗          ✓ →initial      ✗
STOPPED           ✓ →STOPPED   ✓ →RUNNING ✗         ✓ →PRE_OP  ✗               ✗ (ignored)
RUNNING           ✗            ✗          ✓ →STOP.  ✗          ✗               ✓ →RUN_TIME_ERROR
RUN_TIME_ERROR    ✗            ✗          ✓ →STOP.  ✗          ✓ →RUNNING      ✓ (stays)
================  ===========  =========  ========  =========  ==============  ============

Hooks and vetoes: ``configure_hook`` and ``start_hook`` veto by returning ``False``
(``None`` counts as success): a vetoed configure lands in ``PRE_OPERATIONAL``, a vetoed
start stays ``STOPPED``; both transitions then return False. ``stop_hook``,
``cleanup_hook``, ``update_hook``, ``error_hook``, ``exception_hook`` cannot veto.

Cycles (run by the activity): in ``RUNNING`` → ``update_hook``; if ``error()`` was called
during it, ``error_hook`` runs in that same cycle; in ``RUN_TIME_ERROR`` → ``error_hook``
instead of ``update_hook`` until ``recover()``. ``error()`` is ignored (False) while the
target state is below ``RUNNING``.

Exceptions: an exception escaping any hook is logged once with its traceback and moves
the task to ``EXCEPTION``; on the way ``stop_hook`` runs if it was running (not when the
exception came from ``stop_hook`` itself), ``cleanup_hook`` if it was configured
(``>= STOPPED``) and its initial state is ``PRE_OPERATIONAL`` (not when the exception came
from ``cleanup_hook``), then ``exception_hook``;
the activity stops. An exception while doing that → ``FATAL_ERROR``: activity stopped,
every transition refused for good. ``recover()`` from ``EXCEPTION`` returns to the
initial state. Nothing of this touches other tasks.

Threading: transitions may be called from any thread (they serialise on a per-task
lock, released while joining the activity thread); ``stop()`` is idempotent and safe
from inside a hook (from ``update_hook`` it signals the activity and returns).
"""

from __future__ import annotations

import enum
import inspect
import logging
import threading
from concurrent.futures import Future
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from .activities import Activity, EventActivity
from .clock import WALL, Clock
from .errors import NotFoundError
from .introspection import (
    OperationDescription,
    PortDescription,
    PropertyDescription,
    TaskDescription,
)
from .operations import describe_operation, spec_of
from .ports import InputPort, OutputPort, Port
from .properties import BoundProperty, Property
from scart_wire.types import registry

if TYPE_CHECKING:
    from .tf.buffer import FrameBuffer

__all__ = ["TaskContext", "TaskState"]

PortT = TypeVar("PortT", bound=Port[Any])

log = logging.getLogger(__name__)


class TaskState(enum.IntEnum):
    """RTT 2.9 ``TaskCore::TaskState``, in RTT's order (comparisons are meaningful)."""

    INIT = 0
    PRE_OPERATIONAL = 1
    FATAL_ERROR = 2
    EXCEPTION = 3
    STOPPED = 4
    RUNNING = 5
    RUN_TIME_ERROR = 6

    def __str__(self) -> str:
        return self.name


S = TaskState


class TaskContext:
    """A data-flow component: ports, properties, operations, lifecycle, one activity.

    Subclass it, declare ports/properties/operations on the class, override hooks.
    Declaring a port whose attribute or port name would shadow the task API raises
    ``TypeError`` when the class is created.
    """

    _port_templates: dict[str, Port[Any]] = {}
    _property_decls: dict[str, Property[Any]] = {}
    _operation_attrs: dict[str, str] = {}
    #: The time this task lives in (:mod:`dataflow.clock`): the system's unless its deployer
    #: follows a simulation's (:meth:`Deployer.use_clock`); its periodic activity counts on it.
    clock: Clock = WALL

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        ports = dict(cls._port_templates)
        props = dict(cls._property_decls)
        ops = dict(cls._operation_attrs)
        for attr, value in cls.__dict__.items():
            if isinstance(value, Port):
                for n in {attr, value.name}:
                    if n in _RESERVED:
                        raise TypeError(
                            f"{cls.__name__}.{attr}: port name {n!r} would shadow the TaskContext "
                            f"API; use another attribute and InputPort(..., name=...)"
                        )
                ports[attr] = value
            elif isinstance(value, Property):
                if attr in _RESERVED:
                    raise TypeError(f"{cls.__name__}.{attr}: property would shadow the TaskContext API")
                props[attr] = value
            elif callable(value) and spec_of(value) is not None:
                ops[attr] = attr
        names = [p.name for p in ports.values()]
        dupes = {n for n in names if names.count(n) > 1}
        if dupes:
            raise TypeError(f"{cls.__name__}: duplicate port names {sorted(dupes)}")
        cls._port_templates, cls._property_decls, cls._operation_attrs = ports, props, ops

    def __init__(self, name: str, initial_state: TaskState = TaskState.STOPPED) -> None:
        if initial_state not in (S.STOPPED, S.PRE_OPERATIONAL):
            raise ValueError(f"initial_state must be STOPPED or PRE_OPERATIONAL, got {initial_state!r}")
        self.name = name
        self._tc_initial = TaskState(initial_state)
        self._tc_state = self._tc_initial
        self._tc_target = self._tc_initial
        self._tc_lock = threading.RLock()
        self._tc_stopping = False
        self._prop_values: dict[str, Any] = {n: p.default for n, p in self._property_decls.items()}
        self._tc_ports: dict[str, Port[Any]] = {}
        for attr, template in self._port_templates.items():
            port = template._clone()
            self.__dict__[attr] = port  # this task's own port; the class keeps the template
            self.add_port(port)
        self._tc_activity: Activity = EventActivity()
        self._tc_activity.task = self
        self._tc_frames: FrameBuffer | None = None
        self._tc_frames_from: Callable[[], FrameBuffer] | None = None  # its deployer's, once added

    # -- frames -----------------------------------------------------------------
    @property
    def frames(self) -> FrameBuffer:
        """The frame tree this task reads and publishes through (:mod:`dataflow.tf`):
        its deployer's, the one of its process (a composite's ``<scart:frames>`` joins it to
        ROS); a task in no deployer gets one of its own, made on first use. Thread-safe."""
        frames = self._tc_frames
        if frames is None:
            if self._tc_frames_from is not None:
                frames = self._tc_frames_from()
            else:
                from .tf.buffer import FrameBuffer

                frames = FrameBuffer()
            self._tc_frames = frames
        return frames

    @frames.setter
    def frames(self, buffer: FrameBuffer) -> None:
        self._tc_frames = buffer

    # -- state ----------------------------------------------------------------
    @property
    def state(self) -> TaskState:
        """The current lifecycle state."""
        return self._tc_state

    @property
    def initial_state(self) -> TaskState:
        """The state this task starts in and returns to on ``recover()`` from EXCEPTION."""
        return self._tc_initial

    @property
    def activity(self) -> Activity:
        """The activity running this task's cycles."""
        return self._tc_activity

    def is_running(self) -> bool:
        """True in RUNNING or RUN_TIME_ERROR."""
        return self._tc_state >= S.RUNNING

    def is_configured(self) -> bool:
        """True in STOPPED, RUNNING or RUN_TIME_ERROR."""
        return self._tc_state >= S.STOPPED

    def set_activity(self, activity: Activity) -> bool:
        """Give the task another activity; refused (False) while running or if owned elsewhere."""
        with self._tc_lock:
            if self.is_running() or (activity.task is not None and activity.task is not self):
                log.warning("task %s: set_activity refused in state %s", self.name, self._tc_state.name)
                return False
            self._tc_activity.task = None
            activity.task = self
            self._tc_activity = activity
            return True

    # -- hooks (override) -----------------------------------------------------
    def configure_hook(self) -> bool | None:
        """Configure; return False to veto (the task stays/lands in PRE_OPERATIONAL)."""
        return True

    def start_hook(self) -> bool | None:
        """Prepare to run; return False to veto (the task stays STOPPED)."""
        return True

    def update_hook(self) -> None:
        """One cycle of business logic (RUNNING)."""

    def error_hook(self) -> None:
        """Cycle in RUN_TIME_ERROR (instead of update_hook)."""

    def stop_hook(self) -> None:
        """Leaving RUNNING."""

    def cleanup_hook(self) -> None:
        """Unconfigure (STOPPED → PRE_OPERATIONAL)."""

    def exception_hook(self) -> None:
        """Entering EXCEPTION (after stop_hook/cleanup_hook as applicable)."""

    # -- transitions ----------------------------------------------------------
    def _refuse(self, transition: str) -> bool:
        log.warning("task %s: %s() not allowed in state %s", self.name, transition, self._tc_state.name)
        return False

    def configure(self) -> bool:
        """PRE_OPERATIONAL/STOPPED → STOPPED; a veto lands in PRE_OPERATIONAL. Thread-safe."""
        with self._tc_lock:
            if self._tc_state not in (S.PRE_OPERATIONAL, S.STOPPED):
                return self._refuse("configure")
            self._tc_target = S.STOPPED
            ok = self._call_hook(self.configure_hook)
            if ok is _RAISED:
                return False
            self._tc_state = self._tc_target = S.STOPPED if ok is not False else S.PRE_OPERATIONAL
            return ok is not False

    def start(self) -> bool:
        """STOPPED → RUNNING (starts the activity); a veto stays STOPPED. Thread-safe."""
        with self._tc_lock:
            if self._tc_state is not S.STOPPED:
                return self._refuse("start")
            self._tc_target = S.RUNNING
            ok = self._call_hook(self.start_hook)
            if ok is _RAISED:
                return False
            if ok is False:
                self._tc_target = S.STOPPED
                return False
            if self._tc_state is not S.RUN_TIME_ERROR:  # error() from start_hook keeps RTE
                self._tc_state = S.RUNNING
            self._tc_activity.start()
            return True

    def stop(self) -> bool:
        """RUNNING/RUN_TIME_ERROR → STOPPED: stop the activity (signal, join), then stop_hook.

        Idempotent and safe from inside any hook; never hangs (bounded join): if the
        activity thread does not end within the join timeout (a stuck ``update_hook``), a
        warning is logged and the task is stopped all the same. Returns False when not
        running (logged) or when ``stop_hook`` raised (the task is then in EXCEPTION).
        """
        with self._tc_lock:
            if self._tc_stopping:
                return True
            if not self.is_running():
                return self._refuse("stop")
            self._tc_stopping = True
            self._tc_target = S.STOPPED
        try:
            self._tc_activity.stop()
            with self._tc_lock:
                if self._tc_state < S.RUNNING:  # an exception path already took over
                    return False
                if self._call_hook(self.stop_hook, from_stop=True) is _RAISED:
                    return False
                self._tc_state = S.STOPPED
                return True
        finally:
            self._tc_stopping = False

    def cleanup(self) -> bool:
        """STOPPED → PRE_OPERATIONAL (cleanup_hook). Thread-safe."""
        with self._tc_lock:
            if self._tc_state is not S.STOPPED:
                return self._refuse("cleanup")
            self._tc_target = S.PRE_OPERATIONAL
            if self._call_hook(self.cleanup_hook) is _RAISED:
                return False
            self._tc_state = S.PRE_OPERATIONAL
            return True

    def recover(self) -> bool:
        """RUN_TIME_ERROR → RUNNING; EXCEPTION → initial state. Thread-safe."""
        with self._tc_lock:
            if self._tc_state is S.RUN_TIME_ERROR:
                self._tc_state = self._tc_target = S.RUNNING
                return True
            if self._tc_state is S.EXCEPTION:
                self._tc_state = self._tc_target = self._tc_initial
                return True
            return self._refuse("recover")

    def error(self) -> bool:
        """Enter RUN_TIME_ERROR (from update_hook typically); ignored (False) below RUNNING."""
        if self._tc_target < S.RUNNING:
            log.warning("task %s: error() ignored in state %s", self.name, self._tc_state.name)
            return False
        self._tc_state = self._tc_target = S.RUN_TIME_ERROR
        return True

    def trigger(self) -> bool:
        """Ask the activity for one cycle; refused by a periodic activity (as RTT)."""
        return self._tc_activity.trigger()

    def update(self) -> bool:
        """Run one cycle now in the caller's thread: only with a SlaveActivity (RTT ``update``)."""
        return self._tc_activity.execute()

    # -- machinery --------------------------------------------------------------
    def _call_hook(self, hook: Callable[[], object], from_stop: bool = False) -> object:
        try:
            return hook()
        except Exception as exc:
            self._exception(exc, hook.__name__, from_stop)
            return _RAISED

    def _exception(self, exc: BaseException, where: str, from_stop: bool = False) -> None:
        log.error("task %s: exception in %s", self.name, where, exc_info=exc)
        with self._tc_lock:
            copy = S.STOPPED if from_stop else self._tc_state
            self._tc_state = self._tc_target = S.EXCEPTION
            self._tc_activity.stop()
            try:
                if copy >= S.RUNNING:
                    self.stop_hook()
                if (
                    copy >= S.STOPPED
                    and self._tc_initial is S.PRE_OPERATIONAL
                    and where != "cleanup_hook"  # never re-run the hook that just raised
                ):
                    self.cleanup_hook()
                self.exception_hook()
            except Exception:
                log.exception("task %s: exception while handling an exception: FATAL_ERROR", self.name)
                self._tc_state = self._tc_target = S.FATAL_ERROR

    def _cycle(self) -> None:
        """One cycle as the activity runs it (see the class docstring)."""
        state = self._tc_state
        if state is S.RUNNING:
            try:
                self.update_hook()
            except Exception as exc:
                self._exception(exc, "update_hook")
                return
            state = self._tc_state
        if state is S.RUN_TIME_ERROR:
            try:
                self.error_hook()
            except Exception as exc:
                self._exception(exc, "error_hook")

    # -- ports ----------------------------------------------------------------
    def ports(self) -> dict[str, Port[Any]]:
        """Every port by port name (a copy)."""
        return dict(self._tc_ports)

    def port(self, name: str) -> Port[Any]:
        """The port called ``name``; raises ``NotFoundError`` listing the existing ones."""
        try:
            return self._tc_ports[name]
        except KeyError:
            raise NotFoundError(
                f"task {self.name} has no port {name!r}; ports: {sorted(self._tc_ports) or 'none'}"
            ) from None

    def add_port(self, port: PortT, name: str | None = None) -> PortT:
        """Add a port at run time (name defaults to ``port.name``); returns it.

        Raises ``ValueError`` if the name is empty or taken.
        """
        name = name or port.name
        if not name:
            raise ValueError(f"task {self.name}: a port needs a name")
        if name in self._tc_ports and self._tc_ports[name] is not port:
            raise ValueError(f"task {self.name}: a port {name!r} exists already")
        port.name = name
        port.task = self
        self._tc_ports[name] = port
        if isinstance(port, InputPort) and port.event:
            port.add_data_callback(self._event_port_data)
        return port

    def rename_port(self, old: str, new: str) -> Port[Any]:
        """Give port ``old`` the name ``new`` (remapping at launch: before it is connected or
        served; the task's own code keeps using its attribute). Returns the port; raises
        ``NotFoundError``, or ``ValueError`` when ``new`` is empty or taken."""
        port = self.port(old)
        if new == old:
            return port
        if not new or new in self._tc_ports:
            raise ValueError(f"task {self.name}: cannot rename port {old!r} to {new!r}: "
                             f"{'a port of that name exists' if new else 'empty name'}")
        del self._tc_ports[old]
        port.name = new
        self._tc_ports[new] = port
        return port

    def _event_port_data(self, port: object) -> None:
        if self._tc_state >= S.RUNNING:
            self._tc_activity._on_event()

    # -- properties -----------------------------------------------------------
    def properties(self) -> dict[str, BoundProperty]:
        """Every property of this task by name."""
        return {n: BoundProperty(self, p) for n, p in self._property_decls.items()}

    def get_property(self, name: str) -> Any:
        """The value of property ``name``; raises ``NotFoundError``."""
        self._prop(name)
        return self._prop_values[name]

    def set_property(self, name: str, value: object) -> None:
        """Validate and set property ``name``.

        Raises ``NotFoundError``, ``PortTypeError`` (wrong type) or ``PropertyValueError``.
        Thread-safe (one reference store).
        """
        setattr(self, self._prop(name).name, value)

    def _prop(self, name: str) -> Property[Any]:
        try:
            return self._property_decls[name]
        except KeyError:
            raise NotFoundError(
                f"task {self.name} has no property {name!r}; "
                f"properties: {sorted(self._property_decls) or 'none'}"
            ) from None

    # -- operations -----------------------------------------------------------
    def operations(self) -> dict[str, OperationDescription]:
        """Every operation with its signature and doc."""
        out = {}
        for name, attr in self._operation_attrs.items():
            fn = getattr(type(self), attr)
            spec = spec_of(fn)
            if spec is not None:  # every name here is a declared operation's
                out[name] = describe_operation(name, fn, spec)
        return out

    def check_arguments(self, name: str, args: list[object]) -> list[object]:
        """``args`` of operation ``name`` checked as values from outside, by the one check
        every remote entry uses (:func:`scart_wire.bounds.check_argument`): each against its
        parameter's declared type (numbers strict: no string, no bool), bounds
        (``Annotated[float, Field(ge=...)]``) and finiteness. Returns them converted.
        Raises ``NotFoundError`` for an unknown operation, :class:`~dataflow.errors.PortTypeError`
        or :class:`~dataflow.errors.PortValueError` naming ``task.operation(parameter)``."""
        import typing

        from scart_wire.bounds import check_argument

        attr = self._operation_attrs.get(name)
        if attr is None:
            raise NotFoundError(f"task {self.name} has no operation {name!r}")
        fn = getattr(type(self), attr)
        try:
            hints = typing.get_type_hints(fn, include_extras=True)
        except Exception:  # noqa: BLE001 - unresolvable annotations: nothing checkable
            hints = {}
        params = [p for p in inspect.signature(fn).parameters if p != "self"]
        out = list(args)
        for i, (param, value) in enumerate(zip(params, args, strict=False)):
            out[i] = check_argument(f"{self.name}.{name}({param})", hints.get(param), value)
        return out

    def call(self, name: str, *args: object, **kwargs: object) -> Any:
        """Call operation ``name``; blocks until it returned; re-raises what it raised.

        ``own_thread`` operations run in the activity's thread when it has a live one.
        Raises ``NotFoundError`` for an unknown operation. To wait with a deadline, use
        :meth:`send`.
        """
        return self.send(name, *args, **kwargs).result()

    def send(self, name: str, *args: object, **kwargs: object) -> Future[Any]:
        """Start operation ``name`` and return a :class:`~concurrent.futures.Future` (RTT's
        ``send``/``collect``).

        An ``own_thread`` operation is queued to the activity's live thread and the future
        completes when that thread ran it: ``future.result(timeout)`` waits with a deadline,
        and ``future.cancel()`` withdraws it if it has not started. Any other operation runs
        now, in the caller's thread, and the returned future is already done. Raises
        ``NotFoundError`` (at once) for an unknown operation.
        """
        attr = self._operation_attrs.get(name)
        if attr is None:
            raise NotFoundError(
                f"task {self.name} has no operation {name!r}; "
                f"operations: {sorted(self._operation_attrs) or 'none'}"
            )
        fn = getattr(self, attr)
        spec = spec_of(fn)
        if spec is not None and spec.own_thread:  # queued where the activity has a live thread
            fut = self._tc_activity._submit(lambda: fn(*args, **kwargs))
            if fut is not None:
                return fut
        done: Future[Any] = Future()
        try:
            done.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller, who re-raises it from result()
            done.set_exception(exc)
        return done

    # -- introspection ----------------------------------------------------------
    def describe(self) -> TaskDescription:
        """This task as plain data (thread-safe snapshot)."""
        act = self._tc_activity
        ports = [
            PortDescription(
                name=n,
                direction="in" if p.is_input else "out",
                type_name=p.type_name,
                doc=p.doc,
                connections=p.connection_count(),
                event=bool(getattr(p, "event", False)),
                bounds=p.bounds.text if isinstance(p, InputPort) and p.bounds is not None else "",
                check=getattr(p, "check_text", ""),
                writes=p.last_sample()[0] if isinstance(p, OutputPort) else 0,
                streams=[s.note() for s in p.streams],
            )
            for n, p in self._tc_ports.items()
        ]
        cycles, last_cycle = act.stamp if act.stamp[1] else (act.cycles, 0.0)
        props = [
            PropertyDescription(
                name=n, type_name=p.type_name, value=registry.to_jsonable(p.value), doc=p.doc,
                bounds=p.prop.bounds.text if p.prop.bounds is not None else "",
            )
            for n, p in self.properties().items()
        ]
        return TaskDescription(
            name=self.name,
            state=self._tc_state.name,
            activity=act.kind,
            period=act.period,
            cycles=cycles,
            overruns=act.overruns,
            last_cycle=last_cycle,
            ports=ports,
            properties=props,
            operations=list(self.operations().values()),
        )

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} {self._tc_state.name}>"


_RAISED = object()
_RESERVED = frozenset(n for n in dir(TaskContext) if not n.startswith("_")) | {
    "name",
    "state",
    "activity",
}
