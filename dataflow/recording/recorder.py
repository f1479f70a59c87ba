"""Recording port samples to one MCAP file (what ``scart record`` writes): a
:class:`Recording` is given samples from any thread (a subscription's observer) and writes
them from a thread of its own, each port one channel of JSON messages with a JSON Schema of
its type. Nothing is lost in a crash beyond the last :data:`FLUSH_SECONDS`: samples reach
the disk in chunks written at least that often. A full disk (or a file-size limit) stops
the recording and cuts the file back to its last whole chunk, said in :attr:`Recording.failure`."""

from __future__ import annotations

import errno
import json
import os
import queue
import threading
import time
from typing import TYPE_CHECKING, Any

from dataflow.recording.mcap import Sink
from dataflow.threads import OwnedThread

if TYPE_CHECKING:
    from dataflow.remote import SampleEvent

__all__ = ["FLUSH_SECONDS", "Recording"]

FLUSH_SECONDS = 0.5  #: samples reach the disk at least this often (a kill -9 loses at most this much)
_STOP = object()


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

    def observe(self, event: SampleEvent) -> None:
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

    def _add(self, item: tuple[str, int, float, object]) -> None:
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
