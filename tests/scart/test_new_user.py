"""What a new user met with the SCA verbs and took for success, or could not do (issue:
"every promise kept", section 3), each through ``scart`` as typed: a call by named
arguments, a missing argument said in one line (no traceback in ``scart run``'s
terminal), the SCA services of a ``--remap __ns=`` run found under that namespace, a
busy port said in one line with what to do (not gRPC's raw ``add_port.cc`` line)."""

from __future__ import annotations

import json
import re
import shutil
import socket
from pathlib import Path

import pytest

from support import ROOT, free_port
from support.cli import finish, read_until, run, start

CALCULATOR = ROOT / "composites" / "calculator" / "calculator.composite"
FIRST = ROOT / "composites" / "first" / "first.composite"

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


def test_call_by_name_and_a_missing_argument_in_one_line() -> None:
    ns = f"127.0.0.1:{free_port()}"
    proc = start("run", str(CALCULATOR), "--ns", ns)
    try:
        read_until(proc, "started")
        named = run("call", "CalculatorService.add", "{n1: 3, n2: 2}", "--ns", ns)
        assert named.returncode == 0 and json.loads(named.stdout) == 5.0, named
        missing = run("call", "CalculatorService.add", "3", "--ns", ns)
        assert missing.returncode == 1 and missing.stdout == "", missing
        assert missing.stderr.count("\n") == 1, missing.stderr
        assert "CalculatorService.add(n1, n2): missing a required argument: 'n2'" in missing.stderr
        assert "in order, or as one mapping by name" in missing.stderr
    finally:
        proc.terminate()
        _, err = finish(proc)
    assert proc.returncode == 0 and "Traceback" not in err, err


def test_the_services_of_a_run_under_a_namespace_are_found_under_it() -> None:
    ns = f"127.0.0.1:{free_port()}"
    plain = start("run", str(CALCULATOR), "--ns", ns)
    right = None
    try:
        read_until(plain, "started")
        right = start("run", str(CALCULATOR), "--ns", ns, "--remap", "__ns=right")
        said = read_until(right, "started")
        assert re.search(r"call one: scart call --ns \S+ right/CalculatorService\.add", said), said
        assert json.loads(run("call", "right/CalculatorService.add", "1", "2", "--ns", ns).stdout) == 3.0
        assert json.loads(run("call", "CalculatorService.add", "1", "1", "--ns", ns).stdout) == 2.0  # not ambiguous
        listed = run("services", "--ns", ns).stdout
        assert "right/CalculatorServiceComponent/CalculatorService" in listed, listed
    finally:
        for proc in (right, plain):
            if proc is not None:
                proc.terminate()
                finish(proc)


def test_a_busy_port_is_said_in_one_line_without_grpc_s_own() -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        taken = f"127.0.0.1:{busy.getsockname()[1]}"
        for args in (["run", str(FIRST), "--ns", taken],
                     ["run", str(CALCULATOR), "--services", taken, "--ns", f"127.0.0.1:{free_port()}"]):
            done = run(*args)
            assert done.returncode == 1, done
            assert "add_port.cc" not in done.stderr and "E1" not in done.stderr, done.stderr
            assert f"cannot listen on {taken}: the port is in use" in done.stderr, done.stderr
            assert "choose another port" in done.stderr


def test_a_typo_in_a_connect_end_is_an_error_and_an_external_task_is_declared(tmp_path: Path) -> None:
    """``to="filtr.inp"`` was a warning: validate exited 0 and run waited forever for
    ``filtr``. A task served by another process is declared ``<scart:external>``, and
    ``run`` says what it waits for."""
    folder = tmp_path / "first"
    shutil.copytree(ROOT / "composites" / "first", folder, ignore=shutil.ignore_patterns("__pycache__"))
    original = (folder / "first.composite").read_text(encoding="utf-8")
    typo = folder / "typo.composite"
    typo.write_text(original.replace('to="summer.inp"', 'to="sumer.inp"'), encoding="utf-8")
    checked = run("validate", str(typo))
    assert checked.returncode == 2, checked
    assert "'sumer' is no task of this composite (did you mean 'summer'?)" in checked.stderr
    assert '<scart:external task="sumer"/>' in checked.stderr
    declared = folder / "declared.composite"
    declared.write_text(original.replace('to="summer.inp"', 'to="far.inp"').replace(
        "<scart:connect ", '<scart:external task="far"/>\n    <scart:connect '), encoding="utf-8")
    assert run("validate", str(declared)).returncode == 0
    proc = start("run", str(declared), "--ns", f"127.0.0.1:{free_port()}")
    try:
        said = read_until(proc, "linked when it appears)")
    finally:
        proc.terminate()
        finish(proc)
    assert re.search(r"waiting for far in name service \S+ \(declared external: linked when it appears\)", said), said


def test_an_element_typo_gets_the_near_element(tmp_path: Path) -> None:
    """``<scart:conect>`` was told 'did you mean component', ``<scart:brige>`` nothing."""
    path = tmp_path / "typo.composite"
    path.write_text('<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0" '
                    'targetNamespace="urn:t" name="T">\n  <scart:conect from="a.out" to="b.in"/>\n'
                    '  <scart:brige name="x"/>\n</composite>\n', encoding="utf-8")
    checked = run("validate", str(path))
    assert checked.returncode == 2
    assert f"{path}:2: unknown element <conect> in 'urn:scart:1.0' inside <composite> (did you mean 'connect'?)" \
        in checked.stderr
    assert f"{path}:3: unknown element <brige> in 'urn:scart:1.0' inside <composite> (did you mean 'bridge'?)" \
        in checked.stderr


def test_run_chooses_where_its_data_flow_server_listens() -> None:
    """``deploy`` had ``--listen``; ``run`` could not choose its data-flow address."""
    ns, listen = f"127.0.0.1:{free_port()}", f"127.0.0.1:{free_port()}"
    first = start("run", str(FIRST), "--ns", ns)
    second = None
    try:
        read_until(first, "started")
        second = start("run", str(FIRST), "--ns", ns, "--listen", listen, "--remap", "__ns=b")
        said = read_until(second, "started")
        assert f"dataflow server at {listen}" in said and f"name service at {ns} (joined)" in said, said
        rows = {r["name"]: r for r in json.loads(run("ls", "--ns", ns, "--json").stdout)}
        assert rows["b/ticker"]["deployer"] == listen and rows["ticker"]["deployer"] == ns
    finally:
        for proc in (second, first):
            if proc is not None:
                proc.terminate()
                finish(proc)
