"""Large samples through shared memory on one host (transport ``shm``): ``auto`` takes it
for large kinds of samples and leaves small ones to ipc, a reader gets a read-only view
that stays valid while its task holds it, the policy bounds the memory a slow reader
pins, and kill -9 of the writer, the reader or both leaves nothing in ``/dev/shm``."""

from __future__ import annotations

import contextlib
import gc
import mmap
import os
import signal

import numpy as np
import pytest
from support import wait_until
from support.cli import run
from support.remote import address_of, start_scart, stop_process

from dataflow import Array, ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext
from dataflow.remote import connect
from dataflow.transports.ipc import shm as shm_transport

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(not shm_transport.available(), reason="shm needs Linux anonymous memory files")]

IMAGE = Array[np.uint8, (480, 640, 3)]


class Eye(TaskContext):
    image = OutputPort(IMAGE)
    count = OutputPort(int)


class Viewer(TaskContext):
    image = InputPort(IMAGE)
    count = InputPort(int)


def _backing(value) -> object:
    """What an array's memory finally belongs to (following its bases)."""
    while True:
        base = value.obj if isinstance(value, memoryview) else getattr(value, "base", None)
        if base is None:
            return value
        value = base


def _memfds(pid: int | str = "self") -> int:
    """The shared-memory slots a process maps now."""
    with open(f"/proc/{pid}/maps", encoding="ascii", errors="replace") as maps:
        return sum(1 for line in maps if "memfd:scart-shm" in line)


@contextlib.contextmanager
def serving():
    d1, d2 = Deployer(), Deployer()
    eye = d1.add(Eye("eye"))
    viewer = d2.add(Viewer("viewer"))
    s1 = d1.serve("127.0.0.1:0")
    s2 = d2.serve("127.0.0.1:0", ns=s1.address)
    try:
        with connect(s1.address, timeout=5.0) as system:
            yield system, eye, viewer, s1
    finally:
        s2.stop()
        s1.stop()


def _next(port: InputPort) -> list | None:
    """``[the next new sample]``, or None when there is none (a truthy box for wait_until)."""
    flow, value = port.read()
    return [value] if flow is FlowStatus.NEW_DATA else None


def _frame(k: int) -> np.ndarray:
    return np.full((480, 640, 3), k % 256, dtype=np.uint8)


def test_auto_takes_shared_memory_for_images_and_ipc_for_small_samples_and_a_view_lives_while_held() -> None:
    with serving() as (system, eye, viewer, source):
        system.connect_ports("eye.image", "viewer.image", ConnPolicy.buffer(4), name="img")
        system.connect_ports("eye.count", "viewer.count", ConnPolicy.buffer(4), name="n")
        wait_until(lambda: {lk.name: lk.transport for lk in system.links()} == {"img": "shm", "n": "ipc"}, timeout=10,
                   message=f"{system.links()}")
        eye.image.write(_frame(1))
        (held,) = wait_until(lambda: _next(viewer.image), timeout=10)
        assert isinstance(_backing(held), mmap.mmap) and not held.flags.writeable  # a view of the shared memory
        with pytest.raises(ValueError):
            held[0, 0, 0] = 9
        for k in range(2, 40):  # many more samples than slots, each read and let go
            eye.image.write(_frame(k))
            (got,) = wait_until(lambda: _next(viewer.image), timeout=10)
            assert got[0, 0, 0] == k % 256
            del got
        assert int(held.min()) == int(held.max()) == 1  # the held one was never written over
        carrier = next(link for link in source._links.values() if link.name == "img").end._carrier  # noqa: SLF001
        # the others' releases come back asynchronously: wait until only the held one and the
        # last one read (which the buffer keeps, for a read finding nothing new) are out
        wait_until(lambda: carrier.pool.busy == 2, timeout=5, message=f"{carrier.pool.busy} slots out, not 2")
        del held
        gc.collect()
        wait_until(lambda: carrier.pool.busy == 1, timeout=5, message="the slot never came back")


def test_a_subscription_to_an_image_port_takes_shared_memory_and_gets_read_only_views() -> None:
    with serving() as (system, eye, _, _):
        got: list = []
        sub = system.component("eye").subscribe("image", got.append, ConnPolicy.buffer(4))
        small = system.component("eye").subscribe("count", lambda e: None, ConnPolicy.buffer(4))
        try:
            assert (sub.transport, small.transport) == ("shm", "ipc")  # the deployer knows its port's samples
            wait_until(lambda: eye.image.write(_frame(5)) and got, timeout=10)
            image = got[0].value
            assert isinstance(_backing(image), mmap.mmap) and not image.flags.writeable and int(image[1, 2, 0]) == 5
        finally:
            small.close()
            sub.close()


def test_a_slow_reader_pins_no_more_slots_than_its_buffer_and_every_write_is_counted() -> None:
    before = _memfds()
    with serving() as (system, eye, viewer, _):
        system.connect_ports("eye.image", "viewer.image", ConnPolicy.buffer(4), name="img")
        wait_until(lambda: system.links()[0].transport == "shm", timeout=10)
        statuses = [eye.image.write(_frame(k)).name for k in range(60)]  # nobody reads meanwhile
        assert _memfds() - before <= 2 * (4 + 3)  # the buffer's samples and 3 more, each mapped by both ends
        link = wait_until(lambda: (lambda lk: lk if lk.samples == lk.dropped + 4 else None)(system.links()[0]),
                          timeout=10, message=f"{system.links()}")
        assert link.dropped == 56 and statuses.count("WRITE_SUCCESS") >= 4
        read = []
        for _ in range(100):
            flow, value = viewer.image.read()
            if flow is not FlowStatus.NEW_DATA:
                break
            read.append(int(value[0, 0, 0]))
        assert len(read) == 4


@pytest.mark.subprocess
def test_kill_9_of_the_writer_the_reader_or_both_leaves_nothing_in_dev_shm() -> None:
    before = sorted(os.listdir("/dev/shm"))
    camera, line = start_scart(["deploy", "support.remote:Camera", "--name", "camera", "--period", "0.05"])
    address = address_of(line)
    screen_args = ["deploy", "support.remote:Screen", "--name", "screen", "--ns", address]
    procs = [camera]
    try:
        procs.append(start_scart(screen_args)[0])
        assert run("connect", "camera.video", "screen.video", "--ns", address).returncode == 0
        with connect(address, timeout=5.0) as system:
            assert wait_until(lambda: [lk.transport for lk in system.links()] == ["shm"], timeout=10)
            seen = lambda: system.component("screen").call("seen")  # noqa: E731
            wait_until(lambda: seen() > 3, timeout=15, message=f"{system.links()}")
            assert _memfds(camera.pid) > 0
            procs[1].kill()  # the reader
            procs[1].wait(timeout=10)
            wait_until(lambda: _memfds(camera.pid) == 0, timeout=10, message="the writer kept its slots")
            procs[1] = start_scart(screen_args)[0]
            wait_until(lambda: seen() > 3, timeout=15, message=f"{system.links()}")
            camera.kill()  # the writer
            camera.wait(timeout=10)
        assert sorted(os.listdir("/dev/shm")) == before
        procs[1].kill()  # and the other: both gone
        procs[1].wait(timeout=10)
        assert sorted(os.listdir("/dev/shm")) == before
    finally:
        for proc in procs:
            stop_process(proc, signal.SIGKILL)
