"""``scart validate`` and ``scart run --dry-run`` agree on every composite of the repository:
the same exit code and the same problems and warnings (``run --dry-run`` loads exactly as
``run`` does — its settings, ``--set``, ``--remap`` — and starts nothing). Real subprocesses."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from support import ROOT
from support.cli import run

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]

PROBLEM = re.compile(r"^\S.*?: .*\[(?:ASM\d+|SCART-[A-Z0-9-]+)\]$")
COMPOSITES = sorted(p for top in ("composites", "tests/data") for p in (ROOT / top).rglob("*.composite")
                    if "build" not in p.parts)


def said(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if PROBLEM.match(line)]


@pytest.mark.parametrize("path", COMPOSITES, ids=lambda p: str(p.relative_to(ROOT)))
def test_validate_and_run_dry_run_agree(path: Path) -> None:
    checked = run("validate", str(path))
    dry = run("run", "--dry-run", str(path))
    assert checked.returncode == dry.returncode == 0, checked.stderr + dry.stderr
    assert said(checked.stderr) == said(dry.stderr)
    assert "nothing started" in dry.stderr and "scart: started" not in dry.stderr  # scart's own lines: stderr


def test_a_dry_run_refuses_what_validate_refuses(tmp_path: Path) -> None:
    broken = tmp_path / "first.composite"
    text = (ROOT / "composites" / "first" / "first.composite").read_text(encoding="utf-8")
    broken.write_text(text.replace('class="first:Ticker" period="0.1"', 'class="first:Ticker" period="0"'),
                      encoding="utf-8")
    for extra in ((), ("--contribution", str(ROOT / "composites" / "first"))):
        checked = run("validate", str(broken), *extra)
        dry = run("run", "--dry-run", str(broken), *extra)
        assert checked.returncode == dry.returncode == 2
        assert said(checked.stderr) == said(dry.stderr) != []
