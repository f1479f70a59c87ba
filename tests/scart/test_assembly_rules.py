"""Assembly rules at the edges: several replace wires, a broken component without knock-on
errors, schema failures before imports, duplicate names, one-way and callback
compatibility, multiplicity narrowing, remotable, autowire, DOCTYPE detection, nested
composites used twice, duplicate QNames, ``scart graph`` of promoted references, ``--set``."""

from __future__ import annotations

from pathlib import Path

import pytest

import scart
from support.cli import run
from support.sca import composite, line_of, py, write

EXTRA = '''
from __future__ import annotations

from typing import Protocol

import scart


@scart.interface
class FireAndForget(Protocol):
    @scart.oneway
    def greet(self, name: str) -> None: ...


class OneWayCaller:
    one: FireAndForget = scart.reference()


@scart.interface
class Ping(Protocol):
    def ping(self) -> str: ...


class Mutator(Protocol):
    def mutate(self, items: list) -> list: ...


class Mutating:
    target: Mutator = scart.reference()

    def run(self, items: list) -> list:
        return self.target.mutate(items)


@scart.interface
class Pong(Protocol):
    def pong(self) -> None: ...
'''


def errors_of(path: Path) -> scart.ScdlError:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return info.value


def codes(err: scart.ScdlError) -> list[str]:
    return [p.code for p in err.errors]


def extra_write(tmp_path: Path, body: str) -> tuple[Path, str]:
    (tmp_path / "extra.py").write_text(EXTRA, encoding="utf-8")
    text = composite(body)
    return write(tmp_path, {"x.composite": text}), text


