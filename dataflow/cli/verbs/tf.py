"""``scart tf echo SOURCE TARGET`` and ``scart tf frames [--dot]``: a running process's frame
tree, as ROS's ``tf_echo`` and ``view_frames`` show theirs.

The tree is the task a composite's ``<scart:frames>`` hosts (``tf`` unless ``--server``
names another), found through the name service as every verb finds a task. ``echo`` is a
listener, as ``tf_echo`` is: it follows the task's ``tf_static`` and ``tf`` ports into a
tree of its own (:class:`dataflow.tf.listener.FrameListener`) and, ``--rate`` times a
second, prints the pose of TARGET in SOURCE at the newest time both have — the argument
order and the output of ``tf_echo``. ``frames`` prints the task's ``tree`` sample: each
frame under its parent with its rate, age, history kept and last publisher. Both only
subscribe (a ``read`` token is enough where tokens are checked), so neither needs ROS,
and both work wherever the name service is reachable.
"""

from __future__ import annotations

import argparse
import math
import threading
import time
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, err, out, stopped_by_signals

if TYPE_CHECKING:
    from dataflow.remote import ComponentProxy, SampleEvent
    from dataflow.tf.buffer import Transform
    from dataflow.tf.messages import FrameTree, FrameTreeEntry

HELP = "a running frame tree: echo a transform (as tf_echo), list the frames (as view_frames)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``echo SOURCE TARGET`` or ``frames [--dot]``, ``--server``, and the common options."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    echo = actions.add_parser("echo", help="print TARGET's pose in SOURCE, as tf_echo SOURCE TARGET",
                              description="Print the pose of TARGET in SOURCE at the newest time both have, "
                                          "--rate times a second (tf_echo's order and output).")
    echo.add_argument("source", metavar="SOURCE", help="the frame the pose is given in")
    echo.add_argument("target", metavar="TARGET", help="the frame whose pose is printed")
    echo.add_argument("-r", "--rate", type=float, default=1.0, help="prints per second (default 1, as tf_echo)")
    echo.add_argument("-n", type=int, default=None, help="stop after N prints")
    echo.add_argument("--once", action="store_true", help="print once, then stop (as -n 1)")
    echo.add_argument("--duration", type=float, default=None,
                      help="stop after this many seconds (default: none; with -n or --once, 10)")
    frames = actions.add_parser("frames", help="the frames with their parents, rates and ages (as view_frames)",
                                description="The frame tree: each frame under its parent, with its rate, age, "
                                            "the history kept and who published it.")
    frames.add_argument("--dot", action="store_true", help="the tree for Graphviz (dot -Tsvg), as view_frames draws it")
    for sub in (echo, frames):
        sub.add_argument("--server", default="tf", help="the frame tree's task (default tf: <scart:frames>'s)")
        add_common(sub)


def main(args: argparse.Namespace) -> int:
    """Echo or list; 1 when the tree cannot be reached or the transform never could be looked up."""
    if args.action == "echo":
        if args.once:
            args.n = 1
        for what, value in (("--rate", args.rate), ("-n", args.n), ("--duration", args.duration)):
            if value is not None and (not math.isfinite(value) or value <= 0):
                err(f"tf echo: {what} {value}: more than 0")
                return 2
        return with_system(args, _echo)
    return with_system(args, _frames)


def _server(args: argparse.Namespace) -> ComponentProxy:
    """The component serving the frame tree, checked to exist."""
    from dataflow import NotFoundError

    try:
        proxy = args.system.component(args.server)
        proxy.describe()
    except NotFoundError as exc:
        raise ValueError(f"{exc}; a composite serves its frame tree with <scart:frames/> (or --server NAME)") \
            from None
    return proxy


# ---- echo ------------------------------------------------------------------------------
def _echo(args: argparse.Namespace) -> int:
    from dataflow.tf import TransformError
    from dataflow.tf.listener import FrameListener

    done = threading.Event()
    duration = args.duration if args.duration is not None else (10.0 if args.n is not None else None)
    printed, said = 0, ""
    with stopped_by_signals(done), FrameListener(_server(args)) as listener:
        deadline = None if duration is None else time.monotonic() + duration
        while not done.is_set():
            try:
                seen = listener.buffer.lookup(args.source, args.target)
            except TransformError as exc:
                if str(exc) != said:  # each new reason once, as tf_echo keeps trying
                    said = str(exc)
                    err(f"tf echo: waiting: {said}")
            else:
                _print(seen, args.json)
                printed += 1
                if args.n is not None and printed >= args.n:
                    break
            wait = 1.0 / args.rate if deadline is None else min(1.0 / args.rate, deadline - time.monotonic())
            if wait <= 0 or done.wait(wait):
                break
    if not printed:
        err(f"tf echo: no transform from {args.source} to {args.target}" + (f": {said}" if said else ""))
        return 1
    return 0


