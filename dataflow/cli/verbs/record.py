"""``scart record PORT... -o FILE.mcap``: record output ports to one MCAP file.

``-o`` names a *file* (``ros2 bag record -o`` names a folder; scart writes the one
``.mcap`` file, which the Foxglove app and the ``mcap`` tools open). An existing file is
kept unless ``--overwrite``; a folder, or a file in a folder that does not exist, is
refused in one line before anything is subscribed.

Each output port (``-a``: every output port the name service's tasks have) is subscribed
with a ``BUFFER`` policy (nothing is lost while the file is written) and becomes one
channel (topic ``task.port``) of JSON messages with a JSON Schema of the port's type;
``log_time`` is when a sample arrived, ``publish_time`` when the task stored it. It stops
after ``--duration`` s, ``-n`` samples, or Ctrl-C/SIGTERM, and the file is closed complete
(summary and index).

Nothing is lost in a crash beyond the last :data:`FLUSH_SECONDS`: samples reach the disk in
chunks written at least that often, so a ``kill -9`` leaves a file that ``scart info``
reads (saying it is truncated) and ``scart record --recover FILE`` finishes into a
complete copy, as ``mcap recover`` does. A full disk (or a file-size limit) stops the
recording: the subscriptions end, the file is cut back to its last whole chunk and
closed, one line says how much was kept, and the exit code is 1.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import queue
import signal
import threading
import time
from typing import Any

from dataflow.cli.connected import with_system
from dataflow.recording.mcap import Sink, open_output, output_problem
from dataflow.threads import OwnedThread
from scart_wire.console import add_common, err, out, stopped_by_signals, wait_until_stopped

HELP = "record output ports to an MCAP file"
MAX_RECORDED_PORTS = 256
FLUSH_SECONDS = 0.5  #: samples reach the disk at least this often (a kill -9 loses at most this much)
_STOP = object()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ports, the file, when to stop, ``--recover`` and the common options."""
    parser.add_argument("ports", nargs="*", metavar="COMP.PORT", help="output ports: COMP.PORT or /COMP/PORT")
    parser.add_argument("-a", "--all", action="store_true", help="every output port of every task the name service lists")
    parser.add_argument("-o", "--output", default=None, metavar="FILE.mcap",
                        help="the MCAP file to write: a file, not a folder as ros2 bag's -o (with --recover: "
                             "default FILE-recovered.mcap)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    parser.add_argument("-n", type=int, default=None, help="stop after N samples in all")
    parser.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    parser.add_argument("--recover", default=None, metavar="FILE",
                        help="write a complete copy of FILE, a recording cut short (killed, disk full), "
                             "and record nothing (as mcap recover)")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Record (or ``--recover``); 1 on any failure, said in one line."""
    if args.recover is not None:
        from dataflow.cli.verbs._recover import recover

        return recover(args)
    if args.output is None:
        err("record: give -o FILE.mcap, the file to write")
        return 2
    problem = output_problem(args.output, args.overwrite)
    if problem is not None:
        err(f"record: {problem}")
        return 1
    return with_system(args, _record)


def _ports_to_record(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """``(task, port, type name)`` of each output port to record."""
    from dataflow.remote.api import split_port

    wanted = [split_port(p) for p in args.ports]
    described: dict[str, dict[str, Any]] = {}  # each task described once

    def ports_of(task: str) -> dict[str, Any]:
        if task not in described:
            described[task] = {p.name: p for p in args.system.component(task).describe().ports}
        return described[task]

    if args.all:
        wanted += [(c, name) for c in args.system.component_names()
                   for name, p in ports_of(c).items() if p.direction == "out"]
    if not wanted:
        raise ValueError("name output ports (COMP.PORT ...) or give -a")
    if len(wanted) > MAX_RECORDED_PORTS:
        raise ValueError(f"{len(wanted)} ports: at most {MAX_RECORDED_PORTS}")
    found = []
    for task, port in dict.fromkeys(wanted):
        ports = ports_of(task)
        info = ports.get(port)
        if info is None or info.direction != "out":
            raise ValueError(f"{task} has no output port {port!r}; outputs: "
                             f"{', '.join(n for n, p in ports.items() if p.direction == 'out') or 'none'}")
        found.append((task, port, info.type_name))
    return found


def _record(args: argparse.Namespace) -> int:
    """Subscribe, write until told to stop, finish the file; see the module docstring."""
    from dataflow import ConnPolicy

    ports = _ports_to_record(args)
    fd = open_output(args.output, args.overwrite)
    if hasattr(signal, "SIGXFSZ"):  # a file-size limit: an error to report, not a silent death
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        recording = Recording(fd, ports, args.n)
    except OSError as exc:  # not even the file's start fits (a full disk)
        os.close(fd)
        raise ValueError(f"-o {args.output}: {exc.strerror or exc}") from None
    subs = []
    try:
        with stopped_by_signals(recording.done):  # before it says Ctrl-C stops it
            for task, port, _ in ports:
                subs.append(args.system.component(task).subscribe(port, recording.observe,
                                                                  policy=ConnPolicy.buffer(10_000)))
            err(f"record: {len(ports)} port(s) to {args.output}; Ctrl-C to stop")
            wait_until_stopped(recording.done, args.duration, tick=0.2)
    finally:
        for sub in subs:
            sub.close()
        recording.close()
    if recording.failure is not None:
        err(f"record: {args.output}: {recording.failure}")
        return 1
    total = sum(recording.counts.values())
    out(json.dumps({"file": args.output, "samples": total, "channels": recording.counts}) if args.json
        else f"recorded {total} sample(s) to {args.output}: " + ", ".join(f"{k} {v}" for k, v in recording.counts.items()))
    return 0


class Recording:
    """One MCAP file being written by its own thread from the samples :meth:`observe` is
    given (any thread). :attr:`done` is set when it stops by itself (``limit`` samples, or
    a write failed: :attr:`failure` says why and how much was kept). :meth:`close` ends
    the thread and finishes the file; idempotent."""

    def __init__(self, fd: int, ports: list[tuple[str, str, str]], limit: int | None) -> None:
        from mcap.writer import Writer

        from scart_wire.jsonschema import message_schema, schema_name

        self.done = threading.Event()
        self.failure: str | None = None
        self.counts = {f"{t}.{p}": 0 for t, p, _ in ports}
        self._limit = limit
        self._sink = Sink(fd)
        self._writer = Writer(self._sink)  # type: ignore[arg-type]  # mcap wants an IO; a Sink has what it uses: write, tell, flush
        self._samples: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._total, self._first, self._last = 0, 0.0, 0.0
        self._writer.start(profile="", library="scart")
        self._channels = {}
        for task, port, type_name in ports:
            schema_id = self._writer.register_schema(name=schema_name(type_name), encoding="jsonschema",
                                                     data=json.dumps(message_schema(type_name)).encode())
            self._channels[f"{task}.{port}"] = self._writer.register_channel(
                topic=f"{task}.{port}", message_encoding="json", schema_id=schema_id,
                metadata={"type_name": type_name})
        self._kept = (self._sink.pos, 0, 0.0, 0.0)  # (bytes, samples, first, last log time) on disk whole
        self._thread = OwnedThread(lambda _stopping: self._run(), "scart-record-writer").start()
        self._closed = False

    def observe(self, event: Any) -> None:
        """A subscription's observer: queue the sample (never blocks)."""
        self._samples.put((f"{event.component}.{event.port}", time.time_ns(), event.source_time, event.value))

    def _run(self) -> None:
        """The writer thread: each queued sample to the file, a chunk on disk at least every
        :data:`FLUSH_SECONDS`, until the stop mark."""
        pending, flushed_at = 0, time.monotonic()
        while True:
            try:
                item = self._samples.get(timeout=FLUSH_SECONDS / 2)
            except queue.Empty:
                item = None
            if item is _STOP:
                break
            if item is not None and self.failure is None and (self._limit is None or self._total < self._limit):
                try:
                    self._add(item)
                except OSError as exc:
                    self._fail(exc)
                    continue
                pending += 1
                if self._limit is not None and self._total >= self._limit:
                    self.done.set()
            if pending and self.failure is None and time.monotonic() - flushed_at >= FLUSH_SECONDS:
                if self._flush():
                    pending, flushed_at = 0, time.monotonic()

    def _flush(self) -> bool:
        """The chunk so far, whole, to the file; True when it is there (else failed)."""
        try:
            self._writer.flush()
        except OSError as exc:
            self._fail(exc)
            return False
        self._kept = (self._sink.pos, self._total, self._first, self._last)
        return True

    def _add(self, item: tuple[str, int, float, Any]) -> None:
        from scart_wire.jsonschema import message_of

        topic, log_ns, source_time, value = item
        self.counts[topic] += 1
        self._total += 1
        self._first, self._last = self._first or log_ns / 1e9, log_ns / 1e9
        publish_ns = int(source_time * 1e9) if source_time else log_ns
        self._writer.add_message(channel_id=self._channels[topic], log_time=log_ns, publish_time=publish_ns,
                                 sequence=self.counts[topic], data=json.dumps(message_of(value)).encode())

    def _fail(self, exc: OSError) -> None:
        """A write failed: stop recording, cut the file back to its last whole chunk."""
        _, kept, first, last = self._kept
        what = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is full",
                errno.EFBIG: "the file-size limit is reached"}.get(exc.errno or 0, f"writing failed ({exc.strerror})")
        self.failure = (f"{what}: recording stopped; kept {kept} sample(s) ({max(0.0, last - first):.1f} s), "
                        f"the rest is lost")
        self._cut_back()
        self.done.set()

    def _cut_back(self) -> None:
        """Cut the file to its last whole chunk and end it there (an MCAP data end and footer
        without a summary: every reader reads it); when even that does not fit, the cut file
        is left, which ``scart info`` reads and ``--recover`` finishes."""
        from mcap.data_stream import RecordBuilder
        from mcap.records import DataEnd, Footer

        good = self._kept[0]
        builder = RecordBuilder()
        DataEnd(data_section_crc=0).write(builder)
        Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(builder)
        tail = builder.end() + b"\x89MCAP0\r\n"
        try:
            os.ftruncate(self._sink.fd, good)
            os.pwrite(self._sink.fd, tail, good)
        except OSError:
            try:
                os.ftruncate(self._sink.fd, good)
            except OSError:
                pass
            if self.failure is not None:
                self.failure += " (the file ends without its index: scart record --recover finishes it)"

    def close(self) -> None:
        """Stop the writer thread (bounded), finish the file, close it. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._samples.put(_STOP)
        self._thread.join(30)
        try:
            if self._thread.alive:  # never finish a file the writer thread is still writing
                self.failure = self.failure or "the writer thread did not finish within 30 s; the file is incomplete"
            elif self.failure is None and self._flush():
                try:
                    self._writer.finish()
                except OSError as exc:
                    self._fail(exc)
        finally:
            os.close(self._sink.fd)
