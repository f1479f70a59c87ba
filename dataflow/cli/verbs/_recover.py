"""``scart record --recover FILE [-o OUT]``: a complete copy of a recording cut short (a
``kill -9``, a full disk), as ``mcap recover`` writes one: every schema, channel and
message that can be read, then a summary and index. Not a verb of its own: ``record``
runs it."""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from typing import TYPE_CHECKING

from scart_wire.console import dump, err, out

if TYPE_CHECKING:
    from mcap.records import McapRecord
    from mcap.writer import Writer

__all__ = ["recover"]


def recover(args: argparse.Namespace) -> int:
    """Copy ``args.recover`` to ``args.output`` (default ``FILE-recovered.mcap``); 0 when
    a copy was written, 1 (one line) when the source cannot be read at all."""
    from dataflow.recording.mcap import McapError, McapScan

    source = args.recover
    target = _target(args)
    if target is None:
        return 1
    scan = McapScan(source)
    records = scan.records()
    try:
        first = next(records, None)  # a file that is no MCAP at all: said before anything is written
    except McapError as exc:
        err(f"record --recover: {source}: {exc}")
        return 1
    try:
        copied, stopped = _write_copy(target, args.overwrite, [first] if first is not None else [], records)
    except ValueError as exc:
        err(f"record --recover: {exc}")
        return 1
    state = (f"truncated at byte {scan.truncated_at}" if scan.truncated_at is not None
             else "complete" if scan.complete else "cut short")
    doc = {"file": source, "output": target, "messages": copied, "source": state, "stopped_at": stopped}
    out(dump(doc) if args.json else
        f"recovered {copied} message(s) from {source} ({state}) into {target}" + (f"; stopped at {stopped}" if stopped else ""))
    return 0


def _target(args: argparse.Namespace) -> str | None:
    """Where the copy goes (``-o``, else ``FILE-recovered.mcap``), or None after saying why not."""
    from dataflow.recording.mcap import output_problem

    stem, ext = os.path.splitext(args.recover)
    target = args.output or f"{stem}-recovered{ext or '.mcap'}"
    problem = output_problem(target, args.overwrite)
    if problem is None and os.path.abspath(target) == os.path.abspath(args.recover):
        problem = f"-o {target}: the file to recover; give another name"
    if problem is not None:
        err(f"record --recover: {problem}")
        return None
    return target


def _write_copy(target: str, overwrite: bool, head: list[McapRecord],
                records: Iterator[McapRecord]) -> tuple[int, str]:
    """A complete MCAP file at ``target`` of ``head`` then ``records``: see :func:`_copy`.
    Raises ``ValueError`` when the file cannot be made."""
    from mcap.writer import Writer

    from dataflow.recording.mcap import Sink, open_output

    fd = open_output(target, overwrite)
    try:
        writer = Writer(Sink(fd))  # type: ignore[arg-type]  # mcap wants an IO; a Sink has what it uses: write, tell, flush
        writer.start(profile="", library="scart")
        copied, stopped = _copy(writer, head, records)
        writer.finish()
    finally:
        os.close(fd)
    return copied, stopped


def _copy(writer: Writer, head: list[McapRecord], records: Iterator[McapRecord]) -> tuple[int, str]:
    """Every record to ``writer`` (ids renumbered); ``(messages copied, where a malformed
    part stopped the copy or "")``."""
    from mcap import records as kinds

    from dataflow.recording.mcap import McapError

    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    copied = 0

    def one(record: McapRecord) -> None:
        nonlocal copied
        if isinstance(record, kinds.Schema):
            schema_ids[record.id] = writer.register_schema(record.name, record.encoding, record.data)
        elif isinstance(record, kinds.Channel):
            channel_ids[record.id] = writer.register_channel(
                record.topic, record.message_encoding, schema_ids.get(record.schema_id, 0), dict(record.metadata))
        elif isinstance(record, kinds.Message) and record.channel_id in channel_ids:
            writer.add_message(channel_ids[record.channel_id], record.log_time, record.data, record.publish_time,
                               record.sequence)
            copied += 1

    for record in head:
        one(record)
    try:
        for record in records:
            one(record)
    except McapError as exc:
        return copied, str(exc)
    return copied, ""
