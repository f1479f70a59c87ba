"""YARP's flow control on a link between deployers (``ConnPolicy.wait``; see
:mod:`dataflow.policy`): the writer end of a link whose writer waits holds each sample
until the reader end's buffer has room for it — room = the buffer's size, less what it
holds unread, less what was sent and not yet reported received — and, for ``WAIT_AFTER``,
until the reader end reports it received. The reader end reports at once after each
sample and after each read that frees a slot (its transport does: ``Transport.waits``).

Each wait is bounded by the policy's ``wait_timeout``; a writer with no connection does not
wait (its sample is not sent, counted, as for any writer). Thread-safe: the writer's thread
waits, the transport's thread reports.
"""

from __future__ import annotations

import threading
import time
from collections import deque

from dataflow.policy import ConnPolicy, ConnType, WaitMode

__all__ = ["WriterFlow", "waits"]


def waits(policy: ConnPolicy) -> bool:
    """A writer with ``policy`` can be held back (it waits, and its reader can run out of
    room: a DATA reader always has room)."""
    return policy.wait is not WaitMode.NO_WAIT and policy.type is not ConnType.DATA


class WriterFlow:
    """What a waiting writer end knows of its reader's room (see the module docstring)."""

    def __init__(self, policy: ConnPolicy) -> None:
        self.capacity = max(1, policy.size)
        self.after_sent = policy.wait is WaitMode.WAIT_AFTER
        self.timeout = policy.wait_timeout
        self.waited = 0.0  #: seconds the writer spent waiting, in all
        self._cv = threading.Condition(threading.Lock())
        self._sent: deque[int] = deque()  # write numbers sent and not yet reported received
        self._peer_last = 0
        self._pending = 0

    def _room(self) -> int:
        sent = self._sent
        while sent and sent[0] <= self._peer_last:
            sent.popleft()
        return self.capacity - self._pending - len(sent)

    def before(self) -> bool:
        """Wait until the reader has room for one more sample; False when it did not
        within the timeout (the sample is then refused)."""
        with self._cv:
            if self._room() > 0:
                return True
            started = time.monotonic()
            ok = self._cv.wait_for(lambda: self._room() > 0, self.timeout)
            self.waited += time.monotonic() - started
            return ok

    def sent(self, n: int) -> None:
        """Sample ``n`` left."""
        with self._cv:
            self._sent.append(n)

    def after(self, n: int) -> bool:
        """``WAIT_AFTER``: wait until the reader reported sample ``n`` received (True at
        once otherwise); False on timeout."""
        if not self.after_sent:
            return True
        with self._cv:
            started = time.monotonic()
            ok = self._cv.wait_for(lambda: self._peer_last >= n, self.timeout)
            self.waited += time.monotonic() - started
            return ok

    def reported(self, last: int, pending: int) -> None:
        """The reader end's report: every write up to ``last`` had, ``pending`` unread."""
        with self._cv:
            self._peer_last = max(self._peer_last, last)
            self._pending = pending
            self._cv.notify_all()

    def reset(self) -> None:
        """A new reader end (a first connection, or a restarted peer): it holds nothing yet."""
        with self._cv:
            self._sent.clear()
            self._pending = 0
            self._cv.notify_all()
