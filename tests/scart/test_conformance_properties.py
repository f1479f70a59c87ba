"""SCA Assembly 1.1 conformance, properties and componentType side files: complex values,
XML Schema types of the contribution, @element, @source XPath, @file documents, and type
agreement — each statement both ways. Composites written from the spec's text."""

from __future__ import annotations

from pathlib import Path

import pytest

import scart
from support.sca import OSOA, SCA, composite, line_of, write

XSD = """<?xml version="1.0"?>
<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" xmlns:geo="urn:geo" targetNamespace="urn:geo"
           elementFormDefault="qualified">
  <xs:complexType name="Point">
    <xs:sequence><xs:element name="x" type="xs:double"/><xs:element name="y" type="xs:double"/></xs:sequence>
  </xs:complexType>
  <xs:element name="pose">
    <xs:complexType>
      <xs:sequence><xs:element name="x" type="xs:double"/><xs:element name="y" type="xs:double"/>
        <xs:element name="label" type="xs:string" minOccurs="0"/></xs:sequence>
    </xs:complexType>
  </xs:element>
  <xs:simpleType name="Speed">
    <xs:restriction base="xs:double"><xs:minInclusive value="0"/><xs:maxInclusive value="2"/></xs:restriction>
  </xs:simpleType>
</xs:schema>
"""

PROPS = '''
from __future__ import annotations

from pydantic import BaseModel

import scart


class Point(BaseModel):
    x: float
    y: float


class Pose(BaseModel):
    x: float
    y: float
    label: str = ""


class Robot:
    home: Point | None = scart.prop(default=None)
    waypoints: list[Point] = scart.prop(default=[])
    pose: Pose | None = scart.prop(default=None)
    speed: float = scart.prop(default=0.5)
    name: str = scart.prop(default="robot")
    count: int = scart.prop(default=1)
    raw: str = scart.prop(default="")

    def values(self) -> dict:
        return {"home": self.home, "waypoints": self.waypoints, "pose": self.pose, "speed": self.speed,
                "name": self.name, "count": self.count, "raw": self.raw}
'''

HEAD = 'xmlns:geo="urn:geo" xmlns:xs="http://www.w3.org/2001/XMLSchema"'


def robot(props: str, composite_props: str = "") -> str:
    return composite(f"""
        {composite_props}
        <component name="R"><scart:implementation.python class="props:Robot"/>
          {props}
        </component>
    """, extra=f" {HEAD}")


def load(tmp_path: Path, text: str, **files: str) -> dict:
    path = write(tmp_path, {"main.composite": text, "props.py": PROPS, "geo.xsd": XSD, **files})
    with scart.Runtime.from_file(str(path)) as rt:
        return rt.service("R").values()


def refused(tmp_path: Path, text: str, **files: str) -> scart.ScdlError:
    path = write(tmp_path, {"main.composite": text, "props.py": PROPS, "geo.xsd": XSD, **files})
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return info.value


# ---- complex values and XML Schema types ----------------------------------------------

def test_a_complex_value_of_a_contribution_type_becomes_the_python_model(tmp_path: Path) -> None:
    values = load(tmp_path, robot("""
        <property name="home" type="geo:Point"><value><geo:x>1.5</geo:x><geo:y>-2</geo:y></value></property>
        <property name="waypoints" type="geo:Point" many="true">
          <value><geo:x>0</geo:x><geo:y>0</geo:y></value>
          <value><geo:x>3</geo:x><geo:y>4</geo:y></value>
        </property>"""))
    assert values["home"].x == 1.5 and values["home"].y == -2.0
    assert [(p.x, p.y) for p in values["waypoints"]] == [(0.0, 0.0), (3.0, 4.0)]


def test_asm50027_a_value_must_be_valid_for_its_type(tmp_path: Path) -> None:
    text = robot("""<property name="home" type="geo:Point"><value><geo:x>east</geo:x><geo:y>0</geo:y></value></property>
    """)
    err = refused(tmp_path, text)
    assert err.codes == ["ASM50027"] and "'east' is not a valid value of the atomic type 'xs:double'" in str(err)
    assert err.errors[0].line == line_of(text, 'name="home"')
    speed = refused(tmp_path, robot('<property name="speed" type="geo:Speed">3.5</property>'))
    assert speed.codes == ["ASM50027"] and "maximum value allowed" in str(speed)
    ok = load(tmp_path, robot('<property name="speed" type="geo:Speed">1.25</property>'))
    assert ok["speed"] == 1.25


