"""Guards the curated public API of dataflow and its independence from scart."""

from __future__ import annotations

import subprocess
import sys

import dataflow

CONTRACT = {
    "TaskContext", "TaskState", "InputPort", "OutputPort", "ConnPolicy", "ConnType", "LockPolicy",
    "BufferPolicy", "FlowStatus", "WriteStatus", "Property", "operation", "PeriodicActivity",
    "SlaveActivity", "EventActivity", "Deployer", "TypeRegistry", "registry", "register_type",
    "UnknownValue", "Encoded", "DataflowError", "PortTypeError", "NotFoundError", "DeploymentError",
    "TaskDescription", "PortDescription", "PropertyDescription", "OperationDescription",
}
EXTRA = {"Activity", "Connection", "PropertyValueError", "PortValueError", "WaitMode", "Array", "ArraySpec",
         "SequentialActivity"}


def test_exports_exactly():
    assert set(dataflow.__all__) == CONTRACT | EXTRA
    assert len(dataflow.__all__) == len(set(dataflow.__all__))
    for name in dataflow.__all__:
        assert getattr(dataflow, name) is not None


def test_error_tree():
    from dataflow import DataflowError, DeploymentError, NotFoundError, PortTypeError

    assert issubclass(PortTypeError, DataflowError) and issubclass(PortTypeError, TypeError)
    assert issubclass(NotFoundError, DataflowError) and issubclass(NotFoundError, KeyError)
    assert issubclass(DeploymentError, DataflowError)


def test_dataflow_never_imports_scart():
    code = "import sys, dataflow; import dataflow.deployer; print('scart' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "False", out.stderr
