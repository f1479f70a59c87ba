"""One bounded operation, twice: a data-flow task and an SCA Python component declare
``set_gain(x)`` with ``0 <= x <= 1``; each keeps what it received (the tests ask whether a
refused value ever reached it)."""

from __future__ import annotations

from typing import Annotated, Protocol

from pydantic import Field

import scart
from dataflow import Property, TaskContext, operation

Gain = Annotated[float, Field(ge=0.0, le=1.0)]


class BoundedTask(TaskContext):
    """The task: ``received`` lists every value its operation ran with."""

    received = Property(str, "", doc="the values set_gain ran with, comma-separated")

    @operation
    def set_gain(self, x: Gain) -> float:
        self.received = ",".join(filter(None, [self.received, repr(x)]))
        return x


@scart.interface
class Gaining(Protocol):
    """The SCA service (the same operation), and what it received."""

    def set_gain(self, x: Gain) -> float: ...
    def received(self) -> list[float]: ...


@scart.component(services=[Gaining])
class BoundedComponent:
    """The SCA Python component."""

    @scart.init
    def open(self) -> None:
        self._received: list[float] = []

    def set_gain(self, x: Gain) -> float:
        self._received.append(x)
        return x

    def received(self) -> list[float]:
        return list(self._received)


@scart.interface
class Calling(Protocol):
    """A caller's view of the operation (no bounds: it sends whatever it is given)."""

    def set_gain(self, x: float) -> float: ...


@scart.interface
class Forwarding(Protocol):
    """What a test asks the caller to do."""

    def forward(self, x: object) -> float: ...


@scart.component(services=[Forwarding])
class Caller:
    """Calls ``set_gain`` through its ``gain`` reference (a composite binds it with binding.grpc)."""

    gain: Calling = scart.reference()

    def forward(self, x: object) -> float:
        return self.gain.set_gain(x)  # type: ignore[arg-type] - whatever it is given: the far side checks
