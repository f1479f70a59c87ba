"""Properties (validated on set), operations (introspection, call), port declaration rules."""

from __future__ import annotations

import pytest

from dataflow import (
    InputPort,
    NotFoundError,
    OutputPort,
    PortTypeError,
    Property,
    PropertyValueError,
    TaskContext,
    operation,
)


def positive(v: float) -> None:
    if v <= 0:
        raise ValueError("must be > 0")


class Ctl(TaskContext):
    cmd = InputPort(list[float], doc="set-points")
    new_period = InputPort(float, name="period")
    out = OutputPort(float, name="y", doc="output")
    gain = Property(float, 1.0, doc="gain")
    label = Property(str, "a", doc="label")
    limit = Property(float, 2.0, doc="limit", check=positive)

    @operation
    def reset(self) -> None:
        """Reset the controller."""

    @operation
    def scale(self, value: float, times: int = 2) -> float:
        """Scale a value."""
        return value * times * self.gain


def test_property_read_write_validate():
    c = Ctl("c")
    assert c.gain == 1.0
    c.gain = 2  # lax coercion
    assert c.gain == 2.0 and isinstance(c.gain, float)
    c.set_property("gain", "3.5")
    assert c.get_property("gain") == 3.5
    with pytest.raises(PortTypeError, match=r"c\.gain"):
        c.gain = "abc"
    with pytest.raises(PropertyValueError, match=r"c\.limit"):
        c.limit = -1.0
    assert c.limit == 2.0
    with pytest.raises(NotFoundError, match="gain"):
        c.get_property("nope")
    d = Ctl("d")
    assert d.gain == 1.0  # per-instance values


def test_properties_mapping():
    c = Ctl("c")
    props = c.properties()
    assert set(props) == {"gain", "label", "limit"}
    p = props["gain"]
    assert (p.name, p.type_name, p.doc, p.value) == ("gain", "float64", "gain", 1.0)
    p.set(4.0)
    assert c.gain == 4.0


def test_operations_introspection_and_call():
    c = Ctl("c")
    ops = c.operations()
    assert set(ops) == {"reset", "scale"}
    assert ops["reset"].signature == "reset() -> None"
    assert ops["reset"].doc == "Reset the controller."
    s = ops["scale"]
    assert s.params == [("value", "float64"), ("times", "int64")]
    assert s.returns == "float64" and s.own_thread is False
    assert s.signature == "scale(value: float64, times: int64) -> float64"
    assert c.call("scale", 2.0) == 4.0
    assert c.call("scale", 2.0, times=3) == 6.0
    with pytest.raises(NotFoundError, match="scale"):
        c.call("missing")


def test_ports_by_name_and_attribute():
    c = Ctl("c")
    assert set(c.ports()) == {"cmd", "period", "y"}
    assert c.port("period") is c.new_period
    assert c.new_period.task is c and c.new_period.name == "period"
    assert c.cmd is not Ctl("d").cmd  # each task its own port
    assert c.out.qualname == "c.y"
    with pytest.raises(NotFoundError) as err:
        c.port("nope")
    assert "period" in str(err.value)
    extra = c.add_port(OutputPort(int), "extra")
    assert c.port("extra") is extra and extra.task is c
    with pytest.raises(ValueError):
        c.add_port(OutputPort(int), "extra")


def test_port_shadowing_task_api_refused_at_class_creation():
    with pytest.raises(TypeError, match="shadow"):

        class Bad(TaskContext):
            state = InputPort(float)

    with pytest.raises(TypeError, match="shadow"):

        class Bad2(TaskContext):
            p = InputPort(float, name="configure")


def test_describe():
    c = Ctl("c")
    d = c.describe()
    assert d.name == "c" and d.state == "STOPPED" and d.activity == "event"
    ports = {p.name: p for p in d.ports}
    assert ports["period"].direction == "in" and ports["y"].direction == "out"
    assert ports["cmd"].type_name == "float64[]" and ports["y"].doc == "output"
    assert {p.name: p.value for p in d.properties}["gain"] == 1.0
    assert {o.name for o in d.operations} == {"reset", "scale"}
    assert d.model_dump(mode="json")["ports"][0]["connections"] == 0