def test_a_complex_type_takes_value_elements_not_text(tmp_path: Path) -> None:
    err = refused(tmp_path, robot('<property name="home" type="geo:Point" value="1 2"/>'))
    assert err.codes == ["ASM50027"] and "takes <value> elements" in str(err)


def test_asm40007_a_type_names_an_xml_schema_type(tmp_path: Path) -> None:
    err = refused(tmp_path, robot('<property name="speed" type="geo:Velocity">1</property>'))
    assert err.codes == ["ASM40007"] and "names no XML Schema type" in str(err)
    ok = load(tmp_path, robot('<property name="count" type="xs:int">7</property>'))
    assert ok["count"] == 7


def test_sca_namespace_types(tmp_path: Path) -> None:
    sca = f'xmlns:sca="{SCA}"'
    ok = load(tmp_path, robot('<property name="name" type="sca:Multiplicity">0..n</property>').replace(HEAD, f"{HEAD} {sca}"))
    assert ok["name"] == "0..n"
    err = refused(tmp_path, robot('<property name="name" type="sca:Multiplicity">2..3</property>').replace(HEAD, f"{HEAD} {sca}"))
    assert err.codes == ["ASM50027"] and "'0..1', '1..1', '0..n', '1..n'" in str(err)


def test_asm40008_asm50029_an_element_property_takes_instances_of_a_global_element(tmp_path: Path) -> None:
    ok = load(tmp_path, robot(
        '<property name="pose" element="geo:pose"><geo:pose><geo:x>1</geo:x><geo:y>2</geo:y>'
        '<geo:label>dock</geo:label></geo:pose></property>'))
    assert ok["pose"].label == "dock" and ok["pose"].y == 2.0
    unknown = refused(tmp_path, robot('<property name="pose" element="geo:where"><geo:where/></property>'))
    assert unknown.codes == ["ASM40008"]
    invalid = refused(tmp_path, robot('<property name="pose" element="geo:pose"><geo:pose><geo:x>1</geo:x></geo:pose></property>'))
    assert invalid.codes == ["ASM50029"] and "Expected is ( y )" in str(invalid)


@pytest.mark.parametrize("where, code", [("component", "ASM50035"), ("composite", "ASM60040")])
def test_type_and_element_together(tmp_path: Path, where: str, code: str) -> None:
    both = '<property name="{n}" type="geo:Point" element="geo:pose"/>'
    text = robot(both.format(n="pose")) if where == "component" else robot("", both.format(n="p"))
    err = refused(tmp_path, text)
    assert code in err.codes and "both @type and @element" in str(err)


def test_asm50032_asm50033_value_counts(tmp_path: Path) -> None:
    two = refused(tmp_path, robot('<property name="speed"><value>1</value><value>2</value></property>'))
    assert two.codes == ["ASM50032"] and "property 'speed' (float) is single-valued but has 2 values" in str(two)
    both = refused(tmp_path, robot('<property name="speed" type="xs:double" value="1"><value>2</value></property>'))
    assert both.codes == ["ASM50033"] and "property 'speed' (xs:double) has both @value and a <value>" in str(both)


# ---- type agreement ---------------------------------------------------------------------

def test_asm50036_a_component_property_type_matches_its_component_type(tmp_path: Path) -> None:
    err = refused(tmp_path, robot('<property name="count" type="xs:string">seven</property>'))
    assert err.codes == ["ASM50036"] and "declared xs:string, but its componentType's is integer" in str(err)
    assert load(tmp_path, robot('<property name="count" type="xs:long">7</property>'))["count"] == 7


def test_asm50038_a_source_has_a_compatible_type(tmp_path: Path) -> None:
    err = refused(tmp_path, robot('<property name="count" source="$label"/>',
                                  '<property name="label" type="xs:string">x</property>'))
    assert err.codes == ["ASM50038"] and "@source $label is xs:string" in str(err)
    ok = load(tmp_path, robot('<property name="count" source="$n"/>', '<property name="n" type="xs:int">3</property>'))
    assert ok["count"] == 3


