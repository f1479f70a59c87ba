"""A real ROS 1 around the ROS 1 tests: ``rosmaster --core`` on a free port, ROS's own tools
and rospy peers as subprocesses (Debian's ``ros-core`` and ``python3-rospy``).

Skipped with a reason where ROS 1 is not installed (CI installs it with apt-get). Every
process is stopped by its context manager; every wait has a deadline.
"""

from __future__ import annotations

import contextlib
import functools
import os
import selectors
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import TESTS, free_port, stop_group, wait_until

ROSMASTER = shutil.which("rosmaster")
SYSTEM_PYTHON = "/usr/bin/python3"  # Debian's python3-rospy lives in the system Python
PEER = TESTS / "dataflow" / "transports" / "ros1" / "rospy_peer.py"
APT = "apt-get install ros-core python3-rospy python3-rostopic python3-rosbag python3-std-msgs python3-sensor-msgs"


needs_ros = pytest.mark.skipif(ROSMASTER is None, reason=f"ROS 1's rosmaster is not installed (CI: {APT})")


@functools.cache
def has_rospy() -> bool:
    """Whether the system Python has rospy and the message packages the peers use (asked once)."""
    if not os.path.exists(SYSTEM_PYTHON):
        return False
    probe = subprocess.run([SYSTEM_PYTHON, "-c", "import rospy, std_msgs.msg, roscpp.srv"], capture_output=True, timeout=60)
    return probe.returncode == 0


def require_rospy() -> None:
    """Skip the calling test, saying why, where the system Python has no rospy."""
    if not has_rospy():
        pytest.skip(f"Debian's rospy is not installed for {SYSTEM_PYTHON} (CI: {APT})")


class RosMaster:
    """A ``rosmaster --core`` on one port that can be stopped and started again."""

    def __init__(self, log_dir: Path) -> None:
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}/"
        self.env = dict(os.environ, ROS_MASTER_URI=self.uri, ROS_HOSTNAME="127.0.0.1", ROS_LOG_DIR=str(log_dir),
                        ROS_HOME=str(log_dir))
        self.env.pop("ROS_NAMESPACE", None)
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        assert ROSMASTER is not None
        self.proc = subprocess.Popen([ROSMASTER, "--core", "-p", str(self.port)], env=self.env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        wait_until(self.answers, timeout=30, interval=0.05, message=f"rosmaster on port {self.port} did not answer")

    def answers(self) -> bool:
        import xmlrpc.client

        try:
            return xmlrpc.client.ServerProxy(self.uri).getPid("/probe")[0] == 1
        except OSError:
            return False

    def stop(self) -> None:
        if self.proc is not None:
            stop_group(self.proc)
            self.proc = None

    def tool(self, *args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
        """Run a ROS command line tool (``rostopic``, ``rosnode``, ...) to completion."""
        return subprocess.run(list(args), env=self.env, capture_output=True, text=True, timeout=timeout)

    def spawn(self, *args: str) -> Proc:
        """Start a ROS tool or program whose output a test reads while it runs."""
        return Proc(subprocess.Popen(list(args), env=self.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     bufsize=0, start_new_session=True))

    def rospy(self, *args: str) -> Proc:
        """Start :file:`rospy_peer.py` with the system Python (see that file for the roles)."""
        return self.spawn(SYSTEM_PYTHON, str(PEER), *args)


class Proc:
    """A running subprocess read line by line with deadlines; :meth:`stop` ends it."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self.proc = proc
        self.out = b""

    def read_until(self, needle: str, timeout: float = 30.0, count: int = 1) -> str:
        """Everything printed so far, once it holds ``needle`` ``count`` times (deadline)."""
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout
        with selectors.DefaultSelector() as sel:
            sel.register(self.proc.stdout, selectors.EVENT_READ)
            while self.out.count(needle.encode()) < count:
                left = deadline - time.monotonic()
                if left <= 0 or (not sel.select(timeout=left) and time.monotonic() >= deadline):
                    raise AssertionError(f"{needle!r} not printed within {timeout} s; got: {self.text()}")
                chunk = os.read(self.proc.stdout.fileno(), 65536)
                if not chunk:
                    raise AssertionError(f"process ended before printing {needle!r}; got: {self.text()}{self.err()}")
                self.out += chunk
        return self.text()

    def text(self) -> str:
        return self.out.decode(errors="replace")

    def err(self) -> str:
        if self.proc.poll() is None or self.proc.stderr is None:
            return ""
        return self.proc.stderr.read().decode(errors="replace")

    def wait(self, timeout: float = 30.0) -> int:
        return self.proc.wait(timeout=timeout)

    def stop(self) -> None:
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        for pipe in (self.proc.stdout, self.proc.stderr):
            if pipe is not None:
                pipe.close()


@contextlib.contextmanager
def rosmaster(log_dir: Path) -> Iterator[RosMaster]:
    """A started :class:`RosMaster`, always stopped at the end."""
    master = RosMaster(log_dir)
    try:
        master.start()
        yield master
    finally:
        master.stop()


@pytest.fixture
def ros(tmp_path: Path) -> Iterator[RosMaster]:
    """A ``rosmaster`` of the test's own, its logs in the test's folder (the ROS 1 test
    folders' conftests take it from here)."""
    with rosmaster(tmp_path) as master:
        yield master


@contextlib.contextmanager
def running(*procs: Proc) -> Iterator[None]:
    """Stop these processes at the end, whatever happens."""
    try:
        yield
    finally:
        for proc in procs:
            proc.stop()
