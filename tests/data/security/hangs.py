"""Components whose start never returns: a task's ``start_hook`` and a Python component's
``@init``. Each says on stderr that it began, so a test knows the start is underway."""

from __future__ import annotations

import sys
import threading

import scart
from dataflow import TaskContext

_NEVER = threading.Event()


def _begin(what: str) -> None:
    print(f"hangs: {what} began", file=sys.stderr, flush=True)
    _NEVER.wait()  # never set: the hang of the probe


class SlowStart(TaskContext):
    """A task whose start_hook does not return."""

    def start_hook(self) -> bool:
        _begin("start_hook")
        return True


@scart.component
class SlowInit:
    """A component whose @init does not return."""

    @scart.init
    def open(self) -> None:
        _begin("@init")

    def ping(self) -> str:
        return "pong"