# ---- @source XPath -------------------------------------------------------------------------

def test_source_is_an_xpath_into_complex_composite_properties(tmp_path: Path) -> None:
    composite_props = """
        <property name="site" type="geo:Point"><value><geo:x>10</geo:x><geo:y>20</geo:y></value></property>
        <property name="route" type="geo:Point" many="true">
          <value><geo:x>1</geo:x><geo:y>2</geo:y></value>
          <value><geo:x>3</geo:x><geo:y>4</geo:y></value>
        </property>
        <property name="label" type="xs:string">dock</property>"""
    values = load(tmp_path, robot("""
        <property name="speed" source="$site/geo:x"/>
        <property name="count" source="$route[2]/geo:y/text()"/>
        <property name="home" source="$route[1]"/>
        <property name="name" source="concat($label, '-', $site/geo:y)"/>
        <property name="waypoints" source="$route"/>""", composite_props))
    assert values["speed"] == 10.0 and values["count"] == 4
    assert (values["home"].x, values["home"].y) == (1.0, 2.0)
    assert values["name"] == "dock-20" and len(values["waypoints"]) == 2


@pytest.mark.parametrize("source", ["$site/geo:x[", "$site/nope:x", "$missing/geo:x"])
def test_a_bad_source_is_named(tmp_path: Path, source: str) -> None:
    err = refused(tmp_path, robot(f'<property name="speed" source="{source}"/>',
                                  '<property name="site" type="geo:Point"><value><geo:x>1</geo:x><geo:y>2</geo:y></value></property>'))
    assert err.codes == ["SCART-C003"] and f"@source {source!r}" in str(err)


# ---- @file ----------------------------------------------------------------------------------

VALUES = f'<values xmlns="{SCA}" xmlns:geo="urn:geo">{{}}</values>'


def test_a_file_is_an_sca_values_document(tmp_path: Path) -> None:
    files = {
        "home.xml": VALUES.format("<value><geo:x>5</geo:x><geo:y>6</geo:y></value>"),
        "route.xml": VALUES.format("<value><geo:x>1</geo:x><geo:y>1</geo:y></value>"
                                   "<value><geo:x>2</geo:x><geo:y>2</geo:y></value>"),
        "speed.xml": VALUES.format("<value>0.75</value>"),
        "pose.xml": VALUES.format("<geo:pose><geo:x>1</geo:x><geo:y>1</geo:y></geo:pose>"),
        "name.txt": "plain text, scart's extension\n",
    }
    values = load(tmp_path, robot("""
        <property name="home" type="geo:Point" file="home.xml"/>
        <property name="waypoints" type="geo:Point" file="route.xml"/>
        <property name="speed" file="speed.xml"/>
        <property name="pose" element="geo:pose" file="pose.xml"/>
        <property name="name" file="name.txt"/>"""), **files)
    assert (values["home"].x, values["speed"], len(values["waypoints"])) == (5.0, 0.75, 2)
    assert values["pose"].x == 1.0 and values["name"] == "plain text, scart's extension"


@pytest.mark.parametrize("content, message", [
    ("<points><point/></points>", "must be an <sca:values>"),
    (VALUES.format("<value>1</value><geo:x>1</geo:x>"), "either <value> elements or global elements"),
    (VALUES.format(""), "holds no value"),
    ("<values", "not well-formed"),
])
def test_asm50046_a_file_that_is_not_a_values_document(tmp_path: Path, content: str, message: str) -> None:
    err = refused(tmp_path, robot('<property name="speed" file="v.xml"/>'), **{"v.xml": content})
    assert err.codes == ["ASM50046"] and message in str(err)


def test_a_file_value_is_checked_against_the_type_without_showing_it(tmp_path: Path) -> None:
    err = refused(tmp_path, robot('<property name="speed" type="geo:Speed" file="v.xml"/>'),
                  **{"v.xml": VALUES.format("<value>secret-9</value>")})
    assert err.codes == ["ASM50027"] and "content not shown" in str(err) and "secret" not in str(err)


