"""The client side of the split calculator: its own copy of the service interface (the
provider's classes are not importable here), and a component that calls it at start."""

from __future__ import annotations

import json
import os
from typing import Protocol

import scart


@scart.interface
class CalculatorService(Protocol):
    def add(self, n1: float, n2: float) -> float: ...
    def subtract(self, n1: float, n2: float) -> float: ...
    def multiply(self, n1: float, n2: float) -> float: ...
    def divide(self, n1: float, n2: float) -> float: ...


class CalculatorClient:
    """Calls each operation once (and divides by zero) at @init; one JSON line per result."""

    calculator: CalculatorService = scart.reference()
    out: str = scart.prop(default="results.jsonl")

    @scart.init
    def run(self) -> None:
        c = self.calculator
        lines = [
            {"op": "add", "result": c.add(3, 2)},
            {"op": "subtract", "result": c.subtract(3, 2)},
            {"op": "multiply", "result": c.multiply(3, 2)},
            {"op": "divide", "result": c.divide(3, 2)},
        ]
        try:
            c.divide(1, 0)
        except scart.ScartError as exc:
            lines.append({"op": "divide by zero", "error": type(exc).__name__,
                          "remote_type": getattr(exc, "remote_type", "")})
        with open(self.out + ".tmp", "w", encoding="utf-8") as fh:
            fh.write("".join(json.dumps(line) + "\n" for line in lines))
        os.replace(self.out + ".tmp", self.out)  # readers never see a partial file
