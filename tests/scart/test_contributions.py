"""Contributions as SCA Assembly 1.1 has them: META-INF/sca-contribution.xml with
deployables, imports and exports of namespaces, resolved across several contribution
folders — and every composite of this repository validates."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import scart
from scart.assembly import assemble
from support import ROOT
from support.sca import SCA, composite, line_of, write

SHARED_NS = "urn:shared"

SHARED_PY = '''
import scart


class Arm:
    def move(self, where: str) -> str:
        return f"arm moved to {where}"
'''

SHARED_PARTS = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="{SHARED_NS}" name="Parts">
  <component name="Arm"><scart:implementation.python class="shared_parts:Arm"/></component>
  <service name="Arm" promote="Arm"/>
</composite>
"""

SHARED_WSDL = f"""<?xml version="1.0"?>
<definitions xmlns="http://schemas.xmlsoap.org/wsdl/" targetNamespace="{SHARED_NS}" name="Arm">
  <portType name="Arm"><operation name="move"><input message="x"/><output message="y"/></operation></portType>
</definitions>
"""


def metadata(*lines: str, extra: str = "") -> str:
    return (f'<?xml version="1.0"?>\n<contribution xmlns="{SCA}" xmlns:s="{SHARED_NS}" xmlns:a="urn:app"{extra}>\n'
            + "\n".join(lines) + "\n</contribution>\n")


def shared(folder: Path, *lines: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "META-INF").mkdir(exist_ok=True)
    (folder / "META-INF" / "sca-contribution.xml").write_text(metadata(*lines or (f'<export namespace="{SHARED_NS}"/>',)))
    (folder / "shared_parts.py").write_text(SHARED_PY)
    (folder / "parts.composite").write_text(SHARED_PARTS)
    (folder / "arm.wsdl").write_text(SHARED_WSDL)
    return folder


APP_BODY = f"""
    <component name="Robot" xmlns:s="{SHARED_NS}"><implementation.composite name="s:Parts"/></component>
    <component name="User"><scart:implementation.python class="app_user:User"/>
      <reference name="arm" target="Robot/Arm">
        <interface.wsdl interface="{SHARED_NS}#wsdl.porttype(Arm)"/>
      </reference>
    </component>
"""

APP_PY = '''
import scart
from shared_parts import Arm  # a module of the other contribution


class User:
    arm: Arm = scart.reference()

    def go(self) -> str:
        return self.arm.move("home")
'''


def app(folder: Path, *meta: str) -> Path:
    path = write(folder, {"app.composite": composite(APP_BODY, name="App", tns="urn:app"), "app_user.py": APP_PY},
                 with_components=False)
    if meta:
        (folder / "META-INF").mkdir(exist_ok=True)
        (folder / "META-INF" / "sca-contribution.xml").write_text(metadata(*meta))
    return path


def refused(path: Path, **kwargs: object) -> scart.ScdlError:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path), **kwargs)  # type: ignore[arg-type]
    return info.value


def test_an_imported_namespace_comes_from_the_contribution_exporting_it(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>')
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"  # composite, WSDL and module of the other one


def test_an_import_may_locate_its_contribution(tmp_path: Path) -> None:
    shared(tmp_path / "shared")
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}" location="../shared"/>')
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("User").go() == "arm moved to home"


