"""Every statement code scart reports is traceable: listed in the README's conformance
section, and every statement listed there is a code scart reports."""

from __future__ import annotations

import re

from scart import errors
from support import ROOT


def _expand(text: str) -> set[str]:
    codes: set[str] = set()
    for a, b in re.findall(r"ASM(\d{5})(?:–(\d{5}))?", text):
        codes |= {f"ASM{n}" for n in range(int(a), int(b or a) + 1)}
    return codes


def test_every_reported_statement_is_in_the_readme_table() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("## SCA Assembly 1.1 conformance", 1)[1].split("\n## ", 1)[0]
    table = "\n".join(line for line in section.splitlines() if line.startswith("| ASM"))
    listed = _expand(table)
    reported = {v for v in vars(errors).values() if isinstance(v, str) and re.fullmatch(r"ASM\d{5}", v)}
    assert reported <= listed, f"codes reported but not in the README table: {sorted(reported - listed)}"
    ranges_only = listed - reported  # a range may span statements scart has no code for: they must not be claimed
    claimed = {c for c in ranges_only if re.search(rf"\b{c}\b", table)}
    assert not claimed, f"statements listed by name but never reported: {sorted(claimed)}"
