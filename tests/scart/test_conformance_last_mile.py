"""SCA Assembly 1.1's last rules, each both ways with the composite that shows it: property
types of the SCA namespace (its schemas ship with scart), binding.sca @uri on a
componentType reference, @file documents of global elements read through an XPath
@source, complex type agreement, callbacks declared only on the component, binding names
on nested composites, and references promoted together. Composites written from the
spec's text."""

from __future__ import annotations

from pathlib import Path

import pytest

import scart
from support.sca import SCA, composite, line_of, write

XSD = """<?xml version="1.0"?>
<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" xmlns:geo="urn:geo" targetNamespace="urn:geo"
           elementFormDefault="qualified">
  <xs:complexType name="Point">
    <xs:sequence><xs:element name="x" type="xs:double"/><xs:element name="y" type="xs:double"/></xs:sequence>
  </xs:complexType>
  <xs:complexType name="Point3">
    <xs:complexContent><xs:extension base="geo:Point">
      <xs:sequence><xs:element name="z" type="xs:double"/></xs:sequence>
    </xs:extension></xs:complexContent>
  </xs:complexType>
  <xs:complexType name="Size">
    <xs:sequence><xs:element name="w" type="xs:double"/><xs:element name="h" type="xs:double"/></xs:sequence>
  </xs:complexType>
  <xs:element name="point" type="geo:Point"/>
</xs:schema>
"""

LM = '''
from __future__ import annotations

from typing import Protocol

import scart


class Props:
    callback: dict = scart.prop(default={})
    text: str = scart.prop(default="")
    number: float = scart.prop(default=0.0)

    def values(self) -> dict:
        return {"callback": self.callback, "text": self.text, "number": self.number}


class Echo(Protocol):
    def echo(self, text: str) -> str: ...


class Back(Protocol):
    def back(self, text: str) -> None: ...


@scart.interface(callback=Back)
class EchoBack(Protocol):
    def echo(self, text: str) -> str: ...


@scart.component(services=[Echo])
class EchoImpl:
    name: str = scart.prop(default="echo")

    def echo(self, text: str) -> str:
        return f"{self.name}: {text}"


@scart.component(services=[EchoBack])
class EchoBackImpl:
    def echo(self, text: str) -> str:
        return text


class User:
    target: Echo = scart.reference()

    def call(self, text: str) -> str:
        return self.target.echo(text)

    def back(self, text: str) -> None: ...


class BackUser:
    target: EchoBack = scart.reference(required=False)

    def back(self, text: str) -> None: ...
'''

HEAD = f' xmlns:geo="urn:geo" xmlns:xs="http://www.w3.org/2001/XMLSchema" xmlns:sca="{SCA}"'


def files(tmp_path: Path, main: str, **others: str) -> Path:
    return write(tmp_path, {"main.composite": main, "lm.py": LM, "geo.xsd": XSD, **others}, with_components=False)


def refused(path: Path) -> scart.ScdlError:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return info.value


# ---- property types of the SCA namespace ---------------------------------------------------

def sca_typed(declaration: str) -> str:
    return composite(f"""
        <component name="P"><scart:implementation.python class="lm:Props"/>
          {declaration}
        </component>""", extra=HEAD)


@pytest.mark.parametrize("declaration", [
    '<property name="callback" type="sca:Callback"><value requires="sca:confidentiality" policySets="sca:x">'
    '<binding.sca/></value></property>',
    '<property name="callback" element="sca:callback"><value requires="sca:confidentiality"><binding.sca/>'
    '</value></property>',
    '<property name="callback" element="sca:callback"><sca:callback><binding.sca name="b"/></sca:callback>'
    '</property>',
    '<property name="text" type="sca:Multiplicity">1..n</property>',
])
def test_sca_namespace_types_and_elements_load(tmp_path: Path, declaration: str) -> None:
    with scart.Runtime.from_file(str(files(tmp_path, sca_typed(declaration)))) as rt:
        values = rt.service("P").values()
    assert "binding.sca" in values["callback"] or values["text"] == "1..n", values


@pytest.mark.parametrize("declaration, why", [
    ('<property name="callback" type="sca:Callback"><value><wire/></value></property>', "wire"),
    ('<property name="callback" element="sca:callback"><value><binding.sca name="not a name"/></value></property>', "name"),
    ('<property name="callback" element="sca:callback"><value nonsense="1"/></property>', "nonsense"),
])
def test_sca_namespace_values_are_checked_against_the_shipped_schemas(tmp_path: Path, declaration: str,
                                                                      why: str) -> None:
    text = sca_typed(declaration)
    err = refused(files(tmp_path, text))
    assert err.codes[0] in ("ASM50027", "ASM50029") and why in str(err), str(err)
    assert err.errors[0].line == line_of(text, 'name="callback"')


# ---- binding.sca @uri on a componentType reference ---------------------------------------

