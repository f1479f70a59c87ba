"""dataflow: Orocos RTT-style data-flow components for Python.

The story — declare, deploy, connect, run, stop::

    from dataflow import TaskContext, InputPort, OutputPort, Property, FlowStatus
    from dataflow import Deployer, ConnPolicy

    class Doubler(TaskContext):
        x = InputPort(float, event=True)
        y = OutputPort(float)
        gain = Property(float, 2.0, doc="multiplier")
        def update_hook(self) -> None:
            flow, v = self.x.read()            # FlowStatus.NO_DATA / OLD_DATA / NEW_DATA
            if flow is FlowStatus.NEW_DATA:
                self.y.write(self.gain * v)    # WriteStatus

    with Deployer() as d:
        d.add(Source("source"))                # some task with an OutputPort(float) "out"
        d.add(Doubler("doubler"))
        d.connect("source.out", "doubler.x", ConnPolicy.buffer(8))
        d.configure_all(); d.start_all()
        ...                                    # stop_all() + cleanup_all() on exit

Ports never block and never take a lock on the hot path (:mod:`dataflow.buffers`
explains the guarantee); the lifecycle is RTT 2.9's (:mod:`dataflow.task` has the
table); activities own their threads (:mod:`dataflow.activities`). This package never
imports ``scart``.
"""

from .activities import Activity, EventActivity, PeriodicActivity, SequentialActivity, SlaveActivity
from .deployer import Deployer
from .errors import DataflowError, DeploymentError, NotFoundError, PortTypeError, PortValueError, PropertyValueError
from .introspection import (
    OperationDescription,
    PortDescription,
    PropertyDescription,
    TaskDescription,
)
from .operations import operation
from .policy import BufferPolicy, ConnPolicy, ConnType, FlowStatus, LockPolicy, WaitMode, WriteStatus
from .ports import Connection, InputPort, OutputPort
from .properties import Property
from .task import TaskContext, TaskState
from scart_wire.arrays import Array, ArraySpec
from scart_wire.types import Encoded, TypeRegistry, UnknownValue, register_type, registry

__all__ = [
    "TaskContext",
    "TaskState",
    "InputPort",
    "OutputPort",
    "Connection",
    "ConnPolicy",
    "ConnType",
    "LockPolicy",
    "BufferPolicy",
    "FlowStatus",
    "WaitMode",
    "WriteStatus",
    "Property",
    "operation",
    "Activity",
    "PeriodicActivity",
    "SlaveActivity",
    "EventActivity",
    "SequentialActivity",
    "Deployer",
    "TypeRegistry",
    "registry",
    "register_type",
    "UnknownValue",
    "Encoded",
    "Array",
    "ArraySpec",
    "DataflowError",
    "PortTypeError",
    "NotFoundError",
    "DeploymentError",
    "PropertyValueError",
    "PortValueError",
    "TaskDescription",
    "PortDescription",
    "PropertyDescription",
    "OperationDescription",
]