# ---- componentType side files -------------------------------------------------------------

SIDE = f"""<?xml version="1.0"?>
<componentType xmlns="{SCA}" xmlns:geo="urn:geo" xmlns:xs="http://www.w3.org/2001/XMLSchema">
  {{}}
</componentType>
"""

CALLER = '''
import scart
from comps import Greeter


class Caller:
    greeter: Greeter = scart.reference()

    def call(self) -> str:
        return self.greeter.greet("side")
'''


def test_a_component_type_side_file_types_and_defaults_properties(tmp_path: Path) -> None:
    side = SIDE.format('<property name="home" type="geo:Point"><value><geo:x>7</geo:x><geo:y>8</geo:y></value></property>'
                       '<property name="count" type="xs:int" mustSupply="true"/>')
    text = robot('<property name="count">2</property>')
    values = load(tmp_path, text, **{"Robot.componentType": side})
    assert (values["home"].x, values["count"]) == (7.0, 2)
    err = refused(tmp_path, robot(""), **{"Robot.componentType": side})
    assert err.codes == ["ASM40011"] and "'count' not supplied" in str(err)
    mismatch = refused(tmp_path, robot('<property name="home" type="xs:string">x</property>'
                                       '<property name="count">1</property>'), **{"Robot.componentType": side})
    assert mismatch.codes == ["ASM50036"]


def test_asm40003_to_asm40010_a_side_file_is_checked(tmp_path: Path) -> None:
    side = SIDE.format('<property name="count" type="xs:int"/><property name="count" type="xs:int"/>'
                       '<property name="speed" type="xs:double" element="geo:pose"/>'
                       '<property name="weight" type="xs:double"/>')
    err = refused(tmp_path, robot(""), **{"Robot.componentType": side})
    assert {"ASM40005", "ASM40010", "SCART-C007"} <= set(err.codes), str(err)
    assert all(p.path.endswith("Robot.componentType") for p in err.errors)


def test_binding_sca_uri_on_a_component_type_reference_is_its_default_target(tmp_path: Path) -> None:
    side = SIDE.format('<reference name="greeter"><binding.sca uri="G/Greeter"/></reference>')
    text = composite("""
        <component name="G"><scart:implementation.python class="comps:GreeterImpl"/></component>
        <component name="C"><scart:implementation.python class="caller:Caller"/></component>""")
    path = write(tmp_path, {"main.composite": text, "caller.py": CALLER, "Caller.componentType": side})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("C").call() == "Hello, side"
    # the component's own target wins over the componentType's
    text = text.replace('class="caller:Caller"/>', 'class="caller:Caller"/><reference name="greeter" target="H"/>')
    text = text.replace("</composite>", '<component name="H"><scart:implementation.python class="comps:GreeterImpl"/>'
                        '<property name="greeting">Hi</property></component></composite>')
    path = write(tmp_path, {"main.composite": text})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("C").call() == "Hi, side"


# ---- review: values in scope, families, files through XPath, nested composites ----------------

def test_a_qname_value_resolves_its_prefix_in_the_composite(tmp_path: Path) -> None:
    text = robot('<property name="raw" type="xs:QName" xmlns:foo="urn:foo">foo:bar</property>')
    assert load(tmp_path, text)["raw"] == "foo:bar"
    err = refused(tmp_path, robot('<property name="raw" type="xs:QName">nope:bar</property>'))
    assert err.codes == ["ASM50027"] and "property 'raw' (xs:QName)" in str(err)


def test_a_string_property_may_declare_another_simple_type(tmp_path: Path) -> None:
    text = robot('<property name="raw" type="xs:dateTime">2026-11-25T10:00:00Z</property>')
    assert load(tmp_path, text)["raw"] == "2026-11-25T10:00:00Z"
    assert refused(tmp_path, robot('<property name="raw" type="xs:dateTime">tomorrow</property>')).codes == ["ASM50027"]


def test_a_file_value_taken_through_an_xpath_is_not_shown_either(tmp_path: Path) -> None:
    composite_props = '<property name="secret" file="v.xml" many="true"/>'
    err = refused(tmp_path, robot('<property name="count" source="$secret[1]/text()"/>', composite_props),
                  **{"v.xml": VALUES.format("<value>hunter2</value><value>x</value>")})
    assert err.codes == ["ASM50027"] and "hunter2" not in str(err) and "v.xml" in str(err), str(err)


