"""SCA Assembly 1.1 conformance, properties and componentType side files: complex values,
XML Schema types of the contribution, @element, @source XPath, @file documents, and type
agreement — each statement both ways. Composites written from the spec's text."""

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
    (VALUES.format("<geo:x>1</geo:x>"), "holds <value> elements"),
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