INNER = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="Inner">
  <component name="U"><scart:implementation.python class="lm:User"/></component>
  <service name="User" promote="U"/>
  <reference name="target" promote="U/target" multiplicity="1..1">
    <binding.sca uri="{{uri}}"/>
  </reference>
</composite>
"""


def outer(extra: str = "") -> str:
    return composite(f"""
        <component name="Outer"><implementation.composite name="t:Inner"/>{extra}</component>
        <component name="Right"><scart:implementation.python class="lm:EchoImpl"/>
          <property name="name">right</property></component>
        <component name="Left"><scart:implementation.python class="lm:EchoImpl"/>
          <property name="name">left</property></component>""")


def test_binding_sca_uri_on_a_composite_reference_wires_the_component(tmp_path: Path) -> None:
    path = files(tmp_path, outer(), **{"inner.composite": INNER.format(uri="Right")})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("Outer/User").call("hi") == "right: hi"
    # the component's own target replaces the componentType's default
    path = files(tmp_path, outer('<reference name="target" target="Left"/>'),
                 **{"inner.composite": INNER.format(uri="Right")})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("Outer/User").call("hi") == "left: hi"


def test_binding_sca_uri_on_a_composite_reference_names_a_service(tmp_path: Path) -> None:
    err = refused(files(tmp_path, outer(), **{"inner.composite": INNER.format(uri="Nowhere")}))
    assert err.codes == ["ASM60047"] and "'Nowhere': no component" in str(err)
    assert err.errors[0].path.endswith("inner.composite") and err.errors[0].line == 6  # the binding.sca, not ASM50040


# ---- @file: an sca:values document of global elements, read through XPath ------------------

NESTED = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" xmlns:geo="urn:geo" targetNamespace="urn:test" name="Pts">
  <property name="points" type="geo:Point" many="true"/>
  <component name="P"><scart:implementation.python class="lm:Props"/>
    <property name="number" source="$points[2]/geo:y"/>
    <property name="text" source="$points[1]/geo:x/text()"/>
  </component>
  <service name="Props" promote="P"/>
</composite>
"""

POINTS = f"""<values xmlns="{SCA}" xmlns:geo="urn:geo">
  <geo:point><geo:x>1</geo:x><geo:y>2</geo:y></geo:point>
  <geo:point><geo:x>3</geo:x><geo:y>{{y}}</geo:y></geo:point>
</values>"""


def points(tmp_path: Path, y: str) -> Path:
    main = composite("""
        <component name="C"><implementation.composite name="t:Pts"/>
          <property name="points" file="points.xml"/>
        </component>""", extra=HEAD)
    return files(tmp_path, main, **{"nested.composite": NESTED, "points.xml": POINTS.format(y=y)})


def test_a_file_of_global_elements_gives_a_many_valued_complex_property(tmp_path: Path) -> None:
    with scart.Runtime.from_file(str(points(tmp_path, "4.5"))) as rt:
        assert rt.service("C/Props").values() == {"callback": {}, "text": "1", "number": 4.5}


def test_global_elements_of_a_file_are_checked_against_the_property_type(tmp_path: Path) -> None:
    err = refused(points(tmp_path, "north"))
    assert err.codes == ["ASM50027"] and "file 'points.xml'" in str(err) and "north" not in str(err)


# ---- complex type agreement --------------------------------------------------------------

TYPED = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" xmlns:geo="urn:geo" targetNamespace="urn:test" name="Typed">
  <property name="where" type="geo:Point"/>
  <component name="P"><scart:implementation.python class="lm:Props"/>
    <property name="number" source="$where/geo:x"/>
  </component>
  <service name="Props" promote="P"/>
