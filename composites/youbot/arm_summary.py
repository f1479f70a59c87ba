"""The youBot demo's bridge parts: the Locomotor's busy flag as a data-flow port, and the
``ArmSummary`` the ``armSummary`` bridge of ``youbot.composite`` builds from the driver's
status and that flag (no hand-written TaskContext merges them).

``LocomotorState`` is a task whose ``set_busy`` input the Locomotor writes through a
``binding.dataflow`` reference (:class:`BusyFeed`) and whose ``busy`` output the bridge
reads; the monitor reads the bridge's ``summary`` port through a ``binding.dataflow``
reference (:class:`ArmSummaryReader`) and shows it.
"""

from __future__ import annotations

from typing import Protocol

from pydantic import BaseModel

import scart
from dataflow import FlowStatus, InputPort, OutputPort, TaskContext
from youbot_model import YouBotStatus

__all__ = ["ArmSummary", "ArmSummaryReader", "BusyFeed", "LocomotorState", "summarize"]


class ArmSummary(BaseModel):
    """One line on the arm: joint positions [rad], whether a move runs, the status sequence."""

    positions: list[float]
    busy: bool
    sequence: int = 0


class LocomotorState(TaskContext):
    """The Locomotor's busy flag on a port: what is written to ``set_busy`` goes out on ``busy``."""

    set_busy = InputPort(bool, event=True, doc="written by the Locomotor (binding.dataflow)")
    busy = OutputPort(bool, doc="whether the Locomotor is moving the arm")

    def update_hook(self) -> None:
        status, value = self.set_busy.read_newest()
        if status is FlowStatus.NEW_DATA:
            self.busy.write(bool(value))


def summarize(status: YouBotStatus, busy: bool) -> ArmSummary:
    """The bridge's builder: the driver's status and the Locomotor's flag, merged."""
    return ArmSummary(positions=[j.position for j in status.joints], busy=busy, sequence=status.sequence)


@scart.interface
class BusyFeed(Protocol):
    """Writes the Locomotor's flag to ``LocomotorState.set_busy`` (binding.dataflow)."""

    def set_busy(self, value: bool) -> None: ...


@scart.interface
class ArmSummaryReader(Protocol):
    """The newest sample of the bridge's ``summary`` port (binding.dataflow reference)."""

    def summary(self) -> ArmSummary | None: ...
