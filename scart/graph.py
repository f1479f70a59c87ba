"""The parts of the resolved component graph the runtime runs: plain data, no XML and no
threads, and no knowledge of extensions (the whole, with the registry it was checked
against, is :class:`scart.assembled.Assembly`).

Leaf components are :class:`Node` s named by their path ("Outer/Inner"); a reference
resolves to endpoints: a :class:`Target` in this runtime or a :class:`Bound` binding
element.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from scart.api import ComponentType, InterfaceInfo
from scart.model import Binding, Component, Location

__all__ = ["DEFAULT", "Bound", "Endpoint", "Node", "Target"]


@dataclass(frozen=True)
class Target:
    """A reference endpoint in this runtime: leaf component path and service name."""

    node: str
    service: str


@dataclass(frozen=True)
class Bound:
    """A reference endpoint reached through a binding (no local target)."""

    binding: Binding


Endpoint = Target | Bound


@dataclass
class Node:
    """A leaf component: implementation kind and type, values to inject, resolved references."""

    path: str
    model: Component
    kind: str
    ctype: ComponentType
    properties: dict[str, object] = field(default_factory=dict)
    references: dict[str, list[Endpoint]] = field(default_factory=dict)
    service_bindings: dict[str, list[Binding]] = field(default_factory=dict)
    # service -> the paths it is promoted as out of nested composites whose bindings it carries
    service_aliases: dict[str, list[str]] = field(default_factory=dict)
    ref_interfaces: dict[str, InterfaceInfo] = field(default_factory=dict)  # as declared in the composite
    # property -> where its value was given: its <property>, "<command line>" (--set), else the component
    property_locations: dict[str, Location] = field(default_factory=dict)


class _DefaultType:
    def __repr__(self) -> str:
        return "<default>"


#: The value of a property left to its declared default (the manager supplies it).
DEFAULT: Final = _DefaultType()
