"""Contributions packed as ZIP archives (SCA Assembly 1.1 §12.1): given, located by an
import, or run as the root — unpacked only into a private temporary folder, under the
limits a property's @file has, and never past an entry that would escape."""

from __future__ import annotations

import stat
import zipfile
from pathlib import Path

import pytest

import scart
from scart import archive
from scart.assembly import assemble
from support.sca import SCA

NS = "urn:shared"

PARTS_PY = '''
class Arm:
    def move(self, where: str) -> str:
        return f"arm moved to {where}"
'''

PARTS = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="{NS}" name="Parts">
  <component name="Arm"><scart:implementation.python class="zipped_parts:Arm"/></component>
  <service name="Arm" promote="Arm"/>
</composite>
"""

APP = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:s="{NS}" targetNamespace="urn:app" name="App">
  <component name="Robot"><implementation.composite name="s:Parts"/></component>
</composite>
"""


def meta(*lines: str) -> str:
    return f'<contribution xmlns="{SCA}" xmlns:a="urn:app">{"".join(lines)}</contribution>'


def zipped(path: Path, entries: dict[str, str]) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        for name, text in entries.items():
            zf.writestr(name, text)
    return path


def shared_zip(path: Path) -> Path:
    return zipped(path, {"META-INF/sca-contribution.xml": meta(f'<export namespace="{NS}"/>'),
                         "parts/parts.composite": PARTS, "zipped_parts.py": PARTS_PY})


def app(folder: Path, *lines: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "META-INF").mkdir(exist_ok=True)
    (folder / "META-INF" / "sca-contribution.xml").write_text(meta(*lines))
    (folder / "app.composite").write_text(APP)
    return folder / "app.composite"


def test_a_zip_contribution_is_given_like_a_folder(tmp_path: Path) -> None:
    lib = shared_zip(tmp_path / "shared.zip")
    path = app(tmp_path / "app", f'<import namespace="{NS}"/>')
    with scart.Runtime.from_file(str(path), contributions=[lib]) as rt:
        assert rt.service("Robot").move("home") == "arm moved to home"  # its composite and its module


def test_an_import_locates_a_zip_contribution(tmp_path: Path) -> None:
    shared_zip(tmp_path / "shared.jar")
    path = app(tmp_path / "app", f'<import namespace="{NS}" location="../shared.jar"/>')
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("Robot").move("dock") == "arm moved to dock"


def test_a_zip_contribution_runs_its_deployable_and_problems_name_the_archive(tmp_path: Path) -> None:
    root = zipped(tmp_path / "robot.zip", {
        "META-INF/sca-contribution.xml": meta('<deployable composite="a:App"/>'),
        "app.composite": APP.replace(f'xmlns:s="{NS}"', 'xmlns:s="urn:app"'),
        "parts.composite": PARTS.replace(NS, "urn:app"), "zipped_parts.py": PARTS_PY})
    with scart.Runtime.from_file(str(root)) as rt:
        assert rt.service("Robot").move("x") == "arm moved to x"
    broken = zipped(tmp_path / "broken.zip", {
        "META-INF/sca-contribution.xml": meta('<deployable composite="a:App"/>'),
        "app.composite": APP.replace("s:Parts", "s:Nothing")})
    with pytest.raises(scart.ScdlError) as info:
        assemble(str(broken))
    assert info.value.errors[0].path == f"{broken}!/app.composite" and info.value.errors[0].line == 3


@pytest.mark.parametrize("name, why", [
    ("../escaped.py", "would land outside"),
    ("/abs/olute.py", "would land outside"),
    ("a\\..\\..\\b.py", "would land outside"),
    ("C:/windows.py", "would land outside"),
])
def test_an_entry_that_would_escape_refuses_the_archive(tmp_path: Path, name: str, why: str) -> None:
    lib = zipped(tmp_path / "evil.zip", {"META-INF/sca-contribution.xml": meta(f'<export namespace="{NS}"/>'),
                                          name: "print('pwned')"})
    path = app(tmp_path / "app", f'<import namespace="{NS}"/>')
    with pytest.raises(scart.ScdlError) as info:
        assemble(str(path), contributions=[lib])
    assert "SCART-X005" in info.value.codes and why in str(info.value)
    assert not (tmp_path / "escaped.py").exists() and not Path("/abs/olute.py").exists()


def test_a_link_entry_refuses_the_archive(tmp_path: Path) -> None:
    lib = tmp_path / "link.zip"
    with zipfile.ZipFile(lib, "w") as zf:
        info = zipfile.ZipInfo("parts.py")
        info.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(info, "/etc/passwd")
    with pytest.raises(archive.ArchiveError, match="is a link"):
        archive.unpack(lib)


@pytest.mark.parametrize("limit, value, why", [
    ("MAX_ENTRIES", 2, "entries bound"),
    ("MAX_ENTRY_BYTES", 100, "over the 100 bytes bound"),
    ("MAX_TOTAL_BYTES", 150, "together"),
    ("MAX_ARCHIVE_BYTES", 50, "bytes bound"),
])
def test_the_limits_of_an_archive(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, limit: str, value: int,
                                  why: str) -> None:
    lib = zipped(tmp_path / "big.zip", {"a.txt": "x" * 90, "b.txt": "y" * 90, "c.txt": "z" * 200})
    monkeypatch.setattr(archive, limit, value)
    with pytest.raises(archive.ArchiveError, match=why):
        archive.unpack(lib)


def test_an_archive_is_unpacked_into_a_private_folder_removed_with_it(tmp_path: Path) -> None:
    unpacked = archive.unpack(shared_zip(tmp_path / "shared.zip"))
    folder = Path(unpacked.name)
    assert (folder / "parts" / "parts.composite").is_file()
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    unpacked.cleanup()
    assert not folder.exists()


def test_a_file_that_is_not_an_archive_is_no_contribution(tmp_path: Path) -> None:
    (tmp_path / "notes.zip").write_text("not a zip")
    path = app(tmp_path / "app", f'<import namespace="{NS}"/>')
    with pytest.raises(scart.ScdlError) as info:
        assemble(str(path), contributions=[tmp_path / "notes.zip"])
    assert "no such folder or ZIP archive" in str(info.value)
