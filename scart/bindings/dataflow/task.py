"""Data-flow tasks inside a composite: ``implementation.task``.

``<scart:implementation.task class="pkg.mod:Driver" period="0.01"/>`` hosts a
:class:`dataflow.TaskContext` in the runtime's :class:`dataflow.Deployer` (one per
runtime, :func:`~scart.bindings.dataflow.deployer_of`):

* the task is created with the component's name (its path "Outer/Inner" when nested);
  ``period`` (seconds, > 0) gives it a ``PeriodicActivity``; ``activity="sequential"`` a
  ``SequentialActivity`` (its cycle runs in the thread that stores an event port's sample,
  with no wake-up); without either the task keeps its own default activity (event-driven;
  ``activity="event"`` says so). An unknown activity, or a period with another activity
  than ``periodic``, is refused at load;
* ``<property name="gain">2.5</property>`` sets the task's dataflow ``Property`` of that
  name; values are parsed and validated at load time against the Property's type,
  bounds and ``check`` (a read-only property refuses any value), problems reported as
  ``file:line`` (``scart validate`` says what ``scart run`` would: see
  :mod:`~scart.bindings.dataflow._checks`), as are names ``--remap`` would give that a task
  could not run under;
* lifecycle: at the component's start the task is added to the deployer, its
  properties set, configured, connected to the tasks already added (see below) and
  started; at the component's stop (reverse order of start) it is stopped, cleaned up
  and disconnected;
* its ``@operation`` s form one SCA service named after the task class, so an SCA
  reference can target the task component and call its operations (in the caller's
  thread, or the activity's for ``own_thread`` ones).

Its links to other tasks are ``scart:connect`` elements (:mod:`~scart.bindings.dataflow.connect`).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import typing
from collections.abc import Callable
from typing import TYPE_CHECKING

import pydantic
from pydantic_core import core_schema

from dataflow import Activity, PeriodicActivity, SequentialActivity, TaskContext
from scart.errors import SCART_IMPORT, RuntimeStateError, ScartError
from scart.bindings.dataflow._checks import property_problems, remap_problems
from scart.bindings.dataflow._host import TASK_KIND, DataflowHost, host_of
from scart.bindings.dataflow._plan import MIN_PERIOD_S
from scart.bindings.dataflow.connect import connect_present
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import (
    DEFAULT, AssemblyView, CheckContext, ComponentManager, ComponentType, Host, Implementation, ImplementationProblem,
    ImplementationProvider, InterfaceInfo, Node, Operation, Problem, PropSpec,
)

if TYPE_CHECKING:
    from dataflow.properties import Property

__all__ = ["TASK_NOT_A_TASK", "TaskImplementation", "TaskManager", "retire", "task_class", "task_interface"]

log = logging.getLogger("scart.dataflow")

#: Problem codes of this module.
TASK_NOT_A_TASK = "SCART-T001"  # implementation.task class is not a TaskContext / bad period or activity


# --- implementation.task ------------------------------------------------------------------


def task_class(impl: Implementation, context: CheckContext) -> type[TaskContext]:
    """Import and check the class of an ``implementation.task``; raises ``ImplementationProblem``."""
    ref = impl.attributes.get("class", "")
    try:
        cls = context.import_object(ref)
    except Exception as exc:  # any import-time failure is a composite problem
        raise ImplementationProblem(SCART_IMPORT, f"cannot import {ref!r}: {type(exc).__name__}: {exc}") from exc
    if not (isinstance(cls, type) and issubclass(cls, TaskContext)):
        raise ImplementationProblem(TASK_NOT_A_TASK, f"{ref!r} is not a dataflow.TaskContext subclass")
    return cls


def _period(impl: Implementation) -> float | None:
    raw = impl.attributes.get("period")
    if raw is None:
        return None
    try:
        period = PeriodicActivity._checked(float(raw))
    except ValueError:
        raise ImplementationProblem(TASK_NOT_A_TASK, f"period {raw!r}: expected seconds > 0") from None
    if period < MIN_PERIOD_S:  # a busy loop, not a period
        raise ImplementationProblem(TASK_NOT_A_TASK, f"period {raw!r}: at least {MIN_PERIOD_S} s")
    return period


#: The activities ``activity="..."`` names (``periodic`` needs a ``period``).
ACTIVITIES = ("event", "sequential", "periodic")


def _activity(impl: Implementation) -> Callable[[], Activity] | None:
    """What makes the task's activity from ``period`` and ``activity`` (None: the task's
    own default); raises ``ImplementationProblem`` for an unknown one or a mismatch."""
    period = _period(impl)
    kind = impl.attributes.get("activity", "periodic" if period is not None else "event")
    if kind not in ACTIVITIES:
        raise ImplementationProblem(TASK_NOT_A_TASK, f"activity {kind!r}: expected one of {', '.join(ACTIVITIES)}")
    if (kind == "periodic") != (period is not None):
        raise ImplementationProblem(TASK_NOT_A_TASK, f"activity {kind!r} with period {impl.attributes.get('period')!r}: "
                                    "a period goes with activity \"periodic\" (or no activity) only, and "
                                    "\"periodic\" needs one")
    if period is not None:
        return lambda: PeriodicActivity(period)
    return SequentialActivity if kind == "sequential" else None


@functools.lru_cache(maxsize=1024)
def _checked_type(prop: Property[object]) -> object:
    """The type the assembler parses a property value as: the Property's type, with its
    ``check`` attached (so a value the task would refuse is a load-time problem).

    Built once per Property declaration: ``scart.values`` caches a TypeAdapter per type,
    so a fresh class on every ``component_type()`` would miss that cache and grow it."""
    validate = prop.check
    if validate is None or prop.type is str or typing.get_origin(prop.type) in (list, tuple, set):
        return prop.type

    base = prop.type

    def check(value: object) -> object:
        try:
            validate(value)
        except ValueError as exc:
            raise ValueError(f"refused by its check: {exc}") from None
        return value

    def schema(cls: type, source: object, handler: pydantic.GetCoreSchemaHandler) -> core_schema.CoreSchema:
        return core_schema.no_info_after_validator_function(check, handler(base))

    # named like the base type, so the assembler's messages read "not a valid float"
    return type(getattr(base, "__name__", "value"), (), {"__get_pydantic_core_schema__": classmethod(schema)})


def task_interface(cls: type[TaskContext]) -> InterfaceInfo:
    """The SCA service of a task class: one operation per ``@operation``. Its
    ``python_type`` holds the operations' functions by operation name, so that a remote
    binding checks their arguments as the data-flow path does (declared types and bounds)."""
    ops: dict[str, Operation] = {}
    functions: dict[str, object] = {}
    for name, attr in cls._operation_attrs.items():
        functions[name] = getattr(cls, attr)
        ann = getattr(functions[name], "__annotations__", {}).get("return")
        ops[name] = Operation(name, False, ann not in (None, "None", type(None)))
    return InterfaceInfo(cls.__name__, ops, None, True, type(cls.__name__, (), functions))


class TaskImplementation(ImplementationProvider):
    """The ``implementation.task`` kind (see the module docstring)."""

    name = TASK_KIND

    def component_type(self, impl: Implementation, context: CheckContext) -> ComponentType:
        """The task's service (its operations) and properties; raises ``ImplementationProblem``."""
        cls = task_class(impl, context)
        props: dict[str, tuple[PropSpec, object]] = {}
        for name, prop in cls._property_decls.items():
            spec = PropSpec(prop.default, False)
            spec.name = name
            props[name] = (spec, _checked_type(prop))
        ctype = ComponentType(cls, {cls.__name__: task_interface(cls)}, {}, props, (), (), (), (), "composite", True)
        try:
            _activity(impl)
        except ImplementationProblem as exc:
            exc.partial = ctype  # the assembler still checks the rest
            raise
        return ctype

    def check(self, nodes: list[Node], assembly: AssemblyView, context: CheckContext) -> list[Problem]:
        """What starting the tasks would refuse: property values, names after ``--remap``."""
        return property_problems(nodes) + remap_problems(nodes, assembly, DataflowSettings.of(context.settings).remap)

    def manager(self, node: Node, host: Host) -> ComponentManager:
        """A :class:`TaskManager`."""
        return TaskManager(node, host)

    def activate(self, host: Host) -> DataflowHost:
        """The runtime's data-flow host: it serves the tasks when the settings say ``serve``."""
        return host_of(host)


