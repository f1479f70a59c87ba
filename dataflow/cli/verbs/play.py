"""``scart play FILE.mcap``: write the samples of an MCAP file again, in order, to the
*input* ports of the same names, at the recorded pace scaled by ``--rate`` (absolute
deadlines: no drift), or one by one on Enter with ``--step``.

``--topics A.out B.out`` plays those channels only (``ros2 bag play --topics``);
``--remap OLD.PORT:=NEW.PORT`` (or ``=``) writes a channel's samples to another port; a
port may be named ``/COMP/PORT`` too. A pause longer than ``--max-gap`` seconds in the
file (default :data:`DEFAULT_MAX_GAP`) is shortened to it, and said. The file is read
with the bounds of :mod:`dataflow.recording.mcap`: a message that is too large, not JSON or
nested too deeply is skipped and counted, a malformed or truncated file is said in one
line. The exit code is 1 when anything was not played (skipped, refused, a bad file).

The samples of an array or ``bytes`` port (a camera's frames, over the control plane's
4 MiB once large) go through a link of play's own from its process to the port, as a link
between deployers does (:mod:`dataflow.recording.playlink`: shm on one host); every other
sample is written through the control plane."""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from dataflow.errors import DataflowError
from dataflow.remote.api import split_port
from scart_wire.console import add_common, dump, err, out, stopped_by_signals

if TYPE_CHECKING:
    from dataflow.recording.mcap import McapScan
    from dataflow.recording.playlink import PlayLink
    from dataflow.remote import ComponentProxy

HELP = "replay an MCAP file into input ports"
DEFAULT_MAX_GAP = 3.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The file, the pace, which channels, where to, and the common options."""
    parser.add_argument("file")
    parser.add_argument("--rate", type=float, default=1.0, help="pace: 2 = twice as fast (default 1)")
    parser.add_argument("--step", action="store_true", help="one sample per Enter on stdin")
    parser.add_argument("--topics", nargs="+", default=None, metavar="COMP.PORT",
                        help="play only these channels (the others are left out)")
    parser.add_argument("--remap", action="append", default=[], metavar="OLD.PORT:=NEW.PORT",
                        help="write OLD.PORT's samples to NEW.PORT (':=' or '='; repeatable)")
    parser.add_argument("--max-gap", type=float, default=DEFAULT_MAX_GAP, metavar="SECONDS",
                        help=f"shorten a longer pause between samples to this (default {DEFAULT_MAX_GAP:g} s)")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Play the file; 1 when anything was not played."""
    if not (0 < args.rate <= 1000):
        err(f"play: --rate {args.rate:g}: expected 0 < rate <= 1000")
        return 2
    if not args.max_gap >= 0:
        err(f"play: --max-gap {args.max_gap:g}: expected a number of seconds >= 0")
        return 2
    try:
        args.remap_table = remap_table(args.remap)
        args.topic_set = None if args.topics is None else {_canonical(t, "--topics") for t in args.topics}
    except ValueError as exc:
        err(f"play: {exc}")
        return 2
    return with_system(args, _play)


def _canonical(name: str, flag: str) -> str:
    try:
        task, port = split_port(name.strip())
    except ValueError as exc:
        raise ValueError(f"{flag} {name!r}: {exc}") from None
    return f"{task}.{port}"


def remap_table(items: list[str]) -> dict[str, str]:
    """``["old.port:=new.port", "a/x=b/y", ...]`` as ``{"old.port": "new.port", ...}``;
    raises ``ValueError`` naming a malformed item."""
    table = {}
    for item in items:
        sep = ":=" if ":=" in item else "="
        old, found, new = item.partition(sep)
        if not found:
            raise ValueError(f"--remap {item!r}: expected OLD.PORT:=NEW.PORT")
        table[_canonical(old, "--remap")] = _canonical(new, "--remap")
    return table


class _Pace:
    """When each sample is due: the recorded spacing over ``rate``, from absolute deadlines,
    with pauses over ``max_gap`` shortened (counted, the first one said)."""

    def __init__(self, rate: float, max_gap: float, file: str) -> None:
        self.rate, self.max_gap, self.file = rate, max_gap, file
        self.start: float | None = None
        self.first_log = self.last_log = 0
        self.shortened = 0

    def due(self, log_ns: int, topic: str) -> float:
        """The monotonic time the sample logged at ``log_ns`` is due."""
        if self.start is None:
            self.start, self.first_log, self.last_log = time.monotonic(), log_ns, log_ns
        gap = (log_ns - self.last_log) / 1e9 / self.rate
        if gap > self.max_gap:
            self.start -= gap - self.max_gap  # the deadlines after it move up by what was cut
            if not self.shortened:
                err(f"play: {self.file}: a pause of {gap:.3g} s before {topic} shortened to {self.max_gap:g} s "
                    "(--max-gap)")
            self.shortened += 1
        self.last_log = max(self.last_log, log_ns)
        return self.start + (log_ns - self.first_log) / 1e9 / self.rate


