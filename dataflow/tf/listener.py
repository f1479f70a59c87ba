"""A frame buffer of this process fed from another process's tree (tf2_ros' ``TransformListener``).

:class:`FrameListener` subscribes to a :class:`~dataflow.tf.FrameServer`'s ``tf_static``
(with ``init``: every static transform at once, as ``/tf_static`` latches) and ``tf``
ports through a component proxy of :mod:`dataflow.remote` (``system.component("tf")``),
and keeps what arrives in its own :class:`~dataflow.tf.FrameBuffer`, to look up here::

    from dataflow.remote import connect
    from dataflow.tf.listener import FrameListener

    system = connect("127.0.0.1:7850")
    with FrameListener(system.component("tf")) as listener:
        pose = listener.buffer.lookup("base_link", "arm_link_5", timeout=2.0)
    system.close()

It knows nothing of gRPC: any object with ``subscribe(port, callback, policy=...)``
returning something with ``close()`` will do. Like a TransformListener, it has what was
published since it subscribed (and every static transform).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Protocol

from dataflow.policy import ConnPolicy

from .buffer import FrameBuffer
from .messages import TFMessage, transforms_of

__all__ = ["FrameListener", "Subscribable"]

log = logging.getLogger(__name__)

ORIGIN = "listener"


class _Closing(Protocol):
    def close(self) -> None: ...


class Subscribable(Protocol):
    """What a listener needs of a component proxy: a subscription it can close."""

    def subscribe(self, port: str, observer: Callable[[Any], None], /, *, policy: ConnPolicy) -> _Closing: ...


class FrameListener:
    """``buffer`` (a new one by default) fed from ``component``'s ``tf_static`` and ``tf``
    ports. Raises what subscribing raises (an unknown component or port). ``close`` is
    idempotent; a context manager."""

    def __init__(self, component: Subscribable, buffer: FrameBuffer | None = None, *, depth: int = 1000) -> None:
        self.buffer = buffer if buffer is not None else FrameBuffer()
        self.received = 0
        self._subs: list[_Closing] = []
        try:
            self._subs.append(component.subscribe("tf_static", lambda e: self._take(e.value, True),
                                                  policy=ConnPolicy.data()))
            self._subs.append(component.subscribe("tf", lambda e: self._take(e.value, False),
                                                  policy=ConnPolicy.circular_buffer(depth)))
        except BaseException:
            self.close()
            raise

    def _take(self, value: object, static: bool) -> None:
        if not isinstance(value, TFMessage):
            log.warning("frame listener: a %s on %s, not a TFMessage: ignored", type(value).__name__,
                        "tf_static" if static else "tf")
            return
        self.received += 1
        self.buffer.receive(transforms_of(value), static=static, authority=ORIGIN, origin=ORIGIN)

    def close(self) -> None:
        """Unsubscribe (idempotent)."""
        subs, self._subs = self._subs, []
        for sub in subs:
            sub.close()

    def __enter__(self) -> FrameListener:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
