"""The SCA assembly model: plain validated data, no XML and no threads.

The loader (:mod:`scart.scdl`) turns XML into these objects; the assembler
(:mod:`scart.assembly`) checks and resolves them; the runtime runs them. Every element
remembers the file and line it came from (``loc``), so every problem can be reported
as ``path:line: message``.

Extension kinds (``implementation.*``, ``binding.*``, and extra composite-level
elements such as ``scart:connect``) are kept generically: ``kind`` is the element's
local name, ``namespace`` its namespace, ``attributes`` its attributes and
``children`` its child elements, so new kinds need no change to this module.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

SCA11_NS = "http://docs.oasis-open.org/ns/opencsa/sca/200912"
SCA10_NS = "http://www.osoa.org/xmlns/sca/1.0"
SCART_NS = "urn:scart:1.0"


class Location(BaseModel):
    """Where an element was read: file path (as given) and 1-based line."""

    model_config = ConfigDict(frozen=True)
    path: str = "<memory>"
    line: int = 0

    def __str__(self) -> str:
        return f"{self.path}:{self.line}"


class _Node(BaseModel):
    model_config = ConfigDict(extra="forbid")
    loc: Location = Field(default_factory=Location)


class Element(_Node):
    """A generic (extension) element: its kind (local name), namespace, attributes, children."""

    kind: str
    namespace: str = ""
    attributes: dict[str, str] = Field(default_factory=dict)
    text: str = ""
    children: list[Element] = Field(default_factory=list)


class Interface(_Node):
    """``interface.python`` (``target`` = "pkg.mod:Class") or ``interface.wsdl``
    (``target`` = "ns#wsdl.interface(PortType)"); ``callback`` likewise, or None."""

    kind: str
    target: str
    callback: str | None = None
    remotable: bool | None = None  # interface.python @remotable (None: as the Python interface says)
    invalid: bool = False  # failed the schema (already reported): not imported


class Binding(Element):
    """A binding element (``binding.sca``, ``scart:binding.grpc``...); ``name`` optional."""

    name: str | None = None


class Implementation(Element):
    """``implementation.python`` (``attributes['class']``), ``implementation.composite``
    (``attributes['name']`` a QName, ``composite`` filled by the loader), or an extension."""

    composite: Composite | None = None
    invalid: bool = False  # failed the schema (already reported): not imported


class PropertyValue(_Node):
    """A property as written on a component, a composite or a componentType.

    ``values`` holds raw text values (``@value``, each ``<value>``, or the text content);
    ``xml`` the same values as XML (each ``<value>`` or global element, serialized) when
    any is complex, else None; ``file`` a path relative to the composite; ``source`` an
    XPath over the composite's properties (``$name``, ``$name/ns:child``...), evaluated
    with ``namespaces``. ``type``/``element`` are Clark QNames ("{ns}local").
    """

    name: str
    values: list[str] | None = None
    xml: list[str] | None = None
    file: str | None = None
    source: str | None = None
    namespaces: dict[str, str] = Field(default_factory=dict)
    type: str | None = None
    element: str | None = None
    many: bool = False
    must_supply: bool = False


class ComponentService(_Node):
    """A ``<service>`` of a component: optional interface and bindings."""

    name: str
    interface: Interface | None = None
    bindings: list[Binding] = Field(default_factory=list)
    callback_bindings: list[Binding] = Field(default_factory=list)


class ComponentReference(_Node):
    """A ``<reference>`` of a component: ``targets`` ("Comp" or "Comp/Service"), bindings."""

    name: str
    targets: list[str] = Field(default_factory=list)
    multiplicity: str | None = None
    autowire: bool | None = None
    non_overridable: bool = False
    interface: Interface | None = None
    bindings: list[Binding] = Field(default_factory=list)
    callback_bindings: list[Binding] = Field(default_factory=list)


class ComponentTypeFile(_Node):
    """A componentType side file (``Class.componentType`` next to an implementation's
    module): what it declares of the implementation's services, references and properties."""

    services: list[ComponentService] = Field(default_factory=list)
    references: list[ComponentReference] = Field(default_factory=list)
    properties: list[PropertyValue] = Field(default_factory=list)


class Component(_Node):
    """A ``<component>``: its implementation, and the services/references/properties it configures."""

    name: str
    implementation: Implementation | None = None
    services: list[ComponentService] = Field(default_factory=list)
    references: list[ComponentReference] = Field(default_factory=list)
    properties: list[PropertyValue] = Field(default_factory=list)
    autowire: bool | None = None
    misread: bool = False  # an element or attribute inside it was not understood (reported)


class CompositeService(_Node):
    """A composite ``<service promote="Comp/Service">``."""

    name: str
    promote: str
    interface: Interface | None = None
    bindings: list[Binding] = Field(default_factory=list)


class CompositeReference(_Node):
    """A composite ``<reference promote="Comp/ref Comp2/ref">`` with optional targets/bindings."""

    name: str
    promote: list[str] = Field(default_factory=list)
    targets: list[str] = Field(default_factory=list)
    multiplicity: str | None = None
    interface: Interface | None = None
    bindings: list[Binding] = Field(default_factory=list)


class Wire(_Node):
    """A ``<wire source="Comp/ref" target="Comp2/Service" replace="...">``."""

    source: str
    target: str
    replace: bool = False


class Include(_Node):
    """An ``<include name="QName">``: the named composite's content is merged."""

    name: str


class Composite(_Node):
    """A ``<composite>``: the unit of assembly. ``qname`` is "{targetNamespace}name"."""

    name: str
    target_namespace: str = ""
    autowire: bool = False
    local: bool = False
    components: list[Component] = Field(default_factory=list)
    services: list[CompositeService] = Field(default_factory=list)
    references: list[CompositeReference] = Field(default_factory=list)
    properties: list[PropertyValue] = Field(default_factory=list)
    wires: list[Wire] = Field(default_factory=list)
    includes: list[Include] = Field(default_factory=list)
    extensions: list[Element] = Field(default_factory=list)

    @property
    def qname(self) -> str:
        """Clark notation ``{targetNamespace}name``."""
        return f"{{{self.target_namespace}}}{self.name}"

    def component(self, name: str) -> Component | None:
        """The component called ``name``, or None (first one when duplicated)."""
        for comp in self.components:
            if comp.name == name:
                return comp
        return None


Implementation.model_rebuild()
Element.model_rebuild()
