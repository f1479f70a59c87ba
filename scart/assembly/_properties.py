"""The property values of the assembly: what each component gives its properties
(``@source`` from the composite, ``--set`` overrides, side-file defaults), checked against
their types, and parsed. A mixin of the assembler, private to :mod:`scart.assembly`."""

from __future__ import annotations

import re

from scart import errors as E
from scart.api import ComponentType, PropSpec
from scart.assembly._state import AssemblerState, Scope
from scart.graph import DEFAULT
from scart.model import Component, Location, PropertyValue
from scart.properties import FileValues, Refused, TypeRef, compatible
from scart.scdl import did_you_mean
from scart.values import is_many, parse_value

_REFUSED = re.compile(r"refused by its check: (.*?)(?: \[type=|$)", re.S)


class Properties(AssemblerState):
    """Resolves and checks property values (ASM50032, ASM50036, ASM50038)."""

    def no_such_property(self, key: str) -> str:
        """Why an override ``Component.prop`` names nothing, with what it could name."""
        path, _, name = key.rpartition(".")
        node = self.nodes.get(path)
        if node is None:
            known = list(self.nodes)
            return (f"no component {path!r}{did_you_mean(path, known)}; components: "
                    f"{', '.join(known[:20]) or 'none'}")
        props = list(node.ctype.properties)
        return (f"component {path!r} has no property {name!r}{did_you_mean(name, props)}; its properties: "
                f"{', '.join(props) or 'none'}")

    def component_raw_props(self, comp: Component, ctype: ComponentType, scope: Scope, path: str,
                            families: dict[str, str | None],
                            declared: dict[str, TypeRef | None] | None = None) -> dict[str, list[str] | None]:
        """The raw values a component gives its properties (``@source`` from ``scope``,
        then ``--set``), their types checked against the componentType's ``families`` (and
        the XML types it ``declared``)."""
        raw: dict[str, list[str] | None] = {}
        for p in comp.properties:
            if p.name in ctype.properties:
                if self.check_property_types(comp, p, scope, families.get(p.name), (declared or {}).get(p.name)):
                    raw[p.name] = self.raw_value(p, scope.props)
                else:
                    raw[p.name] = Refused()
        for name in ctype.properties:
            key = f"{path}.{name}"
            if key in self.overrides:
                raw[name] = [self.overrides[key]]
                self.used_overrides.add(key)
        return raw

    def check_property_types(self, comp: Component, p: PropertyValue, scope: Scope, family: str | None,
                             theirs: TypeRef | None = None) -> bool:
        """A component property's declared type matches its componentType's (``family``,
        and ``theirs`` when the componentType declares an XML type) (ASM50036); a composite
        property it takes whole through ``@source`` matches too (ASM50038). False when one
        does not (reported, naming both types)."""
        reader = self.reader
        own = reader.declared(p)
        if own is not None and not (compatible(reader.family(own), family) and reader.agree(own, theirs)):
            their_type = reader.shown(theirs, p.namespaces) if theirs is not None else family
            self.problem(E.ASM_PROPERTY_TYPE_MISMATCH, f"component {comp.name!r} property {p.name!r}: declared "
                         f"{reader.shown(own, p.namespaces)}, but its componentType's is {their_type}", p.loc)
            return False
        m = re.fullmatch(r"\s*\$([A-Za-z_][\w.-]*)\s*", p.source or "")
        if m is None or m[1] not in scope.types:
            return True
        source = scope.types[m[1]]
        wanted_ref = own if own is not None else theirs
        wanted = reader.family(own) if own is not None else family
        if source is not None and not (compatible(reader.family(source), wanted) and reader.agree(source, wanted_ref)):
            shown = reader.shown(wanted_ref, p.namespaces) if wanted_ref is not None else wanted
            self.problem(E.ASM_SOURCE_TYPE, f"component {comp.name!r} property {p.name!r} ({shown}): @source "
                         f"${m[1]} is {reader.shown(source, p.namespaces)}", p.loc)
            return False
        return True

    def check_against(self, comp: Component, decl: PropertyValue, values: list[str], from_cli: bool) -> list[str] | None:
        """The values a component gives a property of the composite it implements, checked
        at the component (its line) against what the composite declares: its type or
        element, and one value unless ``many`` (ASM50032). Refused when wrong (reported)."""
        own = None if from_cli else next((p for p in comp.properties if p.name == decl.name), None)
        typed = own is not None and self.reader.declared(own) is not None  # checked already, against its own type
        if own is None:  # from --set
            own = decl.model_copy(update={"loc": Location(path="<command line>", line=0), "values": list(values),
                                          "xml": None, "file": None, "source": None})
        if len(values) > 1 and not decl.many:
            self.problem(E.ASM_SINGLE_VALUED, f"component {comp.name!r} property {decl.name!r} "
                         f"({self.reader.shown(self.reader.declared(decl), decl.namespaces)}) is single-valued but has {len(values)} "
                         "values", own.loc)
            return Refused()
        if not typed and not self.reader.check(
                own.model_copy(update={"type": decl.type, "element": decl.element}), values):
            return Refused()
        return values

    def declaration_values(self, decl: PropertyValue) -> list[str] | None:
        """The values a composite or componentType property declaration gives itself: one
        unless it is ``many`` (ASM50032)."""
        values = self.raw_value(decl, {})
        if values is not None and len(values) > 1 and not decl.many and not isinstance(values, Refused):
            self.problem(E.ASM_SINGLE_VALUED, f"property {decl.name!r} ({self.reader.shown(self.reader.declared(decl), decl.namespaces)})"
                         f" is single-valued but has {len(values)} values", decl.loc)
            return Refused()
        return values

    def raw_value(self, p: PropertyValue, ctx: dict[str, list[str] | None]) -> list[str] | None:
        """The raw values of ``p`` (see :class:`scart.properties.PropertyReader`)."""
        return self.reader.raw(p, ctx)

    def property_value(self, comp: Component, name: str, spec: PropSpec, py_type: object, raw: list[str] | None,
                       override: str | None = None) -> object:
        where = next((p.loc for p in comp.properties if p.name == name), comp.loc)
        if override is not None:  # the value came from --set: that is where the problem is
            where = Location(path="<command line>", line=0)
            name = f"{name} (--set {override})"
        if isinstance(raw, Refused):
            return DEFAULT  # its problem is reported
        if raw is None:
            if spec.required:
                self.problem(E.ASM_MUST_SUPPLY, f"component {comp.name!r}: required property {name!r} "
                             "not supplied", comp.loc)
            return DEFAULT
        if len(raw) > 1 and not is_many(py_type):
            type_name = getattr(py_type, "__name__", None) or str(py_type)
            self.problem(E.ASM_SINGLE_VALUED, f"property {name!r} ({type_name}) is single-valued but has "
                         f"{len(raw)} values", where)
            return DEFAULT
        try:
            return parse_value(raw, py_type)
        except ValueError as exc:
            if isinstance(raw, FileValues):  # never echo a file's content (it may be anything)
                type_name = getattr(py_type, "__name__", str(py_type))
                self.problem(E.ASM_PROPERTY_VALUE, f"property {name!r}: the content of file {raw.file!r} is not a "
                             f"valid {type_name} (content not shown)", where)
                return DEFAULT
            msg = str(exc)
            refused = _REFUSED.search(msg)  # a task Property's own check: say so, without pydantic's noise
            if refused is not None:
                msg = f"{' '.join(raw)!r} refused by its check: {refused.group(1).strip()}"
            self.problem(E.ASM_PROPERTY_VALUE, f"property {name!r}: {msg}", where)
            return DEFAULT