def _play(args: argparse.Namespace) -> int:
    from dataflow.recording.mcap import McapError, McapScan

    tally = {"written": 0, "skipped": 0, "refused": 0, "left_out": 0}
    seen: set[str] = set()
    said: set[str] = set()  # ports whose first refusal was said
    pace = _Pace(args.rate, args.max_gap, args.file)
    scan = McapScan(args.file)
    proxies: dict[str, ComponentProxy] = {}
    args.links = {}  # target -> its PlayLink, or None: through the control plane
    done = threading.Event()
    problem = ""
    with stopped_by_signals(done):
        try:
            for topic, log_ns, data in scan.messages():
                if done.is_set():
                    break
                seen.add(topic)
                if args.topic_set is not None and topic not in args.topic_set:
                    tally["left_out"] += 1
                    continue
                if data is None:
                    tally["skipped"] += 1
                    continue
                if not _wait_turn(args, pace, log_ns, topic, data, done):
                    break
                _write(args, proxies, topic, data, tally, said)
        except McapError as exc:
            problem = str(exc)
        finally:
            _close_links(args, tally)
    return _report(args, tally, seen, scan, pace, problem)


def _wait_turn(args: argparse.Namespace, pace: _Pace, log_ns: int, topic: str, data: dict[str, object],
               done: threading.Event) -> bool:
    """Wait until the sample is due (or Enter with ``--step``); False to stop playing."""
    target = args.remap_table.get(topic, topic)
    if args.step:
        err(f"play: {target} <- {json.dumps(data)[:100]}  (Enter: write, Ctrl-D: stop)")
        return bool(sys.stdin.readline())
    return not done.wait(max(0.0, pace.due(log_ns, topic) - time.monotonic()))


def _write(args: argparse.Namespace, proxies: dict[str, ComponentProxy], topic: str, data: dict[str, object],
           tally: dict[str, int], said: set[str]) -> None:
    """One sample to its port; a value the port or task refuses is counted (the first
    refusal of each port said), an unknown task or port stops the play (raises)."""
    target = args.remap_table.get(topic, topic)
    task, port = split_port(target)
    if task not in proxies:
        proxies[task] = args.system.component(task)
    value = data["value"] if set(data) == {"value"} else data
    try:
        link = _link_for(args, proxies[task], target)
        status = link.write(value) if link is not None else proxies[task].write_json(port, value).name
    except (ValueError, TypeError, DataflowError) as exc:  # refused by the port or the task: counted, said once
        if target not in said:
            err(f"play: {target}: {exc}")
            said.add(target)
        tally["refused"] += 1
        return
    if status != "WRITE_SUCCESS":
        err(f"play: {target}: {status}")
        tally["refused"] += 1
        return
    tally["written"] += 1


def _link_for(args: argparse.Namespace, proxy: ComponentProxy, target: str) -> PlayLink | None:
    """The :class:`~dataflow.recording.playlink.PlayLink` that carries ``target``'s samples (made
    at its first sample), or None when the control plane does (a port of another type
    than an array or ``bytes``). Raises ``DataflowError`` when the link cannot be made."""
    if target in args.links:
        return args.links[target]
    from dataflow.recording.playlink import PlayLink, on_data_plane

    task, port = split_port(target)
    found = proxy.ports().get(port)
    type_name = found.type_name if found is not None else ""
    args.links[target] = None
    if on_data_plane(type_name):
        args.links[target] = PlayLink(args.system, task, port, type_name, len(args.links))
    return args.links[target]


def _close_links(args: argparse.Namespace, tally: dict[str, int]) -> None:
    """Undo play's links once what they carry is delivered; what a sink did not take
    (its buffer full) moves from written to refused, and is said."""
    for target, link in getattr(args, "links", {}).items():
        if link is None:
            continue
        lost = min(link.close(), tally["written"])
        if lost:
            err(f"play: {target}: {lost} sample(s) not delivered (the port's buffer was full)")
            tally["written"] -= lost
            tally["refused"] += lost


def _report(args: argparse.Namespace, tally: dict[str, int], seen: set[str], scan: McapScan, pace: _Pace,
            problem: str) -> int:
    """The closing line (stdout), what went wrong (stderr); the exit code."""
    from dataflow.recording.mcap import MAX_JSON_DEPTH, MAX_MESSAGE_BYTES

    missing = sorted((args.topic_set or set()) - seen)
    if missing:
        err(f"play: {args.file} has no channel {', '.join(missing)}; it has {', '.join(sorted(seen)) or 'none'}")
    if problem:
        err(f"play: {args.file}: {problem}")
    elif scan.truncated_at is not None:
        err(f"play: {args.file}: truncated at byte {scan.truncated_at}: played what comes before")
    if tally["skipped"]:
        err(f"play: {args.file}: {tally['skipped']} message(s) unreadable (over {MAX_MESSAGE_BYTES >> 20} MiB, not a "
            f"JSON object, or nested deeper than {MAX_JSON_DEPTH} levels), skipped")
    if pace.shortened > 1:
        err(f"play: {pace.shortened} pauses shortened to {args.max_gap:g} s (--max-gap)")
    notes = [f"{tally[k]} {word}" for k, word in (("skipped", "unreadable, skipped"), ("refused", "refused"),
                                                  ("left_out", "left out by --topics")) if tally[k]]
    if args.json:
        out(dump({"file": args.file, "written": tally["written"], "skipped": tally["skipped"],
                  "refused": tally["refused"], "left_out": tally["left_out"],
                  "truncated": scan.truncated_at is not None}))
    else:
        out(f"played {tally['written']} sample(s) from {args.file}" + (f" ({'; '.join(notes)})" if notes else ""))
    failed = tally["skipped"] or tally["refused"] or missing or problem or scan.truncated_at is not None
    return 1 if failed else 0
