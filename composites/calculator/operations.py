"""The four arithmetic services of the calculator sample."""

from __future__ import annotations

from typing import Protocol

import scart


@scart.interface
class AddService(Protocol):
    def add(self, n1: float, n2: float) -> float: ...


@scart.interface
class SubtractService(Protocol):
    def subtract(self, n1: float, n2: float) -> float: ...


@scart.interface
class MultiplyService(Protocol):
    def multiply(self, n1: float, n2: float) -> float: ...


@scart.interface
class DivideService(Protocol):
    def divide(self, n1: float, n2: float) -> float: ...


@scart.component(services=[AddService])
class AddServiceImpl:
    def add(self, n1: float, n2: float) -> float:
        return n1 + n2


@scart.component(services=[SubtractService])
class SubtractServiceImpl:
    def subtract(self, n1: float, n2: float) -> float:
        return n1 - n2


@scart.component(services=[MultiplyService])
class MultiplyServiceImpl:
    def multiply(self, n1: float, n2: float) -> float:
        return n1 * n2


@scart.component(services=[DivideService])
class DivideServiceImpl:
    def divide(self, n1: float, n2: float) -> float:
        return n1 / n2
