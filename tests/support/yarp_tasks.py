"""Data-flow tasks the YARP tests stream and call (no tests here), in process and in
``scart deploy support.yarp_tasks:Arm`` subprocesses (``tests/`` on PYTHONPATH)."""

from __future__ import annotations

import threading

from pydantic import BaseModel, Field

from dataflow import FlowStatus, InputPort, OutputPort, TaskContext, operation, register_type


@register_type("YarpTestArmState")
class ArmState(BaseModel):
    """A model that crosses as a bottle of its fields, in order: ``name (j1 j2 ...) stamp ok seq``."""

    name: str = "arm"
    joints: list[float] = Field(default_factory=list)
    stamp: float = 0.0
    ok: bool = True
    seq: int = 0


class Arm(TaskContext):
    """Joint commands in (``cmd``, waking the task), a bounded gain, the arm's state out (``armState``),
    and operations a YARP RPC port answers."""

    cmd = InputPort(list[float], event=True, doc="joint set-points")
    gain = InputPort(float, ge=0.0, le=10.0, doc="a gain in [0, 10]")
    out = OutputPort(ArmState, name="armState", doc="the arm's state")

    def __init__(self, name: str = "arm") -> None:
        super().__init__(name)
        self.lock = threading.Lock()
        self.commands: list[list[float]] = []
        self.gains: list[float] = []
        self.seq = 0
        self.factor = 1.0

    @operation
    def scale(self, factor: float) -> float:
        """Set the factor applied to the joints (finite, > 0); the new factor."""
        if factor <= 0:
            raise ValueError(f"a factor must be > 0, got {factor}")
        self.factor = factor
        return factor

    @operation
    def status(self) -> ArmState:
        """The last state written."""
        return self.out.last_written_value() or ArmState()

    @operation
    def received(self) -> int:
        """How many commands the task read."""
        with self.lock:
            return len(self.commands)

    def update_hook(self) -> None:
        for port, into in ((self.cmd, self.commands), (self.gain, self.gains)):
            for _ in range(10_000):
                flow, value = port.read()
                if flow is not FlowStatus.NEW_DATA:
                    break
                with self.lock:
                    into.append(value)
        self.seq += 1
        joints = [j * self.factor for j in (self.commands[-1] if self.commands else [0.0, 0.0])]
        self.out.write(ArmState(joints=joints, stamp=self.seq * 0.5, seq=self.seq))
