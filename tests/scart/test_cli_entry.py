"""The console script and ``python -m scart`` are installed and answer --help."""

import subprocess
import sys


def test_python_m_scart_help() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "scart", "--help"], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0
    assert "usage: scart" in out.stdout
