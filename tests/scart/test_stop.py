"""Stopping a runtime: one-way calls still running or queued when it stops (bounded by the
drain deadline, logged, a second signal exits at once), backpressure of the one-way
queue, ``stop()`` from a worker, and proxies that refuse calls afterwards."""

from __future__ import annotations

import importlib
import logging
import signal
import threading
import time
from pathlib import Path

import pytest

import scart
from support import wait_until
from support.cli import finish, read_until, start
from support.sca import composite, py, write

BLOCKING = '''
from __future__ import annotations

import threading
from typing import Protocol

import scart

RELEASE = threading.Event()
STARTED = threading.Event()


@scart.interface
class Blocking(Protocol):
    @scart.oneway
    def block(self, tag: str) -> None: ...


@scart.component(services=[Blocking])
class Blocker:
    log_file: str = scart.prop(default="")

    def block(self, tag: str) -> None:
        STARTED.set()
        if self.log_file:
            with open(self.log_file, "a", encoding="utf-8") as fh:
                fh.write(f"blocking {tag}\\n")
        RELEASE.wait(None if self.log_file else 30)

    @scart.destroy
    def close(self) -> None:
        if self.log_file:
            with open(self.log_file, "a", encoding="utf-8") as fh:
                fh.write("destroy blocker\\n")


class Kicker:
    target: Blocking = scart.reference()

    @scart.init
    def start(self) -> None:
        self.target.block("init")
'''


def blocking_composite(tmp_path: Path, log: Path | None = None) -> Path:
    (tmp_path / "blocking.py").write_text(BLOCKING, encoding="utf-8")
    prop = f'<property name="log_file">{log}</property>' if log else ""
    return write(tmp_path, {"b.composite": composite(f"""
        <component name="B"><scart:implementation.python class="blocking:Blocker"/>{prop}</component>
        <component name="K"><scart:implementation.python class="blocking:Kicker"/>
          <reference name="target" target="B"/></component>
    """)})


def blocking_module():
    return importlib.import_module("blocking")


# --- 1. stop with a blocked one-way call ---------------------------------------------------

def test_run_stops_within_stop_timeout_when_a_oneway_call_is_blocked(tmp_path: Path) -> None:
    log = tmp_path / "events.log"
    path = blocking_composite(tmp_path, log)
    proc = start("run", str(path), "--stop-timeout", "0.5")
    try:
        read_until(proc, "started")
        wait_until(lambda: log.exists() and "blocking init" in log.read_text(), message="one-way call not running")
        proc.send_signal(signal.SIGTERM)
        out, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "still running" in err and "B/Blocking.block" in err
    assert "destroy blocker" in log.read_text()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_second_signal_while_stopping_exits_at_once(tmp_path: Path, sig: signal.Signals) -> None:
    log = tmp_path / "events.log"
    path = blocking_composite(tmp_path, log)
    proc = start("run", str(path), "--stop-timeout", "60")
    try:
        read_until(proc, "started")
        wait_until(lambda: log.exists() and "blocking init" in log.read_text(), message="one-way call not running")
        proc.send_signal(signal.SIGTERM)
        read_until(proc, "stopping")
        proc.send_signal(sig)
        out, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + sig, err
    assert "exiting at once" in err


