"""Composite-level extension elements (for example ``<scart:connect from=... to=.../>``).

An extension kind is registered under the local name of its ``urn:scart:1.0`` element
with :func:`register_composite_extension`. The loader then accepts the element as a
child of any ``<composite>`` (read generically into ``Composite.extensions``; declare it
in ``scart/schema/scart-1.0.xsd`` too), the assembler calls ``check`` with every such
element of the assembly (problems are reported with the others, before anything
starts), and the runtime calls ``participant`` once at start: the participant is
started after every component's ``@init`` and before service bindings, and stopped
(reverse order) after service bindings stop and before any ``@destroy``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from scart.errors import Problem
from scart.model import Element
from scart.scdl import register_composite_element

if TYPE_CHECKING:
    from scart.assembly import Assembly
    from scart.runtime import Runtime


class Participant(Protocol):
    """Something an extension runs with the composite."""

    def start(self) -> None:
        """Start (components are initialised already)."""

    def stop(self) -> None:
        """Stop; idempotent."""


class CompositeExtension(Protocol):
    """A registered extension kind. ``elements`` are ``(prefix, element)`` pairs, where
    ``prefix`` is the path of the enclosing component ("" at top level, else "Outer/")."""

    def check(self, elements: list[tuple[str, Element]], assembly: Assembly) -> list[Problem]:
        """Static problems (empty list when fine)."""

    def participant(self, elements: list[tuple[str, Element]], runtime: Runtime) -> Participant:
        """What runs with the composite."""


COMPOSITE_EXTENSIONS: dict[str, CompositeExtension] = {}


def register_composite_extension(local_name: str, extension: CompositeExtension) -> None:
    """Register (or replace) the handler of ``<scart:LOCAL_NAME>`` composite children."""
    COMPOSITE_EXTENSIONS[local_name] = extension
    register_composite_element(local_name)
