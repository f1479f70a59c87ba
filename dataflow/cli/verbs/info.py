"""``scart info FILE.mcap``: the channels of an MCAP file (topic, type, messages, rate)
and its duration, read with the bounds of :mod:`dataflow.recording.mcap`. A file cut short
(a recording killed, a full disk) is read as far as it goes, and said to be truncated
(``scart record --recover`` finishes it); a file that is not a readable MCAP file gets
one line saying what is wrong, and exit 1."""

from __future__ import annotations

import argparse
from typing import TypedDict

from scart_wire.console import dump, err, out

HELP = "channels, counts, rates and duration of an MCAP file"


class ChannelRow(TypedDict):
    """One channel of :func:`describe`'s answer."""

    topic: str
    type: str
    count: int
    rate: float
    declared: bool


class FileInfo(TypedDict):
    """What :func:`describe` says of a file (``scart info --json``)."""

    file: str
    duration: float
    messages: int
    channels: list[ChannelRow]
    truncated: bool
    truncated_at: int | None
    undeclared: int


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The file and ``--json``."""
    parser.add_argument("file")
    parser.add_argument("--json", action="store_true", help="JSON on stdout")


def main(args: argparse.Namespace) -> int:
    """Describe the file; 1 (one line) when it cannot be read."""
    from dataflow.recording.mcap import McapError

    try:
        doc = describe(args.file)
    except McapError as exc:
        err(f"info: {args.file}: {exc}")
        return 1
    if doc["truncated"]:
        err(f"info: {args.file}: truncated at byte {doc['truncated_at']} (a recording cut short): what comes before "
            f"is listed; `scart record --recover {args.file}` writes a complete copy")
    if doc["undeclared"]:
        err(f"info: {args.file}: {doc['undeclared']} message(s) of channels the file never declares (listed as "
            "undeclared; scart play stops at the first)")
    if args.json:
        out(dump(doc))
        return 0
    out(f"{args.file}: {doc['messages']} message(s) over {doc['duration']:.3f} s"
        + (" (truncated)" if doc["truncated"] else ""))
    for c in doc["channels"]:
        out(f"  {c['topic']:<40} {c['type']:<20} {c['count']:>8} msgs {c['rate']:>9.1f} Hz")
    return 0


def describe(path: str) -> FileInfo:
    """What ``scart info --json`` prints: ``file``, ``duration`` (s), ``messages``,
    ``channels`` (``topic``, ``type``, ``count``, ``rate``, ``declared``: a message may name
    a channel the file never declares; it is counted in its own row, so the rows add up
    to ``messages``), ``undeclared`` (those messages), ``truncated`` and
    ``truncated_at``. Raises :class:`~dataflow.recording.mcap.McapError`."""
    from mcap import records as kinds

    from dataflow.recording.mcap import McapScan

    scan = McapScan(path)
    counts: dict[int, int] = {}
    start = end = None
    for record in scan.records():
        if isinstance(record, kinds.Message):
            counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
            start = record.log_time if start is None else min(start, record.log_time)
            end = record.log_time if end is None else max(end, record.log_time)
    duration = max(0.0, ((end or 0) - (start or 0)) / 1e9)
    channels: list[ChannelRow] = []
    for cid in sorted(set(scan.channels) | set(counts)):  # a channel the file never declares has its row too
        channel = scan.channels.get(cid)
        schema = scan.schemas.get(channel.schema_id) if channel is not None else None
        count = counts.get(cid, 0)
        channels.append({"topic": channel.topic if channel is not None else f"(channel {cid}, undeclared)",
                         "type": schema.name if schema else "", "count": count,
                         "rate": round(count / duration, 2) if duration > 0 else 0.0,
                         "declared": channel is not None})
    return {"file": path, "duration": round(duration, 6), "messages": sum(counts.values()), "channels": channels,
            "truncated": scan.truncated_at is not None, "truncated_at": scan.truncated_at,
            "undeclared": sum(c["count"] for c in channels if not c["declared"])}