def test_asm50032_a_single_valued_composite_property_has_one_value(tmp_path: Path) -> None:
    text = robot('<property name="count" source="$n"/>',
                 '<property name="n" type="xs:int"><value>1</value><value>2</value></property>')
    err = refused(tmp_path, text)
    assert err.codes == ["ASM50032"] and err.errors[0].line == line_of(text, 'name="n"'), str(err)
    many = text.replace('name="n" type="xs:int"', 'name="n" type="xs:int" many="true"').replace(
        'name="count" source="$n"', 'name="count" source="$n[2]"')
    assert load(tmp_path, many)["count"] == 2


INNER = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" xmlns:xs="http://www.w3.org/2001/XMLSchema"
           targetNamespace="urn:test" name="Inner">
  <property name="n" type="xs:int"/>
  <component name="R"><scart:implementation.python class="props:Robot"/><property name="count" source="$n"/></component>
  <service name="R" promote="R"/>
</composite>
"""


@pytest.mark.parametrize("given, code", [("<value>seven</value>", "ASM50027"),
                                         ("<value>1</value><value>2</value>", "ASM50032")])
def test_a_nested_composite_property_is_checked_where_it_is_given(tmp_path: Path, given: str, code: str) -> None:
    text = composite(f"""
        <component name="O"><implementation.composite name="t:Inner"/>
          <property name="n">{given}</property><!--HERE-->
        </component>""")
    err = refused(tmp_path, text, **{"inner.composite": INNER})
    assert err.codes == [code] and err.errors[0].line == line_of(text, "<!--HERE-->"), str(err)
    path = write(tmp_path, {"main.composite": text.replace(given, "<value>3</value>"), "props.py": PROPS,
                            "inner.composite": INNER})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("O/R").values()["count"] == 3


BASE = """<?xml version="1.0"?>
<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" targetNamespace="urn:parts" elementFormDefault="qualified">
  <xs:simpleType name="Ratio"><xs:restriction base="xs:double"><xs:maxInclusive value="1"/></xs:restriction></xs:simpleType>
</xs:schema>
"""
PARTS = """<?xml version="1.0"?>
<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" xmlns:p="urn:parts" targetNamespace="urn:parts"
           elementFormDefault="qualified">
  <xs:include schemaLocation="base.xsd"/>
  <xs:simpleType name="Speed"><xs:restriction base="p:Ratio"><xs:minInclusive value="0"/></xs:restriction></xs:simpleType>
</xs:schema>
"""


def test_a_schema_included_by_another_is_loaded_once(tmp_path: Path) -> None:
    text = robot('<property name="speed" type="p:Speed" xmlns:p="urn:parts">0.5</property>')
    assert load(tmp_path, text, **{"base.xsd": BASE, "parts.xsd": PARTS})["speed"] == 0.5
    err = refused(tmp_path, text.replace(">0.5<", ">1.5<"), **{"base.xsd": BASE, "parts.xsd": PARTS})
    assert err.codes == ["ASM50027"] and "1.5" in str(err)
    broken = PARTS.replace('base="p:Ratio"', 'base="p:Nothing"')
    err = refused(tmp_path, text, **{"base.xsd": BASE, "parts.xsd": broken})
    assert "parts.xsd" in str(err) and "scart-" not in str(err), str(err)


def test_an_sca_1_0_complex_value_is_the_property_s_own_content(tmp_path: Path) -> None:
    text = composite("""
        <component name="R"><scart:implementation.python class="props:Robot"/>
          <property name="home"><geo:x>4</geo:x><geo:y>5</geo:y></property>
        </component>""", ns=OSOA, extra=f" {HEAD}")
    values = load(tmp_path, text)
    assert (values["home"].x, values["home"].y) == (4.0, 5.0)
    err = refused(tmp_path, text.replace(OSOA, SCA))  # 1.1 wants a <value>
    assert "unknown element <x> in 'urn:geo' inside <property>" in str(err)
