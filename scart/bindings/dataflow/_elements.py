"""What the composite elements that serve something share (``scart:rosservice``,
``scart:yarprpc``): each element read, then checked when it reads well, every problem at
its line with the element's code; and a participant that serves one thing per element at
start and withdraws them, in reverse, at stop."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Generic, Protocol, TypeVar

from dataflow import DataflowError
from scart.spi import Element, Host, Participant, Problem

__all__ = ["Serving", "check_each"]

log = logging.getLogger("scart.dataflow")

T = TypeVar("T")


def check_each(elements: list[tuple[str, Element]], parse: Callable[[str, Element], tuple[T | None, list[str]]],
               check: Callable[[T], list[str]], code: str) -> list[Problem]:
    """The problems of every element: how it reads (``parse``), else what ``check`` finds,
    each at the element's line with ``code``."""
    out: list[Problem] = []
    for prefix, el in elements:
        found, problems = parse(prefix, el)
        if found is not None:
            problems = check(found)
        out += [Problem(code, msg, el.loc.path, el.loc.line) for msg in problems]
    return out


class Served(Protocol):
    """What :meth:`Serving.serve` makes: something served until it is closed."""

    def close(self) -> None: ...


class Serving(Participant, Generic[T]):
    """Serves one thing per item at start — what :meth:`serve` returns, closed at stop —
    and, when one cannot be served, withdraws those served already and raises
    ``DataflowError`` naming it (:meth:`what`). Subclasses say which errors mean "cannot"
    (``failures``)."""

    failures: tuple[type[BaseException], ...] = (DataflowError, ValueError, LookupError, OSError)

    def __init__(self, items: list[T], host: Host) -> None:
        self.items = items
        self.host = host
        self._served: list[Served] = []

    def serve(self, item: T) -> Served:  # pragma: no cover - interface
        """Serve ``item``; what is returned has ``close()``."""
        raise NotImplementedError

    def what(self, item: T) -> str:  # pragma: no cover - interface
        """``item`` as the error that it could not be served says it."""
        raise NotImplementedError

    def start(self) -> None:
        for item in self.items:
            try:
                made = self.serve(item)
            except self.failures as exc:
                self.stop()
                raise DataflowError(f"{self.what(item)}: {exc}") from exc
            self._served.append(made)

    def stop(self) -> None:
        served, self._served = self._served, []
        for made in reversed(served):
            made.close()
