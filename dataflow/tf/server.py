"""The frame tree as a task: :class:`FrameServer`, the transform server of seed 001.

YARP's ``transformServer`` keeps the frames of ``/tf`` and ``/tf_static`` and answers the
``transformClient`` s that query and publish them. Here the tree is the process's
:class:`~dataflow.tf.FrameBuffer` (``deployer.frames``, which every task reads as
``self.frames``), and this task is its face to the rest of the system, found through the
name service like any task (``scart describe tf``):

=================  ====================================================================
``tf`` (out)       every batch of dynamic transforms stored, whoever published it
                   (:class:`~dataflow.tf.messages.TFMessage`): what a listener of
                   another process follows, as tf2_ros' ``TransformListener`` follows ``/tf``
``tf_static``      every static transform, all together, again each time one changes
(out)              (a subscriber with ``init`` gets them at once, as ``/tf_static`` latches)
``tree`` (out)     the frames with their parent, rate and age
                   (:class:`~dataflow.tf.messages.FrameTree`), every ``period`` s and at
                   start: what ``scart tf frames`` prints
``lookup``,        operations: tf2's two ``lookupTransform`` forms, answered from the tree
``lookup_full``
``cache``          property: seconds of history per dynamic frame (10, as tf2)
=================  ====================================================================

With ``ros1`` and/or ``ros2`` options it also joins the tree to ROS's ``/tf`` and
``/tf_static`` (:mod:`dataflow.tf.ros`) while it runs: started by ``start_hook`` (a ROS
that cannot be joined refuses the start, saying why), left by ``stop_hook``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping

from dataflow.activities import PeriodicActivity
from dataflow.errors import DataflowError
from dataflow.operations import operation
from dataflow.ports import OutputPort
from dataflow.properties import Property
from dataflow.task import TaskContext
from dataflow.transports import TransportError

from .buffer import DEFAULT_CACHE, MAX_CACHE, FrameBuffer
from .messages import FrameTree, StampedTransform, TFMessage, message_of, tree_entry
from .ros import Ros1Frames, Ros2Frames, RosFrames
from .transform import Transform

__all__ = ["FrameServer"]

log = logging.getLogger(__name__)


def _stamped(t: Transform) -> StampedTransform:
    return StampedTransform(frame_id=t.frame_id, child_frame_id=t.child_frame_id, stamp_ns=t.stamp_ns,
                            translation=t.translation, rotation=t.rotation)


class FrameServer(TaskContext):
    """The process's frame tree as a task (see the module docstring). ``buffer``: the tree
    (a deployer's ``frames``); ``ros1``/``ros2``: the options of the ROS to join (None: not
    that one; ``{}``: the process's defaults); ``period``: s between ``tree`` samples."""

    tf: OutputPort[TFMessage] = OutputPort(TFMessage, doc="every batch of dynamic transforms stored")
    tf_static: OutputPort[TFMessage] = OutputPort(TFMessage, doc="every static transform, again at each change")
    tree: OutputPort[FrameTree] = OutputPort(FrameTree, doc="the frames, their parents, rates and ages, every period")
    cache = Property(float, DEFAULT_CACHE, doc="seconds of history each dynamic frame keeps", gt=0.0, le=MAX_CACHE)

    def __init__(self, name: str = "tf", buffer: FrameBuffer | None = None, *,
                 ros1: Mapping[str, str] | None = None, ros2: Mapping[str, str] | None = None,
                 period: float = 1.0) -> None:
        super().__init__(name)
        self.buffer = buffer if buffer is not None else FrameBuffer()
        self.frames = self.buffer
        self.ros1, self.ros2 = (dict(ros1) if ros1 is not None else None), (dict(ros2) if ros2 is not None else None)
        self._ros: list[RosFrames] = []
        self._unhook: Callable[[], None] | None = None
        self.failure = ""  #: why the last start was refused ("" when it was not)
        self.set_activity(PeriodicActivity(period))
        self._prop_values["cache"] = self.buffer.cache_time

    def configure_hook(self) -> bool:
        self.buffer.cache_time = self.cache
        return True

    def start_hook(self) -> bool:
        """Follow the tree on the ports; join the ROS asked for (a failure refuses the start,
        :attr:`failure` says why)."""
        self.failure = ""
        self.buffer.cache_time = self.cache
        self._unhook = self.buffer.on_publish(self._on_publish)
        self._write_statics()
        self.update_hook()
        try:
            if self.ros1 is not None:
                self._ros.append(Ros1Frames(self.buffer, self.ros1))
            if self.ros2 is not None:
                self._ros.append(Ros2Frames(self.buffer, self.ros2))
        except TransportError as exc:
            self.failure = f"cannot join ROS's /tf: {exc}"
            log.error("%s: %s", self.name, self.failure)
            self.stop_hook()
            return False
        return True

    def update_hook(self) -> None:
        """Write the tree's description on ``tree``."""
        now = time.time_ns()
        buffer = self.buffer
        self.tree.write(FrameTree(time=now / 1e9, cache=buffer.cache_time,
                                  frames=[tree_entry(f, now) for f in buffer.frames()], roots=buffer.roots(),
                                  refused=buffer.refused))

    def stop_hook(self) -> None:
        """Leave ROS, stop following the tree (idempotent)."""
        ros, self._ros = self._ros, []
        for bridge in reversed(ros):
            bridge.close()
        unhook, self._unhook = self._unhook, None
        if unhook is not None:
            unhook()

    def _on_publish(self, transforms: list[Transform], static: bool, origin: str) -> None:
        if static:
            self._write_statics()
        elif self.tf.connected() or self.tf._fanout is not None:  # a connection, or channel ends (other processes)
            self.tf.write(message_of(transforms))

    def _write_statics(self) -> None:
        self.tf_static.write(message_of(self.buffer.statics()))

    @operation
    def lookup(self, target: str, source: str, time: float = 0.0) -> StampedTransform:
        """The pose of ``source`` in ``target`` at ``time`` (s; 0: the newest the path has)."""
        return _stamped(self._checked(lambda: self.buffer.lookup(target, source, time)))

    @operation
    def lookup_full(self, target: str, target_time: float, source: str, source_time: float,
                    fixed: str) -> StampedTransform:
        """Where ``source`` was at ``source_time``, seen from ``target`` at ``target_time``,
        through ``fixed`` (a frame constant in time)."""
        return _stamped(self._checked(lambda: self.buffer.lookup(target, target_time, source, source_time, fixed)))

    @staticmethod
    def _checked(attempt: Callable[[], Transform]) -> Transform:
        try:
            found: Transform = attempt()
        except DataflowError:
            raise
        except (TypeError, ValueError) as exc:
            raise DataflowError(str(exc)) from None
        return found

    def bridges(self) -> list[RosFrames]:
        """The ROS this tree is joined to now."""
        return list(self._ros)