def test_two_replace_wires_keep_both(tmp_path: Path) -> None:
    path = write(tmp_path, {"w.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">A</property></component>
        <component name="B">{py("GreeterImpl")}<property name="greeting">B</property></component>
        <component name="C">{py("GreeterImpl")}<property name="greeting">C</property></component>
        <component name="M">{py("AtLeastOne")}<reference name="many" target="A"/></component>
        <wire source="M/many" target="B" replace="true"/>
        <wire source="M/many" target="C" replace="true"/>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("M").call("x") == ["B, x", "C, x"]


def test_a_broken_component_causes_no_cascade(tmp_path: Path) -> None:
    text = composite(f"""
        <component name="A"><scart:implementation.python class="comps:Nope"/></component>
        <component name="A"><!--DUP-->{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}<reference name="one" target="A"/></component>
        <component name="P">{py("Single")}<reference name="one" target="A Q"/></component>
    """)
    path = write(tmp_path, {"c.composite": text})
    err = errors_of(path)
    assert sorted(codes(err)) == ["ASM50001", "ASM60047", "SCART-I001"], str(err)
    dup = next(p for p in err.errors if p.code == "ASM50001")
    assert dup.line == line_of(text, "<!--DUP-->")


def test_no_import_after_a_schema_failure(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite("""
        <component name="A"><scart:implementation.python/></component>
        <component name="B">
          <scart:implementation.python class="comps:Single"/>
          <reference name="one" target="A"><scart:interface.python/></reference>
        </component>
    """)})
    err = errors_of(path)
    assert set(codes(err)) == {"SCART-X003"}, str(err)
    assert "cannot import" not in str(err)


def test_duplicate_names_in_a_component_and_a_composite(tmp_path: Path) -> None:
    text = composite(f"""
        <service name="S" promote="G"/>
        <service name="S" promote="G"/><!--CS-->
        <reference name="R" promote="C/one"/>
        <reference name="R" promote="C/one"/><!--CR-->
        <component name="G">{py("GreeterImpl")}
          <service name="Greeter"/>
          <service name="Greeter"/><!--SVC-->
        </component>
        <component name="C">{py("Single")}
          <reference name="one" target="G"/>
          <reference name="one" target="Nobody"/><!--REF-->
        </component>
    """)
    path = write(tmp_path, {"d.composite": text})
    err = errors_of(path)
    got = {p.code: p.line for p in err.errors}
    assert got == {"ASM60003": line_of(text, "<!--CS-->"), "ASM60006": line_of(text, "<!--CR-->"),
                   "ASM50002": line_of(text, "<!--SVC-->"), "ASM50007": line_of(text, "<!--REF-->")}, str(err)


def test_oneway_flag_must_match_between_reference_and_service(tmp_path: Path) -> None:
    path, text = extra_write(tmp_path, f"""
        <component name="G">{py("GreeterImpl")}</component>
        <component name="C"><scart:implementation.python class="extra:OneWayCaller"/>
          <reference name="one" target="G"/><!--HERE-->
        </component>
    """)
    err = errors_of(path)
    assert codes(err) == ["ASM60043"] and "one-way differs for greet" in str(err)
    assert err.errors[0].line == line_of(text, "<!--HERE-->")


def test_callback_interface_must_match(tmp_path: Path) -> None:
    path, text = extra_write(tmp_path, f"""
        <component name="G">{py("GreeterImpl")}</component>
        <component name="C">{py("Single")}
          <reference name="one" target="G"><!--HERE-->
            <scart:interface.python interface="comps:Greeter" callbackInterface="extra:Pong"/>
          </reference>
        </component>
    """)
    err = errors_of(path)
    # the implementation's reference (Greeter) has no callback: the declared one cannot add it
    # (and is not checked against the target: that would only repeat the problem)
    assert codes(err) == ["ASM50011"] and "no callback interface" in str(err)
    assert err.errors[0].line == line_of(text, "interface.python")


def test_a_component_cannot_widen_a_reference_multiplicity(tmp_path: Path) -> None:
    text = composite(f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="B">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one" target="A B" multiplicity="0..n"/><!--HERE-->
        </component>
        <component name="N">{py("Client")}
          <reference name="one" target="A"/>
          <reference name="some" target="A" multiplicity="1..1"/>
        </component>
    """)
    path = write(tmp_path, {"m.composite": text})
    err = errors_of(path)
    assert "ASM50009" in codes(err) and "does not narrow" in str(err)
    assert only_line(err, "ASM50009") == line_of(text, "<!--HERE-->")
    assert codes(err).count("ASM50009") == 1  # narrowing 0..n to 1..1 is fine


def only_line(err: scart.ScdlError, code: str) -> int:
    return next(p.line for p in err.errors if p.code == code)


def test_remotable_on_interface_python_gives_pass_by_value(tmp_path: Path) -> None:
    path, _ = extra_write(tmp_path, f"""
        <component name="L">{py("LocalMutatorImpl")}</component>
        <component name="C"><scart:implementation.python class="extra:Mutating"/>
          <reference name="target" target="L">
            <scart:interface.python interface="comps:LocalMutator" remotable="true"/>
          </reference>
        </component>
    """)
    with scart.Runtime.from_file(str(path)) as rt:
        mine = ["caller"]
        assert rt.service("C").run(mine) == ["caller", "callee"]
        assert mine == ["caller"]  # the callee got a copy
        assert rt.service("L").mutate(mine) is mine  # the service itself stays local


def test_autowire_of_a_single_reference_picks_the_first_match(tmp_path: Path) -> None:
    path = write(tmp_path, {"a.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">A</property></component>
        <component name="B">{py("GreeterImpl")}<property name="greeting">B</property></component>
        <component name="S" autowire="true">{py("Single")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("S").call("x") == "A, x"


# --- 11. DOCTYPE pre-check --------------------------------------------------------------

def test_doctype_inside_a_comment_is_no_false_positive(tmp_path: Path) -> None:
    body = f'<!-- do not add <!DOCTYPE here, nor <!ENTITY x "y"> -->\n<component name="G">{py("GreeterImpl")}</component>'
    path = write(tmp_path, {"c.composite": composite(body).replace("<composite", "<!-- <!DOCTYPE x> -->\n<composite", 1)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("G").greet("x") == "Hello, x"


@pytest.mark.parametrize("encoding", ["utf-8", "utf-16", "utf-16-le", "utf-16-be"])
def test_a_real_doctype_after_a_comment_is_still_refused(tmp_path: Path, encoding: str) -> None:
    text = (f'<?xml version="1.0" encoding="{encoding.upper()[:6]}"?>\n<!-- note -->\n'
            '<!DOCTYPE composite [<!ENTITY e "x">]>\n' + composite("<component name='A'/>").split("\n", 1)[1])
    path = tmp_path / "d.composite"
    path.write_bytes(text.encode(encoding))
    err = errors_of(path)
    assert codes(err) == ["SCART-X002"] and err.errors[0].line == 3, str(err)


# --- 10. nested composite used twice; 13. same QName twice ------------------------------------

def nested_twice(tmp_path: Path) -> None:
    inner = composite(f"""
        <service name="Greeter" promote="G"/>
        <component name="G">{py("GreeterImpl")}<property name="nope">x</property><!--BAD--></component>
    """, name="Inner")
    outer = composite("""
        <component name="M1"><implementation.composite name="t:Inner"/></component>
        <component name="M2"><implementation.composite name="t:Inner"/></component>
    """, name="Outer")
    write(tmp_path, {"outer.composite": outer, "inner.composite": inner})


def test_a_nested_composite_used_twice_reports_its_problems_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    nested_twice(tmp_path)
    monkeypatch.chdir(tmp_path)
    err = errors_of(Path("outer.composite"))
    assert [(p.code, p.path) for p in err.errors] == [("ASM50037", "inner.composite")], str(err)


def test_two_composites_with_the_same_qname_are_reported_when_used(tmp_path: Path) -> None:
    inner = composite(f'<component name="G">{py("GreeterImpl")}</component>', name="Inner")
    outer = composite('<component name="M"><implementation.composite name="t:Inner"/><!--HERE--></component>',
                      name="Outer")
    path = write(tmp_path, {"outer.composite": outer, "a.composite": inner, "b.composite": inner})
    err = errors_of(path)
    assert codes(err) == ["ASM60001"] and "a.composite" in str(err) and "b.composite" in str(err)
    # unused, the clash does not matter
    alone = write(tmp_path, {"alone.composite": composite(f'<component name="G">{py("GreeterImpl")}</component>',
                                                          name="Alone")})
    scart.Runtime.from_file(str(alone))


# --- 12. graph of promoted references through nested composites -------------------------------

@pytest.mark.subprocess
def test_graph_draws_promoted_references_from_leaf_nodes(tmp_path: Path) -> None:
    inner = composite(f"""
        <reference name="Out" promote="S/one"/>
        <component name="S">{py("Single")}</component>
    """, name="Inner")
    outer = composite(f"""
        <reference name="Top" promote="M/Out" target="G"/>
        <component name="M"><implementation.composite name="t:Inner"/><reference name="Out" target="G"/></component>
        <component name="G">{py("GreeterImpl")}</component>
    """, name="Outer")
    path = write(tmp_path, {"outer.composite": outer, "inner.composite": inner})
    out = run("graph", str(path))
    assert out.returncode == 0, out.stderr
    assert '"M/S" -> "reference:Top" [style=dashed' in out.stdout
    assert '"M/S" -> "reference:M/Out" [style=dashed' in out.stdout
    assert '"M" -> "reference:Top"' not in out.stdout


# --- 13. --set --------------------------------------------------------------------------------

def test_a_bad_set_value_is_reported_at_the_command_line(tmp_path: Path) -> None:
    path = write(tmp_path, {"p.composite": composite(f"""
        <component name="P">{py("Props")}<property name="number">3</property></component>
    """)})
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path), overrides={"P.number": "abc"})
    (problem,) = info.value.errors
    assert problem.code == "ASM50027" and problem.path == "<command line>" and "--set P.number" in problem.message


@pytest.mark.subprocess
def test_validate_set_with_several_files_needs_the_component_in_one(tmp_path: Path) -> None:
    a = write(tmp_path / "a", {"a.composite": composite(f'<component name="P">{py("Props")}</component>')})
    b = write(tmp_path / "b", {"b.composite": composite(f'<component name="G">{py("GreeterImpl")}</component>')})
    ok = run("validate", str(a), str(b), "--set", "P.number=4")
    assert ok.returncode == 0, ok.stderr
    bad = run("validate", str(a), str(b), "--set", "Q.number=4")
    assert bad.returncode == 2 and "--set Q.number" in bad.stderr
    single = run("validate", str(b), "--set", "P.number=4")
    assert single.returncode == 2 and "SCART-C005" in single.stderr
