"""The README's code blocks work as printed: each Python block runs (the remote-client one
against a served youBot driver), each ``scart ...`` command line of the shell blocks parses
with scart's own parser, and each XML block is well-formed."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys

import pytest
from lxml import etree

from support import ROOT
from support.youbot import env, start_serving

README = (ROOT / "README.md").read_text(encoding="utf-8")
BLOCKS = [(m["lang"], m["body"], README.count("\n", 0, m.start()) + 1)
          for m in re.finditer(r"^```(?P<lang>\w*)\n(?P<body>.*?)^```", README, re.S | re.M)]
PYTHON = [(body, line) for lang, body, line in BLOCKS if lang == "python"]
SHELL = [(body, line) for lang, body, line in BLOCKS if lang in ("sh", "bash")]
XML = [(body, line) for lang, body, line in BLOCKS if lang == "xml"]
DEFAULT_NS = "127.0.0.1:7850"


def run_python(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT,
                          env=env())


LOCAL_PYTHON = [b for b in PYTHON if DEFAULT_NS not in b[0]]


@pytest.mark.parametrize("body, line", LOCAL_PYTHON, ids=[f"README.md:{line}" for _, line in LOCAL_PYTHON])
def test_a_python_block_runs(body: str, line: int) -> None:
    done = run_python(body)
    assert done.returncode == 0, f"README.md:{line}: {done.stderr}"


def test_the_remote_client_block_runs_against_a_served_driver() -> None:
    blocks = [(body, line) for body, line in PYTHON if DEFAULT_NS in body]
    assert blocks, "the README has no remote-client block"
    demo = start_serving("robot.composite")
    try:
        for body, line in blocks:
            done = run_python(body.replace(DEFAULT_NS, demo.ns))
            assert done.returncode == 0, f"README.md:{line}: {done.stderr}"
            assert "RUNNING" in done.stdout and "jointStatus" in done.stdout, done.stdout
    finally:
        assert demo.stop() == 0


def test_every_scart_command_line_parses() -> None:
    from scart.cli import build_parser

    parser = build_parser()
    seen = 0
    for body, line in SHELL:
        for offset, text in enumerate(body.splitlines()):
            text = re.split(r"\s[|>;]", text.split(" #", 1)[0])[0].strip().rstrip("&").strip()  # the scart part
            if not text.startswith("scart "):
                continue
            seen += 1
            try:
                parser.parse_args(shlex.split(text)[1:])
            except SystemExit:
                pytest.fail(f"README.md:{line + 1 + offset}: {text!r} does not parse")
    assert seen >= 10


@pytest.mark.parametrize("body, line", XML, ids=[f"README.md:{line}" for _, line in XML])
def test_an_xml_block_is_well_formed(body: str, line: int) -> None:
    wrapped = ('<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0">'
               f"{body}</composite>")
    try:
        etree.fromstring(wrapped.encode())
    except etree.XMLSyntaxError as exc:
        pytest.fail(f"README.md:{line}: {exc}")


def test_graph_says_that_drawing_needs_graphviz() -> None:
    """``scart graph ... | dot`` needs Graphviz: every README line piping into dot names it,
    and so does ``scart graph --help``."""
    piped = [line for line in README.splitlines() if "scart graph" in line and "| dot" in line]
    assert piped and all("Graphviz" in line for line in piped), piped
    helped = subprocess.run([sys.executable, "-m", "scart", "graph", "--help"], capture_output=True, text=True,
                            timeout=60)
    assert "Graphviz" in helped.stdout and "apt-get install graphviz" in " ".join(helped.stdout.split())


def test_the_security_section_states_the_buffer_limit_that_holds() -> None:
    """The limit a remote buffer meets is ``MAX_BUFFER``, in the security section as in the
    transports' (it once said 10 000 there while 100 000 held)."""
    from dataflow.policy import MAX_BUFFER

    security = README[README.index("## Security"):README.index("## Crossing processes")]
    said = re.search(r"buffer is at most `MAX_BUFFER` \(([\d ]+)\) samples", security)
    assert said is not None, "the security section names the buffer limit"
    assert int(said[1].replace(" ", "")) == MAX_BUFFER
    assert "10 000 samples" not in security
