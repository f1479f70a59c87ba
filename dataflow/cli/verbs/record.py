"""Record and replay samples as MCAP files: ``scart record | play | info``.

* ``scart record PORT... -o run.mcap`` (or ``-a``: every output port the name service's
  tasks have) subscribes to each output port (``BUFFER`` policy: nothing is lost while the
  file is written) and writes every sample to an MCAP file: one channel per port (topic
  ``task.port``), JSON messages with a JSON Schema of the port's type (what the Foxglove
  app and ``mcap`` tools read), ``log_time`` when it arrived and ``publish_time`` when the
  task stored it. It stops after ``--duration`` s, ``-n`` samples, or Ctrl-C/SIGTERM; the
  file is always closed complete (summary and index).
* ``scart play run.mcap`` writes the samples again, in order, to the *input* ports of the
  same names (or ``--remap old.port=new.port``), at the recorded pace scaled by
  ``--rate`` (absolute deadlines: no drift), or one by one on Enter with ``--step``.
* ``scart info run.mcap`` lists the channels with their counts, rates and the duration.

Files are read with a bound (:data:`MAX_MESSAGE_BYTES` per message, a message count bound
in ``play``); a message that is not JSON is skipped and counted.
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

__all__ = ["MAX_MESSAGE_BYTES", "register"]

MAX_MESSAGE_BYTES = 4 << 20
MAX_RECORDED_PORTS = 256
_STOP = object()


def register(verb: Callable[[str, str, Callable[[argparse.Namespace], int]], argparse.ArgumentParser],
             subparsers: argparse._SubParsersAction) -> None:  # noqa: SLF001
    """Add ``record`` and ``play`` (through the inspection verbs' ``verb``: they reach a
    name service) and ``info`` (a file only)."""
    p = verb("record", "record output ports to an MCAP file", cmd_record)
    p.add_argument("ports", nargs="*", metavar="COMP.PORT")
    p.add_argument("-a", "--all", action="store_true", help="every output port of every task the name service lists")
    p.add_argument("-o", "--output", required=True, help="the .mcap file to write")
    p.add_argument("-n", type=int, default=None, help="stop after N samples in all")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p = verb("play", "replay an MCAP file into input ports", cmd_play)
    p.add_argument("file")
    p.add_argument("--rate", type=float, default=1.0, help="pace: 2 = twice as fast (default 1)")
    p.add_argument("--step", action="store_true", help="one sample per Enter on stdin")
    p.add_argument("--remap", action="append", default=[], metavar="OLD.PORT=NEW.PORT",
                   help="write OLD.PORT's samples to NEW.PORT (repeatable)")
    info = subparsers.add_parser("info", help="channels, counts, rates and duration of an MCAP file")
    info.add_argument("file")
    info.add_argument("--json", action="store_true", help="JSON on stdout")
    info.set_defaults(func=cmd_info)


# ---- record ------------------------------------------------------------------------------

def type_schema(type_name: str) -> dict[str, Any]:
    """The JSON Schema of a registry type (pydantic's; ``{"title": name}``, any JSON, when
    this process does not know the type or pydantic cannot describe it)."""
    import pydantic

    from dataflow import registry

    py_type = registry.python_type(type_name)
    if py_type is None:
        return {"title": type_name}
    try:
        return pydantic.TypeAdapter(py_type).json_schema()
    except Exception:  # noqa: BLE001 - a type pydantic cannot describe: any JSON
        return {"title": type_name}


def _schema_of(type_name: str) -> dict[str, Any]:
    """A message's JSON Schema: the type's, a non-object wrapped as ``{"value": ...}``
    (Foxglove wants objects); ``{"title": name}`` for a type unknown here."""
    from dataflow import registry

    schema = type_schema(type_name)
    if registry.python_type(type_name) is not None and schema.get("type") != "object":
        schema = {"title": type_name, "type": "object", "properties": {"value": schema}}
    return schema


def message_of(value: Any) -> dict[str, Any]:
    """A sample as a JSON message: its JSON form, a non-object wrapped as ``{"value": ...}``
    (the shape :func:`_schema_of` describes)."""
    from dataflow import registry

    data = registry.to_jsonable(value)
    return data if isinstance(data, dict) else {"value": data}


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
    out = []
    for task, port in dict.fromkeys(wanted):
        ports = ports_of(task)
        info = ports.get(port)
        if info is None or info.direction != "out":
            raise ValueError(f"{task} has no output port {port!r}; outputs: "
                             f"{', '.join(n for n, p in ports.items() if p.direction == 'out') or 'none'}")
        out.append((task, port, info.type_name))
    return out


def cmd_record(args: argparse.Namespace) -> int:
    """``scart record PORT... -o FILE``: see the module docstring."""
    from mcap.writer import Writer

    from dataflow import ConnPolicy
    from dataflow.cli.inspect import _err, _out, _stopped_by_signals, _wait_until_stopped

    ports = _ports_to_record(args)
    samples: queue.SimpleQueue[Any] = queue.SimpleQueue()
    done = threading.Event()
    counts = {f"{t}.{p}": 0 for t, p, _ in ports}
    with open(args.output, "wb") as fh:
        writer = Writer(fh)
        writer.start(profile="", library="scart")
        channels = {}
        for task, port, type_name in ports:
            schema_id = writer.register_schema(name=type_name, encoding="jsonschema",
                                               data=json.dumps(_schema_of(type_name)).encode())
            channels[f"{task}.{port}"] = writer.register_channel(
                topic=f"{task}.{port}", message_encoding="json", schema_id=schema_id,
                metadata={"type_name": type_name})

        def observer(event: Any) -> None:
            samples.put((f"{event.component}.{event.port}", time.time_ns(), event.source_time, event.value))

        subs = []
        drain = threading.Thread(target=_write_samples, name="scart-record-writer",
                                 args=(writer, channels, samples, counts, args.n, done), daemon=True)
        drain.start()
        try:
            with _stopped_by_signals(done):  # before it says Ctrl-C stops it
                for task, port, _ in ports:
                    subs.append(args.system.component(task).subscribe(port, observer,
                                                                      policy=ConnPolicy.buffer(10_000)))
                _err(f"record: {len(ports)} port(s) to {args.output}; Ctrl-C to stop")
                _wait_until_stopped(done, args.duration)
        finally:
            for sub in subs:
                sub.close()
            samples.put(_STOP)
            drain.join(30)
            if drain.is_alive():  # never finish a file the writer thread is still writing
                raise RuntimeError("record: the writer thread did not finish within 30 s; the file is incomplete")
            writer.finish()
    total = sum(counts.values())
    _out(json.dumps({"file": args.output, "samples": total, "channels": counts}) if args.json
         else f"recorded {total} sample(s) to {args.output}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0


def _write_samples(writer: Any, channels: dict[str, int], samples: queue.SimpleQueue[Any], counts: dict[str, int],
                   limit: int | None, done: threading.Event) -> None:
    """The writer thread: every queued sample to the file until the stop mark (or ``limit``)."""
    total = 0
    for item in iter(samples.get, _STOP):  # ends at the stop mark
        topic, log_ns, source_time, value = item
        if limit is not None and total >= limit:
            done.set()
            continue
        data = message_of(value)
        counts[topic] += 1
        total += 1
        publish_ns = int(source_time * 1e9) if source_time else log_ns
        writer.add_message(channel_id=channels[topic], log_time=log_ns, publish_time=publish_ns,
                           sequence=counts[topic], data=json.dumps(data).encode())
        if limit is not None and total >= limit:
            done.set()


# ---- read ----------------------------------------------------------------------------------

def _messages(path: str) -> Any:
    """``(topic, log_time ns, decoded JSON or None)`` of each message of ``path``, in log-time order."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        reader = make_reader(fh)
        for _schema, channel, message in reader.iter_messages(log_time_order=True):
            data = None
            if len(message.data) <= MAX_MESSAGE_BYTES:
                try:
                    data = json.loads(message.data)
                except ValueError:
                    data = None
            yield channel.topic, message.log_time, data


