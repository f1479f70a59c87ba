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

Nothing is lost in a crash beyond the last
:data:`~dataflow.recording.recorder.FLUSH_SECONDS`: samples reach the disk in
chunks written at least that often, so a ``kill -9`` leaves a file that ``scart info``
reads (saying it is truncated) and ``scart record --recover FILE`` finishes into a
complete copy, as ``mcap recover`` does. A full disk (or a file-size limit) stops the
recording: the subscriptions end, the file is cut back to its last whole chunk and
closed, one line says how much was kept, and the exit code is 1.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from dataflow.recording.mcap import open_output, output_problem
from dataflow.recording.recorder import Recording
from scart_wire.console import add_common, err, out, stopped_by_signals, wait_until_stopped

if TYPE_CHECKING:
    from dataflow.introspection import PortDescription

HELP = "record output ports to an MCAP file"
MAX_RECORDED_PORTS = 256


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
    described: dict[str, dict[str, PortDescription]] = {}  # each task described once

    def ports_of(task: str) -> dict[str, PortDescription]:
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
