"""A second local user for the security probes: "another user on the same host" is a
real account, not a second process of ours. As root, :func:`second_user` creates it
(``useradd``, once; a system account without a home or a login shell); otherwise the test
is skipped, saying why. :func:`run_as` runs a standard-library Python program as that user
(its source is passed on the command line, so the user needs no access to the checkout).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

USER = "scart-probe"


def second_user() -> str:
    """The name of a local user other than the one running the tests (created if need be)."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        pytest.skip("needs a second local user: run the tests as root (they create one with useradd)")
    if subprocess.run(["id", "-u", USER], capture_output=True).returncode != 0:
        useradd = shutil.which("useradd") or "/usr/sbin/useradd"
        made = subprocess.run([useradd, "--system", "--no-create-home", "--shell", "/usr/sbin/nologin", USER],
                              capture_output=True, text=True, timeout=30)
        if made.returncode not in (0, 9):  # 9: made meanwhile by a parallel run
            pytest.skip(f"useradd {USER} failed: {made.stderr.strip()}")
    if _python_for(USER) is None:
        pytest.skip(f"no Python interpreter that user {USER} may run")
    return USER


def _python_for(user: str) -> str | None:
    """A Python 3 interpreter ``user`` can run (the system's: a virtualenv may sit in a home
    the user cannot enter)."""
    candidates = [str(Path(sys.base_prefix) / "bin" / "python3"), "/usr/bin/python3", shutil.which("python3") or ""]
    for candidate in dict.fromkeys(c for c in candidates if c):
        try:
            probe = subprocess.run([candidate, "-c", "pass"], user=user, capture_output=True, cwd="/", timeout=30,
                                   env={"PATH": "/usr/bin:/bin"})
        except OSError:  # that user may not run it (a home it cannot enter)
            continue
        if probe.returncode == 0:
            return candidate
    return None


def run_as(user: str, source: str, *args: str, stdin: str = "",
           timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    """Run the Python program ``source`` (standard library only) as ``user`` with ``args``
    and ``stdin``."""
    python = _python_for(user)
    assert python is not None
    return subprocess.run([python, "-c", source, *args], user=user, capture_output=True, text=True, cwd="/",
                          input=stdin, timeout=timeout, env={"PATH": "/usr/bin:/bin", "LANG": "C.UTF-8"})