def cmd_info(args: argparse.Namespace) -> int:
    """``scart info FILE``: channels, counts, rates, duration."""
    from mcap.reader import make_reader

    from dataflow.cli.inspect import _dump, _out

    try:
        with open(args.file, "rb") as fh:
            summary = make_reader(fh).get_summary()
    except (OSError, ValueError, Exception) as exc:  # noqa: BLE001 - any unreadable file: one line
        print(f"scart info: {args.file}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    if summary is None or summary.statistics is None:
        print(f"scart info: {args.file}: no summary (a file still being written, or cut short)", file=sys.stderr)
        return 1
    stats = summary.statistics
    duration = max(0.0, (stats.message_end_time - stats.message_start_time) / 1e9)
    channels = []
    for cid, channel in sorted(summary.channels.items()):
        count = stats.channel_message_counts.get(cid, 0)
        schema = summary.schemas.get(channel.schema_id)
        channels.append({"topic": channel.topic, "type": schema.name if schema else "", "count": count,
                         "rate": round(count / duration, 2) if duration > 0 else 0.0})
    doc = {"file": args.file, "duration": round(duration, 6), "messages": stats.message_count, "channels": channels}
    if args.json:
        _out(_dump(doc))
        return 0
    _out(f"{args.file}: {stats.message_count} message(s) over {duration:.3f} s")
    for c in channels:
        _out(f"  {c['topic']:<40} {c['type']:<20} {c['count']:>8} msgs {c['rate']:>9.1f} Hz")
    return 0


# ---- play -----------------------------------------------------------------------------------

def cmd_play(args: argparse.Namespace) -> int:
    """``scart play FILE``: see the module docstring."""
    from dataflow.cli.inspect import _err, _out
    from dataflow.remote.api import split_port

    if not (0 < args.rate <= 1000):
        raise ValueError(f"--rate {args.rate}: expected 0 < rate ≤ 1000")
    remap: dict[str, str] = {}
    for item in args.remap:
        old, sep, new = item.partition("=")
        split_port(old.strip()), split_port(new.strip())
        if not sep:
            raise ValueError(f"--remap {item!r}: expected OLD.PORT=NEW.PORT")
        remap[old.strip()] = new.strip()
    proxies: dict[str, Any] = {}
    written = skipped = 0
    start_wall = first_log = None
    for topic, log_ns, data in _messages(args.file):
        target = remap.get(topic, topic)
        if data is None:
            skipped += 1
            continue
        if args.step:
            _err(f"{target} ← {json.dumps(data)[:100]}  (Enter: write, Ctrl-D: stop)")
            if not sys.stdin.readline():
                break
        else:
            if start_wall is None:
                start_wall, first_log = time.monotonic(), log_ns
            due = start_wall + (log_ns - first_log) / 1e9 / args.rate  # absolute deadline: no drift
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        task, port = split_port(target)
        if task not in proxies:
            proxies[task] = args.system.component(task)
        value = data["value"] if set(data) == {"value"} else data
        status = proxies[task].write_json(port, value)
        if status.name != "WRITE_SUCCESS":
            _err(f"play: {target}: {status.name}")
        written += 1
    _out(json.dumps({"file": args.file, "written": written, "skipped": skipped}) if args.json
         else f"played {written} sample(s) from {args.file}" + (f" ({skipped} unreadable, skipped)" if skipped else ""))
    return 0
