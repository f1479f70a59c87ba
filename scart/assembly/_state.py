"""The state every part of the assembler shares: the contribution, the registry, the
problems found, the leaf nodes built — and the two shapes a composite's children take
while assembling (:class:`Scope`, :class:`Failed`). Private to :mod:`scart.assembly`."""

from __future__ import annotations

from dataclasses import dataclass, field

from scart.api import ComponentType, InterfaceInfo
from scart.checks import Checks
from scart.component_types import SideFile
from scart.contribution import Contribution
from scart.errors import Problem
from scart.extensions import ExtensionRegistry
from scart.graph import Node
from scart.model import Component, Composite, Element, Location
from scart.properties import PropertyReader, TypeRef
from scart.spi import CheckContext


@dataclass
class Failed:
    """Placeholder of a component whose implementation could not be read (already reported):
    names resolve to it silently, so one broken component causes no cascade of errors."""

    model: Component
    ctype: None = None


@dataclass
class Scope:
    """One composite instance while assembling: its children (leaf Node or nested Scope)."""

    composite: Composite
    prefix: str
    props: dict[str, list[str] | None]
    types: dict[str, TypeRef | None] = field(default_factory=dict)  # of the composite's own properties
    children: dict[str, Node | Scope | Failed] = field(default_factory=dict)
    component: Component | None = None  # the component this composite implements
    ctype: ComponentType | None = None


class AssemblerState(Checks):
    """What the assembler's parts read and add to; each part is a mixin over it."""

    def __init__(self, contribution: Contribution, registry: ExtensionRegistry, context: CheckContext,
                 overrides: dict[str, str], strict_overrides: bool = True) -> None:
        self.contribution = contribution
        self.registry = registry
        self.context = context
        self.overrides = overrides
        self.strict_overrides = strict_overrides
        self.used_overrides: set[str] = set()
        self.problems: list[Problem] = []
        self.nodes: dict[str, Node] = {}
        self.extensions: list[tuple[str, Element]] = []
        self.reader = PropertyReader(contribution, self.problem)
        self.side_files: dict[str, SideFile] = {}  # by component path
        self._promoted_interfaces: dict[int, tuple[str, InterfaceInfo]] = {}  # composite reference -> first promoted
        #: (component path, service) -> the interface its <service> declares: what wires see of it
        self.declared_services: dict[tuple[str, str], InterfaceInfo] = {}

    def problem(self, code: str, message: str, loc: Location) -> None:
        self.problems.append(Problem(code, message, loc.path, loc.line))
