"""Samples lost with nothing said (issue 34, section 1), through the public CLI and real
processes: a writer stopped right after a burst delivers it (or says how many it could
not); a link's count survives its sink restarting (written = delivered + dropped); a link
survives a graceful restart of its source, and stays listed as ``waiting`` while the
source is gone."""

from __future__ import annotations

import json
import re
import signal
import subprocess

import pytest
from support import wait_until
from support.cli import run
from support.remote import address_of, start_scart, stop_process

from dataflow.remote import connect

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]

NOT_DELIVERED = re.compile(r"(\d+) sample\(s\) written were not delivered")


def _stop(proc: subprocess.Popen, sig: int = signal.SIGTERM) -> tuple[int, str, str]:
    """Signal ``proc`` and wait (bounded) for it: its exit code, stdout and stderr."""
    proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate(timeout=10)
    return proc.returncode, out, err


def _link(system, name: str):
    return next((lk for lk in system.links() if lk.name == name), None)


def _seen(system) -> int:
    try:
        return system.component("tally").call("seen")
    except Exception:  # noqa: BLE001 - a sink between its stop and its return
        return -1


@pytest.mark.parametrize("transport", ["ipc", "grpc"])
def test_a_writer_stopped_right_after_a_burst_delivers_it_or_says_how_many(transport) -> None:
    sink, line = start_scart(["deploy", "support.remote:Screen", "--name", "tally", "--listen", "127.0.0.1:0"])
    address = address_of(line)
    source = None
    try:
        source, _ = start_scart(["deploy", "support.remote:Burst", "--name", "burst", "--ns", address])
        result = run("connect", "burst.out", "tally.video", "--policy", "buffer:1000", "--transport", transport,
                     "--name", "b", "--ns", address)
        assert result.returncode == 0, result.stderr
        with connect(address, timeout=5.0) as system:
            wait_until(lambda: getattr(_link(system, "b"), "transport", "") == transport, timeout=10)
            assert system.component("burst").call("burst", 1000, 8192) == 0  # more than a socket holds
            code, _, err = _stop(source)  # at once, the burst barely on its way
            source = None
            assert code == 0, err
            said = sum(int(n) for n in NOT_DELIVERED.findall(err))
            wait_until(lambda: _seen(system) + said == 1000, timeout=15,
                       message=f"the sink read {_seen(system)}, the writer said {said} were not delivered: {err}")
    finally:
        if source is not None:
            stop_process(source, signal.SIGKILL)
        stop_process(sink, signal.SIGKILL)


@pytest.mark.parametrize("transport", ["ipc", "grpc"])
def test_a_link_counts_every_write_across_three_sink_restarts(transport) -> None:
    ns, line = start_scart(["nameserver", "--listen", "127.0.0.1:0"])
    address = address_of(line)
    sink_args = ["deploy", "support.remote:LoudTally", "--name", "tally", "--ns", address]
    procs = [ns]
    try:
        procs.append(start_scart(["deploy", "support.remote:Pinger", "--name", "src", "--period", "0.002",
                                  "--no-start", "--ns", address])[0])
        procs.append(start_scart(sink_args)[0])
        result = run("connect", "src.ticks", "tally.inp", "--policy", "buffer:1000", "--transport", transport,
                     "--name", "kept", "--ns", address)
        assert result.returncode == 0, result.stderr
        read = 0
        with connect(address, timeout=5.0) as system:
            assert system.component("src").start()  # every write of the source is one of this link's
            for restart in range(3):
                wait_until(lambda: _seen(system) > 50, timeout=20, message=f"restart {restart}: {system.links()}")
                code, out, err = _stop(procs[-1])
                assert code == 0, err
                read += int(re.search(r"tally read (\d+)", out).group(1))
                procs[-1] = start_scart(sink_args)[0]
            wait_until(lambda: _seen(system) > 50, timeout=20, message=f"{system.links()}")
            assert system.component("src").stop()  # no more writes: the sums must meet

            def balanced():
                link = _link(system, "kept")
                return link is not None and link.samples == read + _seen(system) + link.dropped
            wait_until(balanced, timeout=15, message=f"written {_link(system, 'kept')}, read {read} + {_seen(system)}")
            link = _link(system, "kept")
            assert link.transport == transport and link.samples > 400
    finally:
        for proc in reversed(procs):
            stop_process(proc, signal.SIGKILL)


def test_a_link_survives_a_graceful_restart_of_its_source_and_stays_listed_while_it_is_gone() -> None:
    ns, line = start_scart(["nameserver", "--listen", "127.0.0.1:0"])
    address = address_of(line)
    source_args = ["deploy", "support.remote:Pinger", "--name", "src", "--period", "0.01", "--ns", address]
    procs = [ns]
    try:
        procs.append(start_scart(["deploy", "support.remote:Tally", "--name", "tally", "--ns", address])[0])
        procs.append(start_scart(source_args)[0])
        result = run("connect", "src.ticks", "tally.inp", "--policy", "buffer:100", "--ns", address)  # its default name
        assert result.returncode == 0, result.stderr
        with connect(address, timeout=5.0) as system:
            wait_until(lambda: _seen(system) > 10, timeout=15, message="nothing crossed")
            code, _, err = _stop(procs[-1], signal.SIGINT)  # Ctrl-C
            assert code == 0, err

            def listed():
                rows = json.loads(run("links", "--json", "--ns", address).stdout)
                return rows if rows and rows[0]["state"] == "waiting" else None
            (row,) = wait_until(listed, timeout=10, message="the link vanished from scart links")
            assert (row["name"], row["source"], row["sink"]) == ("src.ticks->tally.inp", "src.ticks", "tally.inp")
            before = _seen(system)
            procs[-1] = start_scart(source_args)[0]
            wait_until(lambda: _seen(system) > before + 10, timeout=15, message=f"no sample after the restart: "
                                                                              f"{system.links()}")
            (row,) = json.loads(run("links", "--json", "--ns", address).stdout)
            assert row["state"] == "connected" and row["source"] == "src.ticks"
    finally:
        for proc in reversed(procs):
            stop_process(proc, signal.SIGKILL)