def _print(seen: Transform, as_json: bool) -> None:
    roll, pitch, yaw = seen.rpy
    if as_json:
        out(dump({"time": seen.stamp, "frame_id": seen.frame_id, "child_frame_id": seen.child_frame_id,
                  "translation": list(seen.translation), "rotation": list(seen.rotation),
                  "rpy": [roll, pitch, yaw]}))
        return
    degrees = [math.degrees(a) for a in (roll, pitch, yaw)]
    out(f"At time {seen.stamp:.3f}\n"
        f"- Translation: [{', '.join(f'{v:.3f}' for v in seen.translation)}]\n"
        f"- Rotation: in Quaternion [{', '.join(f'{v:.3f}' for v in seen.rotation)}]\n"
        f"            in RPY (radian) [{roll:.3f}, {pitch:.3f}, {yaw:.3f}]\n"
        f"            in RPY (degree) [{', '.join(f'{v:.3f}' for v in degrees)}]")


# ---- frames ----------------------------------------------------------------------------
def _frames(args: argparse.Namespace) -> int:
    from dataflow import ConnPolicy
    from dataflow.tf.messages import FrameTree

    got: list[object] = []
    arrived = threading.Event()

    def take(event: SampleEvent) -> None:
        if not got:
            got.append(event.value)
            arrived.set()

    sub = _server(args).subscribe("tree", take, policy=ConnPolicy.data())
    try:
        if not arrived.wait(max(args.timeout, 1.5)):  # the tree is written every second, and at once with init
            raise ValueError(f"{args.server}.tree: no frame tree arrived within {max(args.timeout, 1.5):g} s")
    finally:
        sub.close()
    tree = got[0]
    if not isinstance(tree, FrameTree):
        raise ValueError(f"{args.server}.tree carries a {type(tree).__name__}, not a FrameTree: is it a frame tree?")
    if args.json:
        out(dump(tree.model_dump(mode="json")))
    else:
        out(_dot(tree) if args.dot else _table(tree))
    return 0


def _rate(entry: FrameTreeEntry) -> str:
    return "static" if entry.static else f"{entry.rate:.1f} Hz"


def _rows(tree: FrameTree) -> list[tuple[int, FrameTreeEntry | str]]:
    """(depth, entry or root name) in tree order: each frame under its parent."""
    children: dict[str, list[FrameTreeEntry]] = {}
    for entry in tree.frames:
        children.setdefault(entry.parent, []).append(entry)
    rows: list[tuple[int, FrameTreeEntry | str]] = []
    stack: list[tuple[int, FrameTreeEntry | str]] = [(0, root) for root in reversed(tree.roots)]
    while stack and len(rows) <= len(tree.frames) + len(tree.roots):
        depth, item = stack.pop()
        rows.append((depth, item))
        name = item if isinstance(item, str) else item.frame
        stack += [(depth + 1, c) for c in sorted(children.get(name, []), key=lambda c: c.frame, reverse=True)]
    return rows


def _table(tree: FrameTree) -> str:
    lines = [("FRAME", "PARENT", "RATE", "AGE", "KEPT", "BY")]
    for depth, item in _rows(tree):
        indent = "  " * depth
        if isinstance(item, str):
            lines.append((indent + item, "-", "", "", "", ""))
            continue
        span = f"{item.newest - item.oldest:.2f} s" if not item.static else "all time"
        lines.append((indent + item.frame, item.parent, _rate(item), "-" if item.static else f"{item.age:.3f} s",
                      f"{item.kept} ({span})", item.authority or "?"))
    widths = [max(len(row[i]) for row in lines) for i in range(6)]
    text = "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip() for row in lines)
    footer = f"\n{len(tree.frames)} frame(s), {tree.cache:g} s kept per frame"
    if tree.refused:
        footer += "; refused: " + ", ".join(f"{n} {why}" for why, n in sorted(tree.refused.items()))
    return text + footer


def _dot(tree: FrameTree) -> str:
    lines = ["digraph frames {", f'  label="frame tree at {tree.time:.3f} s, {tree.cache:g} s kept";']
    for entry in tree.frames:
        recent = "static" if entry.static else f"{entry.newest:.3f} ({entry.age:.3f} s old)"
        label = (f"Broadcaster: {entry.authority or '?'}\\nAverage rate: {_rate(entry)}\\n"
                 f"Most recent transform: {recent}\\nBuffer length: {entry.newest - entry.oldest:.3f} s")
        lines.append(f'  "{_quoted(entry.parent)}" -> "{_quoted(entry.frame)}" [label="{label}"];')
    lines.append("}")
    return "\n".join(lines)


def _quoted(name: str) -> str:
    return name.replace("\\", "\\\\").replace('"', '\\"')