def test_stop_drains_with_a_deadline_and_logs_stuck_operations(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path = blocking_composite(tmp_path)
    rt = scart.Runtime.from_file(str(path), drain_timeout=0.2)
    mod = blocking_module()
    mod.RELEASE.clear()
    mod.STARTED.clear()
    try:
        rt.start()
        assert mod.STARTED.wait(10)
        began = time.monotonic()
        with caplog.at_level(logging.WARNING, logger="scart.runtime"):
            rt.stop()
        assert time.monotonic() - began < 5
        assert "B/Blocking.block" in caplog.text and "still running" in caplog.text
    finally:
        mod.RELEASE.set()
    rt._pool.join(10)


def test_oneway_queue_is_bounded(tmp_path: Path) -> None:
    path = blocking_composite(tmp_path)
    rt = scart.Runtime.from_file(str(path), max_workers=1, max_pending=3, drain_timeout=5)
    mod = blocking_module()
    mod.RELEASE.clear()
    mod.STARTED.clear()
    try:
        with rt:
            assert mod.STARTED.wait(10)  # the only worker is blocked by K's init call
            proxy = rt.service("B")
            for i in range(3):
                proxy.block(str(i))
            with pytest.raises(scart.ScartError, match="backpressure"):
                proxy.block("too many")
            assert rt.oneway_rejected == 1
            mod.RELEASE.set()
    finally:
        mod.RELEASE.set()
    rt._pool.join(10)


def test_stop_from_a_worker_waits_for_other_oneway_calls_before_destroy(tmp_path: Path) -> None:
    log = tmp_path / "events.log"
    path = blocking_composite(tmp_path, log)
    rt = scart.Runtime.from_file(str(path), drain_timeout=10)
    mod = blocking_module()
    mod.RELEASE.clear()
    try:
        rt.start()
        wait_until(lambda: log.exists() and "blocking init" in log.read_text())
        done = threading.Event()
        rt.submit(lambda: (rt.stop(), done.set()))
        wait_until(lambda: rt.state is scart.RuntimeState.STOPPED)
        assert "destroy blocker" not in log.read_text()  # B.block still runs on another worker
        with open(log, "a", encoding="utf-8") as fh:
            fh.write("released\n")
        mod.RELEASE.set()
        assert done.wait(10)
        assert log.read_text().splitlines()[-2:] == ["released", "destroy blocker"]
    finally:
        mod.RELEASE.set()
    rt._pool.join(10)


# --- 7. proxies after stop ----------------------------------------------------------------

def test_proxies_raise_after_stop(tmp_path: Path) -> None:
    path = write(tmp_path, {"p.composite": composite(f"""
        <component name="C">{py("Single")}<reference name="one" target="G"/></component>
        <component name="G">{py("GreeterImpl")}</component>
    """)})
    rt = scart.Runtime.from_file(str(path))
    with rt:
        service = rt.service("C")
        assert service.call("x") == "Hello, x"
        again = rt.service("C")
        inner = rt._managers["C"].instance().one
    with pytest.raises(scart.RuntimeStateError):
        service.call("x")
    with pytest.raises(scart.RuntimeStateError):
        again.call("x")
    with pytest.raises(scart.RuntimeStateError):
        inner.greet("x")  # a reference proxy held by the (destroyed) instance
    with pytest.raises(scart.RuntimeStateError):
        rt.service("C")


# --- a @destroy that hangs ---------------------------------------------------------------

HANGING = '''
import threading

import scart

RELEASE = threading.Event()


class Hangs:
    @scart.destroy
    def close(self) -> None:
        RELEASE.wait(None)  # a driver that never lets go


class Fine:
    log_file: str = scart.prop(default="")

    @scart.destroy
    def close(self) -> None:
        if self.log_file:
            with open(self.log_file, "a", encoding="utf-8") as fh:
                fh.write("destroy fine\\n")
'''


def hanging_composite(tmp_path: Path, log: Path | None = None) -> Path:
    (tmp_path / "hanging.py").write_text(HANGING, encoding="utf-8")
    prop = f'<property name="log_file">{log}</property>' if log else ""
    return write(tmp_path, {"h.composite": composite(f"""
        <component name="F"><scart:implementation.python class="hanging:Fine"/>{prop}</component>
        <component name="H"><scart:implementation.python class="hanging:Hangs"/></component>
    """)})


def test_a_hanging_destroy_is_left_behind_at_the_stop_deadline(tmp_path: Path,
                                                               caplog: pytest.LogCaptureFixture) -> None:
    log = tmp_path / "events.log"
    rt = scart.Runtime.from_file(str(hanging_composite(tmp_path, log)), drain_timeout=0.3)
    rt.start()
    start = time.monotonic()
    with caplog.at_level(logging.WARNING, logger="scart.runtime"):
        rt.stop()
    try:
        assert time.monotonic() - start < 5.0
        assert "destroying H did not finish within the stop timeout" in caplog.text
        assert log.read_text() == "destroy fine\n"  # the others are destroyed all the same
    finally:
        importlib.import_module("hanging").RELEASE.set()


def test_many_hanging_destroys_share_one_grace_period(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "hanging.py").write_text(HANGING, encoding="utf-8")
    hangs = "".join(f'<component name="H{i}"><scart:implementation.python class="hanging:Hangs"/></component>'
                    for i in range(12))
    rt = scart.Runtime.from_file(str(write(tmp_path, {"many.composite": composite(hangs)})), drain_timeout=0.3)
    rt.start()
    start = time.monotonic()
    with caplog.at_level(logging.WARNING, logger="scart.runtime"):
        rt.stop()
    try:
        # 12 x MIN_DESTROY_S would be 6 s: the deadline and one shared grace bound it (about 1 s)
        assert time.monotonic() - start < 4.0
        assert caplog.text.count("did not finish within the stop timeout") == 12
    finally:
        importlib.import_module("hanging").RELEASE.set()


def test_run_exits_within_stop_timeout_when_a_destroy_hangs(tmp_path: Path) -> None:
    proc = start("run", str(hanging_composite(tmp_path)), "--stop-timeout", "0.5")
    try:
        read_until(proc, "started")
        began = time.monotonic()
        proc.send_signal(signal.SIGINT)
        out, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0 and time.monotonic() - began < 10.0, err
    assert "destroying H did not finish" in err and "scart: stopped" in err