def test_asm12021_an_import_nobody_exports(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared", '<export namespace="urn:other"/>')
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>')
    err = refused(path, contributions=[lib])
    assert err.codes[0] == "ASM12021" and f"import of namespace {SHARED_NS!r}: no contribution" in str(err)
    assert err.errors[0].path.endswith("sca-contribution.xml") and err.errors[0].line == 3
    located = refused(app(tmp_path / "app2", f'<import namespace="{SHARED_NS}" location="../nowhere"/>'))
    assert "no such folder" in str(located)


def test_asm12024_an_imported_name_is_not_taken_from_the_importer_itself(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>')
    decoy = SHARED_PARTS.replace('class="shared_parts:Arm"', 'class="nowhere:Nothing"')
    (tmp_path / "app" / "decoy.composite").write_text(decoy)  # same QName, inside the importer
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"


def test_asm12023_an_import_that_does_not_hold_it_is_followed_by_the_importer_s_own(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    (lib / "parts.composite").unlink()  # the exporter holds no Parts: the importer's own copy comes next
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>')
    (tmp_path / "app" / "own.composite").write_text(SHARED_PARTS)
    (tmp_path / "app" / "shared_parts.py").write_text(SHARED_PY)
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"
    (tmp_path / "app" / "own.composite").unlink()  # in neither: named where it is used
    err = refused(path, contributions=[lib])
    assert err.codes == ["ASM60030"] and "names no composite {urn:shared}Parts" in str(err)


def test_imports_and_exports_of_other_languages_are_accepted(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared", f'<export namespace="{SHARED_NS}"/>', '<export.java package="org.parts"/>')
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>', '<import.java package="org.parts"/>')
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"


def test_without_metadata_a_contribution_sees_what_the_others_export(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    path = app(tmp_path / "app")
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"
    private = shared(tmp_path / "private", '<export namespace="urn:other"/>')
    err = refused(app(tmp_path / "app3"), contributions=[private])
    assert "ASM60030" in err.codes  # nothing exported in urn:shared: Parts cannot be found


def test_a_contribution_folder_runs_its_deployable(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    folder = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>', '<deployable composite="a:App"/>').parent
    with scart.Runtime.from_file(str(folder), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"
    (folder / "META-INF" / "sca-contribution.xml").write_text(metadata(
        f'<import namespace="{SHARED_NS}"/>', '<deployable composite="a:App"/>', '<deployable composite="a:Other"/>'))
    assert "lists 2 deployable composites (App, Other): name one .composite file" in str(refused(folder))
    assert "a folder without META-INF/sca-contribution.xml" in str(refused(tmp_path / "shared" / "META-INF"))


def test_asm12027_the_contribution_file_follows_its_schema(tmp_path: Path) -> None:
    path = app(tmp_path / "app", '<deployabel composite="a:App"/>', '<export namspace="urn:app"/>')
    err = refused(path)
    assert err.codes[:3] == ["ASM12027", "ASM12027", "ASM12027"], str(err)  # causes first
    assert "unknown element <deployabel> inside <contribution> (did you mean 'deployable'?)" in str(err)
    assert "<export> has no attribute 'namspace' (did you mean 'namespace'?)" in str(err)


@pytest.mark.subprocess
def test_the_command_line_takes_contribution_folders(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    folder = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>', '<deployable composite="a:App"/>').parent
    scart_cli = [sys.executable, "-m", "scart", "validate"]
    ok = subprocess.run([*scart_cli, str(folder), "--contribution", str(lib)], capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0, ok.stderr
    missing = subprocess.run([*scart_cli, str(folder)], capture_output=True, text=True, timeout=60)
    assert missing.returncode == 2 and "ASM12021" in missing.stderr


def test_artifacts_in_subfolders_are_found_and_nested_contributions_left_out(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    (lib / "parts.composite").unlink()
    (lib / "composites" / "arm").mkdir(parents=True)
    (lib / "composites" / "arm" / "parts.composite").write_text(SHARED_PARTS)
    (lib / "interfaces").mkdir()
    (lib / "arm.wsdl").rename(lib / "interfaces" / "arm.wsdl")
    for skipped in (".hidden", "__pycache__", "nested"):  # none of these is searched: no duplicate Parts
        (lib / skipped / "META-INF").mkdir(parents=True)
        (lib / skipped / "parts.composite").write_text(SHARED_PARTS.replace("shared_parts:Arm", "nowhere:Nothing"))
    (lib / "nested" / "META-INF" / "sca-contribution.xml").write_text(metadata())
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>')
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"
    (lib / "composites" / "arm" / "parts.composite").write_text(SHARED_PARTS.replace("<service", "<servise"))
    err = refused(path, contributions=[lib])
    assert err.errors[0].path.endswith(str(Path("composites") / "arm" / "parts.composite")), str(err)


# ---- the schemas a WSDL's messages need ------------------------------------------------------

TYPED_WSDL = f"""<?xml version="1.0"?>
<definitions xmlns="http://schemas.xmlsoap.org/wsdl/" xmlns:tns="{SHARED_NS}" targetNamespace="{SHARED_NS}"
             xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:m="urn:messages"
             xsi:schemaLocation="urn:messages {{location}}" name="Arm">
  {{types}}
  <message name="where"><part name="where" element="m:where"/></message>
  <message name="done"><part name="done" element="m:done"/></message>
  <portType name="Arm"><operation name="move"><input message="tns:where"/><output message="tns:done"/></operation>
  </portType>
</definitions>
"""

MESSAGES_XSD = """<?xml version="1.0"?>
<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" targetNamespace="urn:messages">
  <xs:element name="where" type="xs:string"/><xs:element name="done" type="xs:string"/>
</xs:schema>
"""

INLINE = """<types><xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" targetNamespace="urn:messages">
    <xs:element name="where" type="xs:string"/><xs:element name="done" type="xs:string"/></xs:schema></types>"""


@pytest.mark.parametrize("location, types, xsd", [
    ("http://example.com/schemas/messages.xsd", "", True),  # the named file, found in the contribution by name
    ("messages.xsd", INLINE, False),  # declared inside the WSDL
])
def test_a_wsdl_s_schemas_are_resolved(tmp_path: Path, location: str, types: str, xsd: bool) -> None:
    lib = shared(tmp_path / "shared")
    (lib / "arm.wsdl").write_text(TYPED_WSDL.format(location=location, types=types))
    if xsd:
        (lib / "messages.xsd").write_text(MESSAGES_XSD)
    path = app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>')
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("User").go() == "arm moved to home"


def test_a_wsdl_schema_that_cannot_be_found_is_named_with_the_wsdl(tmp_path: Path) -> None:
    lib = shared(tmp_path / "shared")
    wsdl = TYPED_WSDL.format(location="http://example.com/schemas/missing.xsd", types="")
    (lib / "arm.wsdl").write_text(wsdl)
    err = refused(app(tmp_path / "app", f'<import namespace="{SHARED_NS}"/>'), contributions=[lib])
    assert err.codes == ["ASM12021", "ASM12021"], str(err)  # the input part and the output part
    first = err.errors[0]
    assert first.path.endswith("arm.wsdl") and first.line == line_of(wsdl, 'name="where"')
    assert "part 'where' names element 'where' of namespace 'urn:messages'" in first.message
    assert "'http://example.com/schemas/missing.xsd') is not in the contributions" in first.message


REPOSITORY_COMPOSITES = sorted(p for top in ("composites", "tests/data") for p in (ROOT / top).rglob("*.composite")
                               if "build" not in p.parts)


@pytest.mark.parametrize("path", REPOSITORY_COMPOSITES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_composite_of_the_repository_validates(path: Path) -> None:
    assembly = assemble(str(path))  # offline, as `scart validate` does
    assert assembly.nodes or assembly.elements_of("bridge")  # components, or bridges that stand alone
    meta = path.parent / "META-INF" / "sca-contribution.xml"
    if meta.is_file() and "<deployable" in meta.read_text():
        assert assemble(str(path.parent)).nodes  # the folder itself, when it says what to deploy
