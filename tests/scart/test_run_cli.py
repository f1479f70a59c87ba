"""``scart run`` / ``validate`` / ``graph`` in real subprocesses."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest

from support import ROOT
from support.cli import finish, read_until, run, scart_cmd, start
from support.sca import composite, py, write

CALCULATOR = ROOT / "composites" / "calculator" / "calculator.composite"


def lifecycle_composite(tmp_path: Path, log: Path) -> Path:
    return write(tmp_path, {"life.composite": composite(f"""
        <component name="A">{py("Tracker")}<reference name="next" target="B"/>
          <property name="log_file">{log}</property></component>
        <component name="B">{py("Tracker")}<property name="log_file">{log}</property></component>
    """)})


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_run_stops_cleanly_on_signal(tmp_path: Path, sig: signal.Signals) -> None:
    log = tmp_path / "events.log"
    path = lifecycle_composite(tmp_path, log)
    proc = start("run", str(path))
    try:
        out = read_until(proc, "started")
        assert "component A" in out and "next -> B/Tracker" in out
        assert log.read_text(encoding="utf-8").splitlines() == ["init B", "init A"]
        proc.send_signal(sig)
    finally:
        rest, err = finish(proc)
    assert proc.returncode == 0, err
    assert "stopped" in err and rest == ""  # scart's own lines go to stderr, as ROS's logs do
    assert log.read_text(encoding="utf-8").splitlines() == ["init B", "init A", "destroy A", "destroy B"]


def test_run_refuses_a_bad_composite_before_starting(tmp_path: Path) -> None:
    log = tmp_path / "events.log"
    text = composite(f"""
        <component name="A">{py("Tracker")}<property name="log_file">{log}</property></component>
        <component name="S">{py("Single")}</component>
        <component name="N">{py("NeedsValue")}</component>
    """)
    path = write(tmp_path, {"bad.composite": text})
    out = run("run", str(path))
    assert out.returncode == 2
    assert f"{path}:5: " in out.stderr and "ASM50040" in out.stderr and "ASM40011" in out.stderr
    assert not log.exists()


def test_run_with_set_override(tmp_path: Path) -> None:
    log = tmp_path / "events.log"
    other = tmp_path / "other.log"
    path = lifecycle_composite(tmp_path, log)
    proc = start("run", str(path), "--set", f"B.log_file={other}")
    try:
        read_until(proc, "started")
        proc.send_signal(signal.SIGINT)
    finally:
        finish(proc)
    assert proc.returncode == 0
    assert other.read_text(encoding="utf-8").splitlines() == ["init B", "destroy B"]


def test_validate_good_and_bad(tmp_path: Path) -> None:
    good = run("validate", str(CALCULATOR))
    assert good.returncode == 0 and "ok (5 component(s))" in good.stdout
    bad = write(tmp_path, {"bad.composite": composite(f"<component name='S'>{py('Single')}</component>")})
    out = run("validate", str(CALCULATOR), str(bad))
    assert out.returncode == 2
    assert f"{bad}:3: component 'S': reference 'one' (1..1) has 0 targets [ASM50040]" in out.stderr
    assert "ok" in out.stdout


def test_validate_with_set(tmp_path: Path) -> None:
    out = run("validate", str(CALCULATOR), "--set", "CalculatorServiceComponent.precision=abc")
    assert out.returncode == 2 and "ASM50027" in out.stderr
    assert run("validate", str(CALCULATOR), "--set", "CalculatorServiceComponent.precision=2").returncode == 0
    bad = run("validate", str(CALCULATOR), "--set", "nodot")
    assert bad.returncode == 2 and "COMPONENT.PROPERTY=VALUE" in bad.stderr


def test_graph_is_dot() -> None:
    out = run("graph", str(CALCULATOR))
    assert out.returncode == 0
    dot = out.stdout
    assert dot.startswith('digraph "Calculator" {') and dot.rstrip().endswith("}")
    assert '"CalculatorServiceComponent" -> "AddServiceComponent" [label="add_service -> AddService"];' in dot
    assert '"service:CalculatorService" -> "CalculatorServiceComponent"' in dot


def test_graph_shows_nested_composites_as_clusters(tmp_path: Path) -> None:
    inner = composite(f"""
        <service name="Greeter" promote="G"/>
        <component name="G">{py("GreeterImpl")}</component>
    """, name="Inner")
    outer = composite(f"""
        <service name="Front" promote="M/Greeter"/>
        <component name="M"><implementation.composite name="t:Inner"/></component>
        <component name="S">{py("Single")}<reference name="one" target="M"/></component>
    """, name="Outer")
    path = write(tmp_path, {"outer.composite": outer, "inner.composite": inner})
    out = run("graph", str(path))
    assert out.returncode == 0, out.stderr
    assert 'subgraph "cluster_M" {' in out.stdout
    assert '"M/G" [label="G\\n[Greeter]"];' in out.stdout
    assert '"S" -> "M/G" [label="one -> Greeter"];' in out.stdout
    assert '"service:Front" -> "M/G"' in out.stdout


def test_stdout_closed_early_exits_quietly() -> None:
    """``scart ... | head``: the reader goes away; no BrokenPipeError traceback."""
    files = [str(ROOT / "composites" / "youbot" / f)
             for f in ("youbot.composite", "robot.composite", "workstation.composite")] * 200
    proc = subprocess.Popen(scart_cmd("validate", *files), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # before scart writes anything: every write meets a closed pipe
    try:
        err = proc.stderr.read().decode()
        code = proc.wait(60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        proc.stderr.close()
    assert "Traceback" not in err and "BrokenPipeError" not in err, err
    assert code in (0, 141)
