"""binding.grpc between two real ``scart run`` processes: the calculator split in two, and
callbacks during a synchronous call and after a one-way call; both stopped with SIGINT."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from support import ROOT, DATA as TEST_DATA, free_port, wait_until
from support.grpc_binding import composite, gpy, gwrite
from support.cli import finish, read_until

DATA = TEST_DATA / "grpc_calculator"
CALCULATOR = ROOT / "composites" / "calculator"


def _env(*paths: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([*(str(p) for p in paths), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


@pytest.fixture
def processes() -> Iterator[list[subprocess.Popen[bytes]]]:
    """Started ``scart run`` processes; killed in teardown if a test left one running."""
    procs: list[subprocess.Popen[bytes]] = []
    yield procs
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=30)


def _scart_run(procs: list[subprocess.Popen[bytes]], args: list[str], env: dict[str, str]) -> subprocess.Popen[bytes]:
    proc = subprocess.Popen([sys.executable, "-m", "scart", "run", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, bufsize=0, env=env)
    procs.append(proc)
    return proc


def _stop(proc: subprocess.Popen[bytes]) -> str:
    proc.send_signal(signal.SIGINT)
    out, err = finish(proc)
    assert proc.returncode == 0, f"exit {proc.returncode}\n{out}\n{err}"
    return out + err  # scart's own lines are on stderr


def _with_port(src: Path, dest: Path, port: int) -> Path:
    dest.write_text(re.sub(r"127\.0\.0\.1:50751", f"127.0.0.1:{port}", src.read_text(encoding="utf-8")), encoding="utf-8")
    return dest


def test_calculator_split_across_two_processes(tmp_path: Path, processes: list[subprocess.Popen[bytes]]) -> None:
    port = free_port()
    provider_file = _with_port(DATA / "provider.composite", tmp_path / "provider.composite", port)
    client_dir = tmp_path / "client"
    client_dir.mkdir()
    (client_dir / "calc_client.py").write_text((DATA / "calc_client.py").read_text(encoding="utf-8"), encoding="utf-8")
    client_file = _with_port(DATA / "client.composite", client_dir / "client.composite", port)
    results = tmp_path / "results.jsonl"

    provider = _scart_run(processes, [str(provider_file)], _env(CALCULATOR))
    banner = read_until(provider, "Ctrl-C")
    assert f"binding CalculatorServiceComponent/CalculatorService (binding.grpc) at 127.0.0.1:{port}" in banner
    client = _scart_run(processes, [str(client_file), "--set", f"CalculatorClient.out={results}"], _env())
    read_until(client, "Ctrl-C")
    lines = [json.loads(line) for line in wait_until(lambda: results.exists() and results.read_text(), timeout=30).splitlines()]
    assert [(d["op"], d.get("result")) for d in lines[:4]] == [
        ("add", 5.0), ("subtract", 1.0), ("multiply", 6.0), ("divide", 1.5)]
    assert lines[4] == {"op": "divide by zero", "error": "RemoteError", "remote_type": "ZeroDivisionError"}
    _stop(client)
    assert "scart: stopped" in _stop(provider)


def test_callbacks_and_oneway_across_processes(tmp_path: Path, processes: list[subprocess.Popen[bytes]]) -> None:
    port = free_port()
    out = tmp_path / "seen.json"
    provider_file = gwrite(tmp_path / "p", {"p.composite": composite(
        f'<component name="D">{gpy("DeskImpl")}<service name="Desk">'
        f'<scart:binding.grpc address="127.0.0.1:{port}"/></service></component>')})
    client_file = gwrite(tmp_path / "c", {"c.composite": composite(
        f'<component name="K">{gpy("AskerReport")}<property name="out">{out}</property>'
        f'<reference name="desk"><scart:binding.grpc address="127.0.0.1:{port}" service="D/Desk"/></reference>'
        '</component>')})
    provider = _scart_run(processes, [str(provider_file)], _env())
    read_until(provider, "Ctrl-C")
    client = _scart_run(processes, [str(client_file)], _env())
    read_until(client, "Ctrl-C")
    seen = json.loads(wait_until(lambda: out.exists() and out.read_text(), timeout=30))
    assert seen == {"sync": "go: True False", "questions": ["go?", "go??", "q?"], "told": ["decided", "later q?"]}
    _stop(client)
    _stop(provider)


def test_provider_killed_and_restarted_is_reached_again(tmp_path: Path, processes: list[subprocess.Popen[bytes]]) -> None:
    import scart
    from scart import ServiceUnavailableError

    port = free_port()
    provider_file = _with_port(DATA / "provider.composite", tmp_path / "provider.composite", port)
    client_dir = tmp_path / "client"
    client_dir.mkdir()
    (client_dir / "calc_client.py").write_text((DATA / "calc_client.py").read_text(encoding="utf-8"), encoding="utf-8")
    client_text = _with_port(DATA / "client.composite", client_dir / "client.composite", port).read_text(encoding="utf-8")
    # in this process: a plain component holding the reference (no calls at @init)
    (client_dir / "holder.py").write_text(
        "import scart\nfrom calc_client import CalculatorService\n\n"
        "class Holder:\n    calculator: CalculatorService = scart.reference()\n", encoding="utf-8")
    client_file = client_dir / "holder.composite"
    client_file.write_text(client_text.replace("calc_client:CalculatorClient", "holder:Holder")
                           .replace('timeout="10"', 'timeout="2"')
                           .replace('<property name="out">results.jsonl</property>', ""), encoding="utf-8")
    with scart.Runtime.from_file(str(client_file)) as rt:
        calc = rt._managers["CalculatorClient"].instance().calculator
        first = _scart_run(processes, [str(provider_file)], _env(CALCULATOR))
        read_until(first, "Ctrl-C")
        assert calc.add(1, 2) == 3.0
        first.kill()
        first.communicate(timeout=30)
        with pytest.raises(ServiceUnavailableError, match=f"127.0.0.1:{port}"):
            calc.add(1, 2)
        second = _scart_run(processes, [str(provider_file)], _env(CALCULATOR))
        read_until(second, "Ctrl-C")
        assert calc.multiply(2, 4) == 8.0
        _stop(second)
