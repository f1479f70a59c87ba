"""Your first composite's Python side: two data-flow tasks and one SCA component."""

from __future__ import annotations

from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, OutputPort, TaskContext, operation


class Ticker(TaskContext):
    """A periodic task (its period is in the composite): counts its cycles on ``ticks``."""

    ticks = OutputPort(int)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.count = 0

    def update_hook(self) -> None:
        self.count += 1
        self.ticks.write(self.count)


class Summer(TaskContext):
    """Adds up what arrives on ``inp`` (woken by each sample); ``total()`` reads the sum."""

    inp = InputPort(int, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._total = 0

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, value = self.inp.read()
            if flow is not FlowStatus.NEW_DATA:
                break
            self._total += value

    @operation
    def total(self) -> int:
        """The sum so far."""
        return self._total


class Totals(Protocol):
    """What the Reporter needs of the summer task (its operations form an SCA service)."""

    def total(self) -> int: ...


@scart.component
class Reporter:
    """An SCA component: a property, a reference to the task, an @init."""

    label: str = scart.prop(default="total")
    summer: Totals = scart.reference()

    @scart.init
    def start(self) -> None:
        print(f"Reporter ready: {self.report()}", flush=True)

    def report(self) -> str:
        """``label: sum``."""
        return f"{self.label}: {self.summer.total()}"
