"""A real YARP around the YARP tests: ``yarpserver`` on a free port with a configuration of
its own (``YARP_CONFIG_HOME``), and YARP's ``yarp`` command (read, write, connect,
disconnect, name, rpc) as subprocesses — YARP 3.5, built from PyPI's ``yarp-middleware``.

The tools are found on ``PATH``. Without them the YARP tests are skipped, saying how to
get them; where ``SCART_REQUIRE_YARP=1`` (``.ci/run`` sets it) a missing YARP fails them
instead. Every process is stopped by its context manager; every wait has a deadline.
"""

from __future__ import annotations

import contextlib
import os
import random
import shutil
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import stop_group, wait_until
from support.ros1 import Proc

YARPSERVER, YARP = shutil.which("yarpserver"), shutil.which("yarp")
HOW = ("YARP's yarpserver and yarp are not on PATH: build them with the steering repository's "
       "shared/yarp/build.sh (YARP 3.5.0 from PyPI's yarp-middleware sdist) and put its bin/ on PATH")


def server_port() -> int:
    """A port for ``yarpserver`` below the kernel's ephemeral range, free with the 50 after
    it: yarpserver gives YARP's tools the ports after its own without asking the kernel, so
    they must not be where the kernel hands out ports to everyone (scart's included)."""
    low = ephemeral_low()
    for _ in range(200):  # bounded: random tries
        port = random.randrange(max(1024, low - 12_000), low - 60)
        if all(_free(p) for p in range(port, port + 51)):
            return port
    raise RuntimeError("no run of 51 free ports below the ephemeral range")


def ephemeral_low() -> int:
    """The first port of the kernel's ephemeral range (Linux: 32768 unless set)."""
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def _free(port: int) -> bool:
    with socket.socket() as sock:
        try:
            sock.bind(("127.0.0.1", port))
            return True
        except OSError:
            return False


def require_yarp() -> None:
    """Skip the calling test (fail it where ``SCART_REQUIRE_YARP=1``) without YARP's tools."""
    if YARPSERVER and YARP:
        return
    if os.environ.get("SCART_REQUIRE_YARP") == "1":
        pytest.fail(f"SCART_REQUIRE_YARP=1 and {HOW}")
    pytest.skip(HOW)


class YarpServer:
    """A ``yarpserver`` on loopback with its own ``YARP_CONFIG_HOME`` (written by ``yarp
    conf``, as a user would), so that ``yarp`` and scart both find it there."""

    def __init__(self, home: Path) -> None:
        home.mkdir(parents=True, exist_ok=True)
        self.port = server_port()
        self.address = f"127.0.0.1:{self.port}"
        self.env = dict(os.environ, YARP_CONFIG_HOME=str(home))
        for var in ("YARP_NAMESPACE", "YARP_ROBOT_NAME", "XDG_CONFIG_HOME"):
            self.env.pop(var, None)
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        assert YARPSERVER is not None and YARP is not None
        self.tool("conf", "127.0.0.1", str(self.port))
        self.proc = subprocess.Popen([YARPSERVER, "--read", "--ip", "127.0.0.1", "--socket", str(self.port)],
                                     env=self.env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                     start_new_session=True)
        wait_until(lambda: "/root" in self.tool("name", "query", "/root", timeout=5).stdout, timeout=30,
                   interval=0.05, message=f"yarpserver on port {self.port} did not answer")

    def stop(self) -> None:
        if self.proc is not None:
            stop_group(self.proc)
            self.proc = None

    def tool(self, *args: str, stdin: str | None = None, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
        """Run ``yarp ARGS`` to completion (``stdin`` fed to it)."""
        assert YARP is not None
        return subprocess.run([YARP, *args], env=self.env, input=stdin, capture_output=True, text=True,
                              timeout=timeout)

    def spawn(self, *args: str) -> Proc:
        """Start ``yarp ARGS`` (``read /r``...) whose output a test reads while it runs."""
        assert YARP is not None
        return Proc(subprocess.Popen([YARP, *args], env=self.env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, bufsize=0, start_new_session=True))

    def registered(self, name: str) -> bool:
        return f"registration name {name} " in self.tool("name", "query", name, timeout=10).stdout


@contextlib.contextmanager
def yarpserver(home: Path) -> Iterator[YarpServer]:
    """A started :class:`YarpServer`, always stopped at the end."""
    require_yarp()
    server = YarpServer(home)
    try:
        server.start()
        yield server
    finally:
        server.stop()
