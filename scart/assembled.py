"""The checked, resolved composite the runtime runs: :class:`Assembly`, plain data.

:func:`scart.assembly.assemble` builds one from a composite and checks it; the runtime
turns it into running components. Its parts (:class:`~scart.graph.Node`,
:class:`~scart.graph.Target`...) live in :mod:`scart.graph`, which the extension SPI
re-exports; this whole, which names the extension registry it was checked against, lives
apart so that the SPI never depends on the registry that loads its providers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from scart.contribution import Contribution
from scart.errors import Problem
from scart.extensions import ExtensionRegistry
from scart.graph import Node, Target
from scart.model import Binding, Composite, Element

__all__ = ["Assembly"]


@dataclass
class Assembly:
    """The checked, resolved graph: leaf ``nodes`` by path, ``order`` (targets first),
    top-level promoted ``services`` and their ``service_bindings``, the extension
    ``elements`` of every composite level, and the ``registry`` it was checked against."""

    composite: Composite
    contribution: Contribution
    registry: ExtensionRegistry
    nodes: dict[str, Node]
    order: list[str]
    services: dict[str, Target]
    service_bindings: dict[str, list[Binding]]
    aliases: dict[str, Target] = field(default_factory=dict)  # "Comp", "Comp/Service" of top-level components
    elements: list[tuple[str, Element]] = field(default_factory=list)  # (prefix, <scart:...>) of all composites
    unused_overrides: set[str] = field(default_factory=set)  # overrides naming no property (non-strict mode)
    warnings: list[Problem] = field(default_factory=list)  # what loads but looks wrong (``scart validate`` shows it)

    def elements_of(self, kind: str) -> list[tuple[str, Element]]:
        """The ``(prefix, element)`` pairs of extension elements whose local name is ``kind``."""
        return [(prefix, el) for prefix, el in self.elements if el.kind == kind]

    def import_object(self, ref: str) -> object:
        """Import ``"pkg.mod:Attr"`` from the contributions, as the checks did."""
        return self.contribution.import_object(ref)
