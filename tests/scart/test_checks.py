"""Static checks: each rule refused before anything starts, at its line, with its code."""

from __future__ import annotations

from pathlib import Path

import pytest

import scart
from support.sca import composite, line_of, py, write


def errors_of(path: Path, overrides: dict[str, str] | None = None) -> scart.ScdlError:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path), overrides=overrides)
    return info.value


def only(err: scart.ScdlError, code: str) -> scart.Problem:
    matching = [p for p in err.errors if p.code == code]
    assert matching, f"no {code} in {err}"
    return matching[0]


CASES = {
    # name: (body, code, marker of the faulty line, message fragment)
    "duplicate component": (f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="A"><!--HERE-->{py("GreeterImpl")}</component>
    """, "ASM50001", "duplicate component name 'A'"),
    "target names no component": (f"""
        <component name="S">{py("Single")}
          <reference name="one" target="Nobody"/><!--HERE-->
        </component>
    """, "ASM60047", "no component 'Nobody'"),
    "target names no such service": (f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one" target="A/Nope"/><!--HERE-->
        </component>
    """, "ASM60047", "has no service 'Nope'"),
    "1..1 with zero targets": (f"""
        <component name="S"><!--HERE-->{py("Single")}</component>
    """, "ASM50040", "reference 'one' (1..1) has 0 targets"),
    "1..1 with two targets": (f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="B">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one" target="A B"/><!--HERE-->
        </component>
    """, "ASM50040", "(1..1) has 2 targets"),
    "0..1 with two targets": (f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("OptionalOne")}
          <reference name="maybe" target="A A/Greeter"/><!--HERE-->
        </component>
    """, "ASM50039", "(0..1) has 2 targets"),
    "1..n with none": (f"""
        <component name="S"><!--HERE-->{py("AtLeastOne")}</component>
    """, "ASM50041", "(1..n) has no target"),
    "mustSupply property missing": (f"""
        <component name="N"><!--HERE-->{py("NeedsValue")}</component>
    """, "ASM40011", "required property 'value' not supplied"),
    "property value of the wrong type": (f"""
        <component name="N">{py("NeedsValue")}
          <property name="value">forty-two</property><!--HERE-->
        </component>
    """, "ASM50027", "'forty-two' is not a valid int"),
    "bool property value": (f"""
        <component name="P">{py("Props")}
          <property name="flag">yes</property><!--HERE-->
        </component>
    """, "ASM50027", "not a boolean"),
    "property the implementation does not declare": (f"""
        <component name="G">{py("GreeterImpl")}
          <property name="colour">red</property><!--HERE-->
        </component>
    """, "ASM50037", "has no property 'colour'"),
    "promoted service does not exist": (f"""
        <service name="X" promote="G/Nope"/><!--HERE-->
        <component name="G">{py("GreeterImpl")}</component>
    """, "ASM60004", "has no service 'Nope'"),
    "promoted reference does not exist": (f"""
        <reference name="R" promote="G/nope"/><!--HERE-->
        <component name="G">{py("GreeterImpl")}</component>
    """, "ASM60007", "@promote 'G/nope' names no component reference"),
    "interface mismatch": (f"""
        <component name="F">{py("FarewellImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one" target="F"/><!--HERE-->
        </component>
    """, "ASM60043", "lacks operation(s) greet"),
    "class cannot be imported": ("""
        <component name="X">
          <scart:implementation.python class="comps:NoSuchClass"/><!--HERE-->
        </component>
    """, "SCART-I001", "cannot import 'comps:NoSuchClass'"),
    "module cannot be imported": ("""
        <component name="X">
          <scart:implementation.python class="no_such_module_xyz:C"/><!--HERE-->
        </component>
    """, "SCART-I001", "No module named 'no_such_module_xyz'"),
    "class lacks a declared service operation": (f"""
        <component name="X">
          {py("LacksGreet")}<!--HERE-->
        </component>
    """, "SCART-I002", "lacks operation 'greet' of its declared service 'Greeter'"),
    "one-way returning a value": (f"""
        <component name="X">
          {py("BadOneWay")}<!--HERE-->
        </component>
    """, "SCART-I003", "one-way operation BadOneWay.fire declares a return value"),
    "component service not offered": (f"""
        <component name="G">{py("GreeterImpl")}
          <service name="Nope"/><!--HERE-->
        </component>
    """, "ASM50003", "has no service 'Nope'"),
    "ambiguous component target": (f"""
        <component name="T">{py("TwoFaced")}</component>
        <component name="S">{py("Single")}
          <reference name="one" target="T"/><!--HERE-->
        </component>
    """, "ASM60048", "offers 2 services"),
    "caller lacks the callback method": (f"""
        <component name="W">{py("WorkerImpl")}</component>
        <component name="S">{py("Deaf")}
          <reference name="worker" target="W"/><!--HERE-->
        </component>
    """, "SCART-I006", "needs method(s) notify on the caller"),
    "service interface not offered": (f"""
        <component name="G">{py("GreeterImpl")}
          <service name="Greeter">
            <scart:interface.python interface="comps:Farewell"/><!--HERE-->
          </service>
        </component>
    """, "ASM50004", "operation(s) bye the implementation does not offer"),
    "bad source": (f"""
        <component name="G">{py("GreeterImpl")}
          <property name="greeting" source="$nothing"/><!--HERE-->
        </component>
    """, "SCART-C003", "names no composite property"),
    "unknown implementation kind": ("""
        <component name="G">
          <implementation.java class="x.Y"/><!--HERE-->
        </component>
    """, "SCART-C002", "unknown implementation kind <implementation.java>"),
    "scart element violating the XSD": ("""
        <component name="G">
          <scart:implementation.python klass="comps:GreeterImpl"/><!--HERE-->
        </component>
    """, "SCART-X003", "attribute 'klass'"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_rule(tmp_path: Path, case: str) -> None:
    body, code, fragment = CASES[case]
    text = composite(body)
    path = write(tmp_path, {"bad.composite": text})
    err = errors_of(path)
    problem = only(err, code)
    assert fragment in problem.message
    assert problem.path == str(path)
    assert problem.line == line_of(text, "<!--HERE-->"), str(err)
    assert f"{path}:{problem.line}: " in str(err)


def test_every_problem_is_reported_together(tmp_path: Path) -> None:
    text = composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="colour">red</property></component>
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}<reference name="one" target="Nobody"/></component>
        <component name="N">{py("NeedsValue")}</component>
    """)
    err = errors_of(write(tmp_path, {"many.composite": text}))
    assert {"ASM50037", "ASM50001", "ASM60047", "ASM40011"} <= set(err.codes)
    assert err.line == err.errors[0].line and err.path == err.errors[0].path
    assert len(str(err).splitlines()) == len(err.errors)


def test_implementation_composite_cycle(tmp_path: Path) -> None:
    a = composite('<component name="B"><implementation.composite name="t:B"/></component><!--HERE-->', name="A")
    b = composite('<component name="A"><implementation.composite name="t:A"/></component>', name="B")
    path = write(tmp_path, {"a.composite": a, "b.composite": b})
    err = errors_of(path)
    problem = only(err, "SCART-C001")
    assert "cycle" in problem.message


def test_unknown_implementation_composite(tmp_path: Path) -> None:
    text = composite('<component name="X">\n<implementation.composite name="t:Missing"/><!--HERE-->\n</component>')
    path = write(tmp_path, {"x.composite": text, "broken.composite": "<composite"})
    err = errors_of(path)
    assert only(err, "ASM60030").line == line_of(text, "<!--HERE-->")
    # the unparseable sibling matters here, because it might have held the QName
    assert any("broken.composite" in p.path for p in err.errors)


def test_unparseable_sibling_does_not_matter_otherwise(tmp_path: Path) -> None:
    path = write(tmp_path, {"ok.composite": composite(f"<component name='A'>{py('GreeterImpl')}</component>"),
                            "broken.composite": "<composite"})
    scart.Runtime.from_file(str(path))


def test_bad_set_override(tmp_path: Path) -> None:
    path = write(tmp_path, {"o.composite": composite(f"<component name='A'>{py('GreeterImpl')}</component>")})
    err = errors_of(path, {"A.nope": "1", "Z.greeting": "x"})
    assert err.codes == ["SCART-C005", "SCART-C005"]
    err = errors_of(path, {"A.greeting": "ok", "B.x": "1"})
    assert "B.x" in str(err)
