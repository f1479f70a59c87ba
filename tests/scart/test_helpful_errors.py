"""Errors that help: a misspelling gets "did you mean", a knock-on comes after its cause or
is left out, a missing file says so in words, an unknown --set lists what exists, and a
schema validator's message is rewritten into what the user wrote."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import scart
from support.sca import composite, line_of, py, write


def problems(tmp_path: Path, body: str, overrides: dict[str, str] | None = None) -> tuple[scart.ScdlError, str]:
    text = composite(body)
    path = write(tmp_path, {"m.composite": text})
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path), overrides=overrides)
    return info.value, text


def test_a_misspelled_element_gets_did_you_mean_and_no_knock_on(tmp_path: Path) -> None:
    err, text = problems(tmp_path, f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <referense name="one" target="A"/>
        </component>""")
    # the reference it meant is unwired: that is the misspelling's doing, not a second problem
    assert err.codes == ["ASM13001"], str(err)
    assert "unknown element <referense> inside <component> (did you mean 'reference'?)" in str(err)
    assert err.errors[0].line == line_of(text, "referense")


def test_a_misspelled_attribute_gets_did_you_mean(tmp_path: Path) -> None:
    err, _ = problems(tmp_path, f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Client")}
          <reference name="one" target="A"/>
          <reference name="some" target="A" mulplicity="0..n"/>
        </component>""")
    assert err.codes == ["ASM13001"] and "<reference> has no attribute 'mulplicity' (did you mean 'multiplicity'?)" \
        in str(err)


def test_a_misspelled_scart_element_or_attribute_in_the_user_s_terms(tmp_path: Path) -> None:
    err, _ = problems(tmp_path, """
        <component name="A"><scart:implementation.pyhton class="comps:GreeterImpl"/></component>
        <component name="B"><scart:implementation.python clas="comps:GreeterImpl"/></component>""")
    text = str(err)
    assert "No matching global declaration" not in text
    assert "scart has no element <scart:implementation.pyhton> (did you mean 'implementation.python'?)" in text
    assert "no attribute 'clas' (did you mean 'class'?)" in text


def test_a_missing_file_says_so_in_words(tmp_path: Path) -> None:
    missing = tmp_path / "x.composite"
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(missing))
    assert str(info.value) == f"cannot read {missing}: No such file or directory [SCART-X001]"
    out = subprocess.run([sys.executable, "-m", "scart", "validate", "x.composite"], capture_output=True, text=True,
                         timeout=60, cwd=tmp_path)
    assert out.returncode == 2 and out.stderr.startswith("cannot read x.composite: No such file or directory")


def test_an_unknown_set_lists_what_exists(tmp_path: Path) -> None:
    body = f'<component name="A">{py("GreeterImpl")}</component>'
    err, _ = problems(tmp_path, body, {"A.greting": "Hi"})
    assert "--set A.greting: component 'A' has no property 'greting' (did you mean 'greeting'?); its properties: " \
           "greeting" in str(err)
    err, _ = problems(tmp_path, body, {"B.greeting": "Hi"})
    assert "--set B.greeting: no component 'B'; components: A" in str(err)


def test_a_target_to_a_misspelled_component(tmp_path: Path) -> None:
    err, _ = problems(tmp_path, f"""
        <component name="Greeter">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}<reference name="one" target="Greter"/></component>""")
    assert "component 'S' reference 'one': target 'Greter': no component 'Greter' (did you mean 'Greeter'?)" in str(err)
