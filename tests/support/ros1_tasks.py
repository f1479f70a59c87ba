"""Data-flow tasks the ROS 1 transport tests stream (no tests here), in process and in
``scart deploy support.ros1_tasks:Gauge`` subprocesses (``tests/`` on PYTHONPATH)."""

from __future__ import annotations

import threading

from pydantic import BaseModel

from dataflow import FlowStatus, InputPort, OutputPort, Property, TaskContext, operation, register_type


@register_type("RosTestPoint")
class Point(BaseModel):
    """The fields of a geometry_msgs/Point, by name."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@register_type("RosTestHeat")
class Heat(BaseModel):
    """The fields of a sensor_msgs/Temperature but its header (stamped by the stream)."""

    temperature: float = 0.0
    variance: float = 0.0


class Gauge(TaskContext):
    """A bounded input (``level`` in [0, 1]), an int input, a counting output and a point
    output, and operations a ROS service can answer."""

    level = InputPort(float, ge=0.0, le=1.0, doc="a level in [0, 1]")
    number = InputPort(int, doc="any int64")
    pose = InputPort(Point, doc="any point, NaN and inf included (ROS's floats)")
    strict = InputPort(float, finite=True, doc="a finite number: asks for it")
    count = OutputPort(int, doc="the cycle number")
    point = OutputPort(Point, doc="a point moving along x")
    heat = OutputPort(Heat, doc="the cycle number as a temperature")
    ceiling = Property(float, 1.0, doc="a bounded number (a ROS parameter)", ge=0.0, le=10.0)
    note = Property(str, "", doc="free text (a ROS parameter)")

    def __init__(self, name: str = "gauge") -> None:
        super().__init__(name)
        self.cycles = 0
        self.lock = threading.Lock()
        self.levels: list[float] = []
        self.numbers: list[int] = []
        self.loggers: list[tuple[str, str]] = []

    @operation
    def cycle_count(self) -> int:
        """The cycles run so far."""
        return self.cycles

    @operation
    def seen(self) -> list[float]:
        """The levels read so far."""
        with self.lock:
            return list(self.levels)

    @operation
    def numbers_seen(self) -> list[int]:
        """The numbers read so far."""
        with self.lock:
            return list(self.numbers)

    @operation
    def set_logger_level(self, logger: str, level: str) -> None:
        """Note a logger's level (what roscpp/SetLoggerLevel asks)."""
        if level not in ("debug", "info", "warn", "error", "fatal"):
            raise ValueError(f"no level {level!r}")
        with self.lock:
            self.loggers.append((logger, level))

    def update_hook(self) -> None:
        self.drain()
        self.cycles += 1
        self.count.write(self.cycles)
        self.point.write(Point(x=self.cycles * 0.5, y=1.0, z=-2.0))
        self.heat.write(Heat(temperature=float(self.cycles)))

    def drain(self) -> None:
        """Read what waits on the inputs (the hook does; a test without an activity may)."""
        for port, into in ((self.level, self.levels), (self.number, self.numbers)):
            for _ in range(10_000):
                flow, value = port.read()
                if flow is not FlowStatus.NEW_DATA:
                    break
                with self.lock:
                    into.append(value)
