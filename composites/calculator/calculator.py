"""The calculator component: delegates each operation to a referenced service."""

from __future__ import annotations

from typing import Protocol

import scart
from operations import AddService, DivideService, MultiplyService, SubtractService


@scart.interface
class CalculatorService(Protocol):
    def add(self, n1: float, n2: float) -> float: ...
    def subtract(self, n1: float, n2: float) -> float: ...
    def multiply(self, n1: float, n2: float) -> float: ...
    def divide(self, n1: float, n2: float) -> float: ...


@scart.component(services=[CalculatorService])
class CalculatorServiceImpl:
    add_service: AddService = scart.reference()
    subtract_service: SubtractService = scart.reference()
    multiply_service: MultiplyService = scart.reference()
    divide_service: DivideService = scart.reference()
    precision: int = scart.prop(default=12)

    def add(self, n1: float, n2: float) -> float:
        return round(self.add_service.add(n1, n2), self.precision)

    def subtract(self, n1: float, n2: float) -> float:
        return round(self.subtract_service.subtract(n1, n2), self.precision)

    def multiply(self, n1: float, n2: float) -> float:
        return round(self.multiply_service.multiply(n1, n2), self.precision)

    def divide(self, n1: float, n2: float) -> float:
        return round(self.divide_service.divide(n1, n2), self.precision)