</composite>
"""


def typed(tmp_path: Path, component_property: str, composite_property: str = "") -> tuple[Path, str]:
    main = composite(f"""
        {composite_property}
        <component name="C"><implementation.composite name="t:Typed"/>
          {component_property}
        </component>""", extra=HEAD)
    return files(tmp_path, main, **{"typed.composite": TYPED}), main


VALUE_XY = "<value><geo:x>1</geo:x><geo:y>2</geo:y></value>"
VALUE_XYZ = "<value><geo:x>1</geo:x><geo:y>2</geo:y><geo:z>3</geo:z></value>"


@pytest.mark.parametrize("given", [
    f'<property name="where" type="geo:Point">{VALUE_XY}</property>',
    f'<property name="where" type="geo:Point3">{VALUE_XYZ}</property>',  # derived from geo:Point
    '<property name="where" element="geo:point"><geo:point><geo:x>1</geo:x><geo:y>2</geo:y></geo:point></property>',
])
def test_a_component_property_of_the_same_or_a_derived_complex_type_loads(tmp_path: Path, given: str) -> None:
    with scart.Runtime.from_file(str(typed(tmp_path, given)[0])) as rt:
        assert rt.service("C/Props").values()["number"] == 1.0


def test_asm50036_a_component_property_of_another_complex_type_is_refused(tmp_path: Path) -> None:
    path, text = typed(tmp_path, '<property name="where" type="geo:Size"><value><geo:w>1</geo:w><geo:h>2</geo:h>'
                                 '</value></property>')
    err = refused(path)
    assert err.codes == ["ASM50036"], str(err)
    assert "property 'where': declared geo:Size, but its componentType's is geo:Point" in str(err)
    assert err.errors[0].line == line_of(text, 'name="where"')


def test_asm50038_a_source_of_another_complex_type_is_refused(tmp_path: Path) -> None:
    size = '<property name="size" type="geo:Size"><value><geo:w>1</geo:w><geo:h>2</geo:h></value></property>'
    path, text = typed(tmp_path, '<property name="where" type="geo:Point" source="$size"/>', size)
    err = refused(path)
    assert err.codes == ["ASM50038"] and "property 'where' (geo:Point): @source $size is geo:Size" in str(err)
    assert err.errors[0].line == line_of(text, 'source="$size"')
    point = f'<property name="home" type="geo:Point">{VALUE_XY}</property>'
    with scart.Runtime.from_file(str(typed(tmp_path, '<property name="where" source="$home"/>', point)[0])) as rt:
        assert rt.service("C/Props").values()["number"] == 1.0


# ---- callbacks declared only on the component ----------------------------------------------

BACK_INNER = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="BackInner">
  <component name="U"><scart:implementation.python class="lm:BackUser"/></component>
  <reference name="target" promote="U/target" multiplicity="0..1"/>
</composite>
"""


def back(iface: str, callback: str, impl: str = "EchoBackImpl") -> str:
    return composite(f"""
        <component name="Outer"><implementation.composite name="t:BackInner"/>
          <reference name="target" target="E">
            <scart:interface.python interface="lm:{iface}"{callback}/>
          </reference>
        </component>
        <component name="E"><scart:implementation.python class="lm:{impl}"/></component>""")


def test_a_component_reference_may_declare_the_callback_its_component_type_has(tmp_path: Path) -> None:
    path = files(tmp_path, back("EchoBack", ""), **{"inner.composite": BACK_INNER})
    with scart.Runtime.from_file(str(path)):
        pass


def test_asm50011_a_callback_declared_only_on_the_component_is_refused(tmp_path: Path) -> None:
    text = back("Echo", ' callbackInterface="lm:Back"', impl="EchoImpl")
    inner = BACK_INNER.replace("lm:BackUser", "lm:User").replace('multiplicity="0..1"', 'multiplicity="1..1"')
    err = refused(files(tmp_path, text, **{"inner.composite": inner}))
    assert err.codes == ["ASM50011"], str(err)
    assert "declares callback interface Back, but its componentType's reference (Echo) has no callback" in str(err)
    assert err.errors[0].line == line_of(text, "interface.python")


# ---- a named binding on a service of a nested composite (ASM60050) ----------------------------

NAMED = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="Named">
  <component name="E"><scart:implementation.python class="lm:EchoImpl"/></component>
  <service name="Echo" promote="E"/>
</composite>
"""


@pytest.mark.parametrize("binding, refused_with", [("fast", None), ("slow", "ASM60050")])
def test_a_target_names_a_binding_of_a_nested_composite_s_service(tmp_path: Path, binding: str,
                                                                   refused_with: str | None) -> None:
    text = composite(f"""
        <component name="N"><implementation.composite name="t:Named"/>
          <service name="Echo"><binding.sca name="fast"/></service>
        </component>
        <component name="U"><scart:implementation.python class="lm:User"/>
          <reference name="target" target="N/Echo/{binding}"/>
        </component>""")
    path = files(tmp_path, text, **{"named.composite": NAMED})
    if refused_with is None:
        with scart.Runtime.from_file(str(path)) as rt:
            assert rt.service("U").call("x") == "echo: x"
        return
    err = refused(path)
    assert err.codes == [refused_with] and "has no binding named 'slow'" in str(err) and "fast" in str(err)


# ---- references promoted together have one interface (ASM60008) ------------------------------

def test_asm60008_references_promoted_together_have_the_same_interface(tmp_path: Path) -> None:
    inner = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="Two">
  <component name="A"><scart:implementation.python class="lm:User"/></component>
  <component name="B"><scart:implementation.python class="lm:BackUser"/></component>
  <reference name="both" promote="A/target B/target" multiplicity="1..1"/>
</composite>
"""
    text = composite("""
        <component name="T"><implementation.composite name="t:Two"/><reference name="both" target="E"/></component>
        <component name="E"><scart:implementation.python class="lm:EchoImpl"/></component>""")
    err = refused(files(tmp_path, text, **{"two.composite": inner}))
    assert "ASM60008" in err.codes and "declares no interface of its own" in str(err)
    same = inner.replace("lm:BackUser", "lm:User")
    with scart.Runtime.from_file(str(files(tmp_path, text, **{"two.composite": same}))):
        pass
