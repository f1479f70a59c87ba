"""ROS's own tf2 (Debian's python3-tf2-ros) as the frames tests' judge: :class:`Peer` runs
``tf2_peer.py`` with the system Python and talks JSON lines with it; tests without it are
skipped, saying what CI installs."""

from __future__ import annotations

import functools
import json
import subprocess
from typing import Any

import pytest

from support import TESTS
from support.ros1 import SYSTEM_PYTHON, Proc, RosMaster, has_rospy

PEER = TESTS / "support" / "tf2_peer.py"
APT = "apt-get install python3-tf2-ros python3-tf2-msgs"


@functools.cache
def has_tf2() -> bool:
    """Whether the system Python has rospy and tf2_ros (asked once)."""
    if not has_rospy():
        return False
    probe = subprocess.run([SYSTEM_PYTHON, "-c", "import tf2_ros, tf2_msgs.msg"], capture_output=True, timeout=60)
    return probe.returncode == 0


def require_tf2() -> None:
    """Skip the calling test, saying why, where the system Python has no tf2_ros."""
    if not has_tf2():
        pytest.skip(f"Debian's tf2_ros is not installed for {SYSTEM_PYTHON} (CI: {APT})")


class Peer:
    """``tf2_peer.py`` in a subprocess: a JSON command per line in, a JSON answer per line out."""

    def __init__(self, ros: RosMaster, *args: str) -> None:
        self.proc = Proc(subprocess.Popen([SYSTEM_PYTHON, str(PEER), *args], env=ros.env, stdin=subprocess.PIPE,
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0,
                                          start_new_session=True))
        self.lines = 0

    def next(self, timeout: float = 30.0) -> dict[str, Any]:
        """The next line the peer says (deadline ``timeout`` s)."""
        self.lines += 1
        text = self.proc.read_until("\n", timeout=timeout, count=self.lines)
        return json.loads(text.splitlines()[self.lines - 1])

    def ask(self, **command: Any) -> dict[str, Any]:
        """Send one command, return the answer."""
        assert self.proc.proc.stdin is not None
        self.proc.proc.stdin.write((json.dumps(command) + "\n").encode())
        return self.next()

    def stop(self) -> None:
        """Close its input (it ends), stop it."""
        if self.proc.proc.stdin is not None:
            self.proc.proc.stdin.close()
        self.proc.stop()
