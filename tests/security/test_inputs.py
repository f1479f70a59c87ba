"""Inputs that cannot hurt: properties, input ports and operation arguments declare ranges
and finiteness, and a value from outside beyond them is refused — reported to whoever
sent it — before it reaches the task."""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Iterator
from typing import Annotated

import pydantic
import pytest

from dataflow import Deployer, InputPort, PortValueError, Property, SlaveActivity, TaskContext, operation
from dataflow.remote import RemoteValueError, connect
from support import ROOT

sys.path.insert(0, str(ROOT / "composites" / "youbot"))
from driver import YouBotDriver  # noqa: E402


@pytest.fixture
def driver() -> Iterator[tuple[YouBotDriver, str]]:
    deployer = Deployer()
    task = YouBotDriver()
    task.set_activity(SlaveActivity())
    deployer.add(task)
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0")
    try:
        yield task, server.address
    finally:
        server.stop()
        deployer.stop_all()


@pytest.mark.parametrize("bad", [math.nan, -math.inf, math.inf, -1.0, 1e6])
def test_safety_limits_cannot_be_set_to_nonsense(driver: tuple[YouBotDriver, str], bad: float) -> None:
    task, address = driver
    with connect(address) as system, pytest.raises(RemoteValueError, match="youBotDriver.max_velocity"):
        system.component("youBotDriver").set_property("max_velocity", bad)
    assert task.max_velocity == 1.0


def test_set_points_beyond_the_port_bounds_are_refused_to_the_writer(driver: tuple[YouBotDriver, str]) -> None:
    task, address = driver
    with connect(address) as system:
        proxy = system.component("youBotDriver")
        for bad in ([math.nan, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, -1e304]):
            with pytest.raises(RemoteValueError, match=r"youBotDriver\.commands: .* refused: .*-6\.28319 <= x <= 6\.28319"):
                proxy.write("commands", bad)
        assert proxy.write("commands", [0.1] * 5).name == "WRITE_SUCCESS"
        described = {p.name: p.bounds for p in proxy.describe().ports}
        assert described["commands"] == "-6.28319 <= x <= 6.28319, finite"
        with pytest.raises(RemoteValueError, match=r"set_period\(seconds\).*finite"):
            proxy.call("set_period", math.nan)