class TaskManager(ComponentManager):
    """Creates, deploys, starts and stops the one TaskContext of a task component."""

    def __init__(self, node: Node, host: Host) -> None:
        super().__init__(node, host)
        self.task: TaskContext | None = None

    def method(self, operation: str) -> Callable[..., object]:
        """``task.call(operation, ...)`` (raises ``RuntimeStateError`` before start)."""

        def call(*args: object, **kwargs: object) -> object:
            task = self.task
            if task is None:
                raise RuntimeStateError(f"task component {self.node.path} is not started")
            return task.call(operation, *args, **kwargs)

        return call

    def start(self) -> None:
        """Create, deploy, set properties, configure, connect to present peers, start.

        Raises ``ScartError`` naming the task when a step is refused."""
        impl = self.node.model.implementation
        assert impl is not None
        dataflow_host = host_of(self.host)
        remap = DataflowSettings.of(self.host.settings).remap
        task = self.node.ctype.cls(remap.component(self.node.path))
        try:
            for name in list(task.ports()):
                task.rename_port(name, remap.port(self.node.path, name))
        except ValueError as exc:  # two ports remapped onto one name
            raise ScartError(f"task {task.name}: --remap: {exc}") from None
        make_activity = _activity(impl)
        if make_activity is not None:
            task.set_activity(make_activity())
        for name, value in self.node.properties.items():
            if value is not DEFAULT:
                task.set_property(name, value)
        dataflow_host.deployer.add(task)
        self.task = task
        self.stage = "configure_hook"
        if not task.configure():
            raise ScartError(f"task {task.name}: configure refused (state {task.state.name})")
        self.stage = "connecting its ports"
        connect_present(self.host, task.name)
        self.stage = "start_hook"
        if not task.start():
            raise ScartError(f"task {task.name}: start refused (state {task.state.name})")
        self.stage = "started"
        dataflow_host.refresh()

    def stop(self) -> None:
        """Stop, clean up and disconnect the task (idempotent; refusals are logged)."""
        if self.task is not None:
            retire(self.task)

    def instance(self) -> object | None:
        """The task once started."""
        return self.task


def retire(task: TaskContext) -> None:
    """Stop, clean up and disconnect ``task`` (each step only where it applies: idempotent)."""
    if task.is_running():
        task.stop()
    if task.is_configured():
        task.cleanup()
    for port in task.ports().values():
        port.disconnect()
