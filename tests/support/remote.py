"""Shared fixtures-free helpers for the remote and CLI-inspection suites (no tests here).

Holds a small task used by in-process servers and by ``scart deploy`` subprocesses
(``scart deploy support.remote:Pinger`` with ``tests/`` on PYTHONPATH), and the
subprocess helpers that read a deployer's readiness line with a deadline.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import numpy as np

from dataflow import Array, FlowStatus, InputPort, OutputPort, Property, TaskContext, operation
from support import ROOT, TESTS

if str(ROOT / "composites" / "youbot") not in sys.path:  # the youBot model (Echo's status)
    sys.path.insert(0, str(ROOT / "composites" / "youbot"))
from youbot_model import YouBotStatus  # noqa: E402


class Pinger(TaskContext):
    """Echoes ``input`` × ``gain`` on ``output``; counts cycles on ``ticks``."""

    input = InputPort(float, name="input", doc="value to echo")
    samples = InputPort(list[float], doc="a list input")
    output = OutputPort(float, name="output", doc="gain × input")
    ticks = OutputPort(int, doc="cycle counter")
    gain = Property(float, 1.0, doc="multiplier")
    label = Property(str, "pinger", doc="free text")

    def __init__(self, name: str = "pinger") -> None:
        super().__init__(name)
        self.count = 0
        self.received: list[float] = []

    @operation
    def add(self, a: float, b: float) -> float:
        """Sum of two numbers."""
        return a + b

    @operation
    def reset(self) -> None:
        """Zero the cycle counter."""
        self.count = 0

    @operation
    def fail(self, why: str) -> None:
        """Always raises RuntimeError(why)."""
        raise RuntimeError(why)

    def update_hook(self) -> None:
        for _ in range(1000):
            status, value = self.input.read()
            if status.name != "NEW_DATA":
                break
            self.received.append(value)
            self.output.write(value * self.gain)
        self.count += 1
        self.ticks.write(self.count)


class Slow(TaskContext):
    """A sink behind its writers: reads at most one sample of ``inp`` per cycle; ``seen()``
    says how many it read (run it periodic: ``scart deploy support.remote:Slow --period 0.01``)."""

    inp = InputPort(int, doc="read one per cycle")

    def __init__(self, name: str = "slow") -> None:
        super().__init__(name)
        self.count = 0

    @operation
    def seen(self) -> int:
        """Samples read so far."""
        return self.count

    def update_hook(self) -> None:
        if self.inp.read()[0].name == "NEW_DATA":
            self.count += 1


class Tally(TaskContext):
    """Counts what arrives on ``inp`` (an event port); ``seen()`` says how many."""

    inp = InputPort(int, event=True, doc="counted")

    def __init__(self, name: str = "tally") -> None:
        super().__init__(name)
        self.count = 0

    @operation
    def seen(self) -> int:
        """Samples read so far."""
        return self.count

    def update_hook(self) -> None:
        for _ in range(100_000):
            if self.inp.read()[0].name != "NEW_DATA":
                return
            self.count += 1


class Camera(TaskContext):
    """Writes a frame of ``size`` bytes on ``video`` each cycle (its first byte the cycle
    number, mod 256); ``written()`` counts the writes, ``failed()`` those refused."""

    video = OutputPort(bytes, doc="one frame per cycle")
    size = Property(int, 6_220_800, doc="bytes of a frame (1080p RGB by default)")

    def __init__(self, name: str = "camera") -> None:
        super().__init__(name)
        self.count = 0
        self.refused = 0

    @operation
    def written(self) -> int:
        """Frames written so far."""
        return self.count

    @operation
    def failed(self) -> int:
        """Writes that returned WRITE_FAILURE."""
        return self.refused

    def update_hook(self) -> None:
        self.count += 1
        frame = bytes([self.count % 256]) + bytes(max(0, self.size - 1))
        if self.video.write(frame).name == "WRITE_FAILURE":
            self.refused += 1


class Screen(TaskContext):
    """Counts the frames arriving on ``video`` (an event port); ``seen()`` says how many,
    ``last_size()`` how big the last one was."""

    video = InputPort(bytes, event=True, doc="counted")

    def __init__(self, name: str = "screen") -> None:
        super().__init__(name)
        self.count = 0
        self.size = 0

    @operation
    def seen(self) -> int:
        """Frames read so far."""
        return self.count

    @operation
    def last_size(self) -> int:
        """Bytes of the last frame read."""
        return self.size

    def update_hook(self) -> None:
        for _ in range(10_000):
            flow, frame = self.video.read()
            if flow.name != "NEW_DATA":
                return
            self.count += 1
            self.size = len(frame)


VGA = Array[np.uint8, (480, 640, 3)]


class EyeCam(TaskContext):
    """Writes a 640x480 RGB image each cycle: every byte the cycle number (mod 256)."""

    image = OutputPort(VGA, doc="one frame per cycle")

    def __init__(self, name: str = "eye") -> None:
        super().__init__(name)
        self.count = 0

    def update_hook(self) -> None:
        self.count += 1
        self.image.write(np.full((480, 640, 3), self.count % 256, dtype=np.uint8))


class Album(TaskContext):
    """Keeps the first byte of each image arriving on ``image``: ``firsts()``."""

    image = InputPort(VGA, event=True, doc="kept")

    def __init__(self, name: str = "album") -> None:
        super().__init__(name)
        self.kept: list[int] = []

    @operation
    def firsts(self) -> list[int]:
        """The first byte of each image read, in order."""
        return list(self.kept)

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, image = self.image.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            if int(image.min()) == int(image.max()):  # whole: every byte the same
                self.kept.append(int(image[0, 0, 0]))


FULL_HD = Array[np.uint8, (1080, 1920, 3)]


class HdCam(TaskContext):
    """Writes a 1080p RGB image (6.2 MB) each cycle: every byte the cycle number (mod 256)."""

    image = OutputPort(FULL_HD, doc="one frame per cycle")

    def __init__(self, name: str = "hdcam") -> None:
        super().__init__(name)
        self.count = 0

    def update_hook(self) -> None:
        self.count += 1
        self.image.write(np.full((1080, 1920, 3), self.count % 256, dtype=np.uint8))


class HdAlbum(Album):
    """An :class:`Album` of 1080p RGB images."""

    image = InputPort(FULL_HD, event=True, doc="kept")


class Burst(TaskContext):
    """Writes ``n`` samples of ``size`` bytes at once on ``out`` when asked (``burst(n, size)``)."""

    out = OutputPort(bytes, doc="bursts")

    def __init__(self, name: str = "burst") -> None:
        super().__init__(name)
        self.count = 0

    @operation
    def burst(self, n: int, size: int) -> int:
        """Write ``n`` samples now; returns how many were refused (WRITE_FAILURE)."""
        refused = 0
        for _ in range(n):
            self.count += 1
            refused += self.out.write(bytes([self.count % 256]) * size).name == "WRITE_FAILURE"
        return refused


class LoudTally(Tally):
    """A :class:`Tally` that prints how many it read when it stops: ``tally read N``."""

    def stop_hook(self) -> None:
        print(f"tally read {self.count}", flush=True)


class Plain(TaskContext):
    """A task whose ``__init__`` has no default name (``scart deploy`` names it after the class)."""

    beats = OutputPort(int, doc="always 1")

    def update_hook(self) -> None:
        self.beats.write(1)


class Echo(TaskContext):
    """Echoes a float list and a youBot status (a pydantic model) to its outputs."""

    floats = InputPort(list[float], doc="a list of floats")
    floats_out = OutputPort(list[float], doc="the last floats received")
    status = InputPort(YouBotStatus, doc="a youBot status")
    status_out = OutputPort(YouBotStatus, doc="the last status received")

    def __init__(self, name: str = "echo") -> None:
        super().__init__(name)

    def update_hook(self) -> None:
        flow, value = self.floats.read()
        if flow.name == "NEW_DATA":
            self.floats_out.write(value)
        flow, status = self.status.read()
        if flow.name == "NEW_DATA":
            self.status_out.write(status)


def subprocess_env(ns: str | None = None) -> dict[str, str]:
    """Environment for scart subprocesses: tests/ importable, SCART_NS set or removed."""
    env = dict(os.environ)
    paths = [str(TESTS), str(ROOT), str(ROOT / "composites" / "youbot"), env.get("PYTHONPATH", "")]
    env["PYTHONPATH"] = os.pathsep.join(p for p in paths if p)
    env.pop("SCART_NS", None)
    if ns:
        env["SCART_NS"] = ns
    return env


def start_scart(args: list[str], ns: str | None = None, ready: str = "serving", timeout: float = 30.0):
    """Start ``scart ARGS`` and wait (≤ ``timeout``) for a stderr line containing ``ready``.

    Returns ``(process, line)``. Raises ``AssertionError`` with the output on failure.
    A ``deploy`` told neither ``--ns`` nor ``--listen`` listens on a free port, not on the
    default name-service port (another run on this host may hold it).
    """
    if args[:1] == ["deploy"] and ns is None and not {"--ns", "--listen"} & set(args):
        args = [*args, "--listen", "127.0.0.1:0"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "scart", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        env=subprocess_env(ns), text=True, bufsize=1,
    )
    # Blocking reads, ended by the process's end or the deadline's kill: a select on the pipe
    # would miss a line already read into the stream's buffer with the one before it.
    deadline = threading.Timer(timeout, proc.kill)
    deadline.daemon = True
    deadline.start()
    seen = []
    try:
        for line in iter(proc.stderr.readline, ""):
            seen.append(line)
            if ready in line:
                return proc, line.strip()
    finally:
        deadline.cancel()
        deadline.join(5.0)  # cancelled: it ends at once
    stop_process(proc)
    raise AssertionError(f"scart {' '.join(args)} did not get ready: {''.join(seen)}")


def stop_process(proc: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
    """Signal ``proc`` (continuing it if stopped), wait ≤ ``timeout``, kill if needed."""
    if proc.poll() is None:
        try:
            proc.send_signal(signal.SIGCONT)
            proc.send_signal(sig)
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=timeout)
    for stream in (proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()
    return proc.returncode


def address_of(line: str) -> str:
    """The ``127.0.0.1:PORT`` after 'serving ... on' in a readiness line."""
    return line.split(" on ", 1)[1].split()[0]
