"""SCA services from the command line: ``scart run`` serves every component service on a
loopback endpoint, registers it with the name service and says how to call one; ``scart
services`` lists them and ``scart call`` calls them by name (JSON in and out), ``--at``
names an endpoint without the name service; the server's tokens and roles apply."""

from __future__ import annotations

import json
import os
import re
import secrets
import subprocess
import sys
from pathlib import Path

from support import ROOT, free_port
from support.cli import finish, read_until, run, start

CALCULATOR = ROOT / "composites" / "calculator" / "calculator.composite"
FIRST = ROOT / "composites" / "first" / "first.composite"


def started(*extra: str, composite: Path = CALCULATOR):  # noqa: ANN201 - (process, services address)
    """``scart run`` on a name service of its own (never the default port: another run may hold it)."""
    if "--ns" not in extra:
        extra = (*extra, "--ns", f"127.0.0.1:{free_port()}")
    proc = start("run", str(composite), *extra)
    out = read_until(proc, "started")
    found = re.search(r"SCA services at (\S+) \(list them: scart services (--ns \S+|--at \S+); call one: scart call "
                      r"\2 (\S+\.\w+) ARGS\.\.\.\)", out)
    assert found, out
    return proc, found[1]


def test_the_calculator_is_listed_and_called_by_name_through_the_name_service() -> None:
    ns = f"127.0.0.1:{free_port()}"
    proc, address = started("--ns", ns)
    try:
        listed = json.loads(run("services", "--ns", ns, "--json").stdout)
        assert {s["at"] for s in listed} == {address}
        assert "CalculatorService" in {n for s in listed for n in s["names"]}
        assert json.loads(run("call", "CalculatorService.add", "3", "2", "--ns", ns).stdout) == 5.0
        assert json.loads(run("call", "CalculatorServiceComponent/CalculatorService.multiply", "3", "4",
                              "--ns", ns).stdout) == 12.0
        text = run("services", "--ns", ns).stdout
        assert "AddServiceComponent/AddService" in text and f"at {address}" in text
        unknown = run("call", "Nobody.add", "1", "2", "--ns", ns)
        assert unknown.returncode == 1 and "no component or SCA service named 'Nobody'" in unknown.stderr
        assert "CalculatorServiceComponent/CalculatorService" in unknown.stderr
        # --at still overrides: the name service it names answers nothing
        nowhere = f"127.0.0.1:{free_port()}"
        assert json.loads(run("call", "--at", address, "CalculatorService.add", "1", "1", "--ns", nowhere).stdout) == 2.0
        gone = run("services", "--ns", nowhere, "--timeout", "1")
        assert gone.returncode == 1 and f"no name service answers at {nowhere}" in gone.stderr
    finally:
        proc.terminate()
        finish(proc)
    assert proc.returncode == 0


def test_a_composite_with_tasks_registers_its_services_beside_them() -> None:
    """``scart call Reporter.report``: an SCA component of a composite whose tasks the same
    name service lists; ``scart ls`` lists the tasks only, ``scart call`` reaches both."""
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = started("--ns", ns, composite=FIRST)
    try:
        assert json.loads(run("call", "Reporter.report", "--ns", ns).stdout).startswith("sum of ticks: ")
        assert {r["name"] for r in json.loads(run("ls", "--ns", ns, "--json", "--sample", "0").stdout)} == \
            {"ticker", "summer"}
        assert isinstance(json.loads(run("call", "summer.total", "--ns", ns).stdout), int)  # a task's operation
    finally:
        proc.terminate()
        finish(proc)
    assert proc.returncode == 0


def test_the_calculator_is_listed_and_called_from_the_command_line() -> None:
    proc, address = started()
    try:
        services = json.loads(run("services", "--at", address, "--json").stdout)
        names = {s["names"][0]: s for s in services}
        assert "CalculatorService" in names["CalculatorServiceComponent/CalculatorService"]["names"]
        assert [o["name"] for o in names["AddServiceComponent/AddService"]["operations"]] == ["add"]
        assert json.loads(run("call", "--at", address, "CalculatorService.add", "3", "2").stdout) == 5.0
        assert json.loads(run("call", "--at", address, "CalculatorServiceComponent/CalculatorService.multiply",
                              "3", "4", "--json").stdout) == 12.0
        fault = run("call", "--at", address, "DivideServiceComponent/DivideService.divide", "1", "0")
        assert fault.returncode == 1 and "raised ZeroDivisionError" in fault.stderr
        unknown = run("call", "--at", address, "Nobody.add", "1", "2")
        assert unknown.returncode == 1 and "no service 'Nobody'" in unknown.stderr and "CalculatorService" in unknown.stderr
    finally:
        proc.terminate()
        finish(proc)
    assert proc.returncode == 0


def test_the_services_endpoint_takes_the_servers_tokens_and_roles(tmp_path: Path) -> None:
    tokens = {role: secrets.token_hex(16) for role in ("read", "operate")}
    auth = tmp_path / "tokens.auth"
    auth.write_text("".join(f"{role} {token}\n" for role, token in tokens.items()))
    auth.chmod(0o600)
    proc, address = started("--auth-file", str(auth), "--ns", "127.0.0.1:0")
    try:
        anonymous = run("services", "--at", address)
        assert anonymous.returncode == 1 and "token" in anonymous.stderr.lower()
        reader = {"SCART_TOKEN": tokens["read"]}
        listed = run_env(reader, "services", "--at", address, "--json")
        assert listed.returncode == 0 and json.loads(listed.stdout)
        refused = run_env(reader, "call", "--at", address, "CalculatorService.add", "1", "2")
        assert refused.returncode == 1 and "operate" in refused.stderr
        done = run_env({"SCART_TOKEN": tokens["operate"]}, "call", "--at", address, "CalculatorService.add", "1", "2")
        assert done.returncode == 0 and json.loads(done.stdout) == 3.0
    finally:
        proc.terminate()
        finish(proc)


def test_services_can_be_turned_off() -> None:
    proc = start("run", str(CALCULATOR), "--services", "off")
    try:
        assert "SCA services at" not in read_until(proc, "started")
    finally:
        proc.terminate()
        finish(proc)


def run_env(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60,
                          env={**os.environ, **env})
