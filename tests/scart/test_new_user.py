"""What a new user met with the SCA verbs and took for success, or could not do (issue:
"every promise kept", section 3), each through ``scart`` as typed: a call by named
arguments, a missing argument said in one line (no traceback in ``scart run``'s
terminal), the SCA services of a ``--remap __ns=`` run found under that namespace, a
busy port said in one line with what to do (not gRPC's raw ``add_port.cc`` line)."""

from __future__ import annotations

import json
import re
import socket

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