@pytest.mark.subprocess
def test_the_cli_reports_a_refused_write(driver: tuple[YouBotDriver, str]) -> None:
    _, address = driver
    out = subprocess.run([sys.executable, "-m", "scart", "write", "youBotDriver.commands", "[NaN, 0, 0, 0, 0]",
                          "--ns", address], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 1 and out.stderr.count("\n") == 1
    assert "youBotDriver.commands" in out.stderr and "finite" in out.stderr


class Bounded(TaskContext):
    gain = Property(float, 1.0, ge=0.0, le=10.0)
    ratio = Property(float, 0.5, gt=0.0, lt=1.0)
    raw = Property(float, 0.0, finite=False)
    target = InputPort(float, ge=-1.0, le=1.0)
    anything = InputPort(float, finite=False)

    @operation
    def move(self, speed: Annotated[float, pydantic.Field(ge=0.0, le=2.0)], note: str) -> float:
        return speed


def test_bounds_are_declared_and_checked() -> None:
    task = Bounded("b")
    task.raw = math.inf  # finite=False: a measurement may be infinite
    with pytest.raises(ValueError, match="less than 1"):
        task.ratio = 1.0
    with pytest.raises(PortValueError, match=r"b\.target: 2\.0 refused"):
        task.port("target").admit(2.0)
    assert task.port("anything").admit(math.nan) != 0  # NaN passes where it is allowed
    assert task.check_arguments("move", [1.5, "x"]) == [1.5, "x"]
    with pytest.raises(PortValueError, match=r"b\.move\(speed\): 3\.0 refused"):
        task.check_arguments("move", [3.0, "x"])
    with pytest.raises(ValueError, match="ge=nan"):
        Property(float, 1.0, ge=math.nan)
    with pytest.raises(ValueError, match="no value can satisfy"):
        Property(float, 1.0, ge=2.0, le=1.0)
    with pytest.raises(ValueError):
        Property(float, 5.0, le=1.0)  # a default outside its own bounds
    with pytest.raises(ValueError, match="apply to numbers"):
        Property(str, "x", ge=0.0)


class Pose(pydantic.BaseModel):
    x: float
    y: float


class Nested(TaskContext):
    maybe = Property(float | None, None)
    pair = Property(tuple[float, float], (0.0, 0.0))
    pose = Property(Pose, Pose(x=0, y=0))
    config = Property(dict, {})
    label = Property(str, "n")
    goal = InputPort(Pose)

    @operation
    def speed(self, v: Annotated[float, pydantic.Field(ge=0.0)]) -> float:
        return v

    @operation
    def raw(self, v: Annotated[float, pydantic.Field(allow_inf_nan=True)]) -> float:
        return v

    @operation
    def go(self, pose: Pose, via: list[tuple[float, float]]) -> None: ...


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_numbers_are_finite_wherever_they_sit_in_a_value(bad: float) -> None:
    task = Nested("n")
    for name, value in (("maybe", bad), ("pair", (1.0, bad)), ("pose", {"x": 1.0, "y": bad}),
                        ("config", {"gain": [1.0, bad]})):
        with pytest.raises(ValueError, match="not a finite number"):
            task.set_property(name, value)
    with pytest.raises(PortValueError, match="not a finite number"):
        task.port("goal").admit(Pose(x=bad, y=0.0))
    with pytest.raises(PortValueError, match=r"n\.speed\(v\)"):
        task.check_arguments("speed", [bad])  # a lower bound alone does not let inf through
    with pytest.raises(PortValueError, match=r"n\.go\(via\)"):
        task.check_arguments("go", [Pose(x=0, y=0), [(0.0, 1.0), (bad, 2.0)]])
    assert math.isnan(task.check_arguments("raw", [math.nan])[0])  # allow_inf_nan=True: its own choice
    task.set_property("label", "still fine")


def test_binding_grpc_arguments_are_checked_as_values_from_outside() -> None:
    from scart_wire import codec
    from scart.errors import InvocationError
    from scart.bindings.grpc._wire import Signature

    class Arm:
        def move(self, v: Annotated[float, pydantic.Field(ge=0.0, le=1.0)], w: float) -> None: ...

    read = Signature(Arm.move)
    assert read.args([codec.encode(0.5), codec.encode(2.0)]) == (0.5, 2.0)
    with pytest.raises(InvocationError, match="less than or equal to 1"):
        read.args([codec.encode(5.0), codec.encode(0.1)])
    with pytest.raises(InvocationError, match="not a finite number"):
        read.args([codec.encode(0.5), codec.encode(math.nan)])
    with pytest.raises(InvocationError, match="not a finite number"):
        read.kwargs({"w": codec.encode(math.inf)})


# ---- property @file ---------------------------------------------------------------------

def _composite_with_file(tmp_path, file: str, prop: str = "number"):
    from support.sca import composite, py, write

    return write(tmp_path, {"f.composite": composite(
        f'<component name="P">{py("Props")}<property name="{prop}" file="{file}"/></component>')})


def _problems(path) -> str:
    import scart

    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return str(info.value)


def test_a_property_file_outside_the_contribution_is_refused(tmp_path) -> None:
    (tmp_path / "secret.txt").write_text("root:x:0:0:secret\n")
    inner = tmp_path / "app"
    inner.mkdir()
    (inner / "escape").symlink_to(tmp_path / "secret.txt")
    for file in ("../secret.txt", "escape", "/etc/passwd", "/dev/zero"):
        text = _problems(_composite_with_file(inner, file))
        assert "outside the contribution folder" in text and "root:x" not in text, text


def test_a_property_file_is_never_echoed(tmp_path) -> None:
    (tmp_path / "n.txt").write_text("root:x:0:0:password-like content\n")
    text = _problems(_composite_with_file(tmp_path, "n.txt"))
    assert "the content of file 'n.txt' is not a valid int (content not shown)" in text and "password" not in text


def test_a_fifo_or_a_huge_file_is_refused_at_once(tmp_path) -> None:
    import os

    os.mkfifo(tmp_path / "pipe")  # reading it would block for ever
    assert "is not a regular file" in _problems(_composite_with_file(tmp_path, "pipe"))
    (tmp_path / "big.txt").write_bytes(b"1" * (2 << 20))
    assert "over the 1048576 bytes bound" in _problems(_composite_with_file(tmp_path, "big.txt"))


def test_a_property_file_inside_the_contribution_still_works(tmp_path) -> None:
    import scart

    (tmp_path / "n.txt").write_text(" 42\n")
    with scart.Runtime.from_file(str(_composite_with_file(tmp_path, "n.txt"))) as rt:
        assert rt._managers["P"].instance().number == 42


def test_nan_from_a_transport_that_carries_it_passes_unless_limits_or_the_port_refuse_it() -> None:
    """``admit(v, nan_ok=True)`` (a ROS or YARP float): NaN and inf pass a port without
    limits, limits still hold, and a port that asked ``finite=True`` refuses them."""
    free, limited, strict = InputPort(float), InputPort(float, ge=-1.0, le=1.0), InputPort(float, finite=True)
    assert math.isnan(free.admit(math.nan, nan_ok=True)) and free.admit(math.inf, nan_ok=True) == math.inf
    assert free.admit(2.5, nan_ok=True) == 2.5 and InputPort(int).admit(7, nan_ok=True) == 7
    with pytest.raises(PortValueError):
        free.admit(math.nan)
    assert limited.admit(0.5, nan_ok=True) == 0.5
    for bad in (2.0, math.nan, math.inf):
        with pytest.raises(PortValueError):
            limited.admit(bad, nan_ok=True)
    assert strict.admit(0.5, nan_ok=True) == 0.5
    with pytest.raises(PortValueError):
        strict.admit(math.nan, nan_ok=True)
    assert InputPort(list[float]).admit([math.nan, 1.0], nan_ok=True)[1] == 1.0
