"""The frame tree's values on ports: registered types, so they cross processes like any sample.

* :class:`TFMessage` — transforms, as ``tf2_msgs/TFMessage`` carries them (the
  :class:`~dataflow.tf.server.FrameServer`'s ``tf`` and ``tf_static`` ports);
* :class:`FrameTree` — every frame with its parent, rate and age (its ``tree`` port:
  what ``scart tf frames`` prints).
"""

from __future__ import annotations

from pydantic import BaseModel, Field

from scart_wire.types import register_type

from .buffer import MAX_FRAMES, FrameInfo
from .transform import Transform

__all__ = ["FrameTree", "FrameTreeEntry", "StampedTransform", "TFMessage", "message_of", "transforms_of", "tree_entry"]

_NAME = Field(min_length=1, max_length=256)


@register_type("StampedTransform")
class StampedTransform(BaseModel):
    """One transform (``geometry_msgs/TransformStamped``): the pose of ``child_frame_id``
    in ``frame_id`` at ``stamp_ns`` (integer nanoseconds)."""

    frame_id: str = _NAME
    child_frame_id: str = _NAME
    stamp_ns: int = 0
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)


@register_type("TFMessage")
class TFMessage(BaseModel):
    """Transforms published together (``tf2_msgs/TFMessage``)."""

    transforms: list[StampedTransform] = Field(default_factory=list, max_length=MAX_FRAMES)


@register_type("FrameTreeEntry")
class FrameTreeEntry(BaseModel):
    """One frame of a :class:`FrameTree`: its parent, kind, last publisher, how many
    transforms it keeps, their span (s), the rate over it (Hz) and its age (s: the
    tree's time less the newest stamp; 0 when static)."""

    frame: str
    parent: str
    static: bool = False
    authority: str = ""
    kept: int = 0
    oldest: float = 0.0
    newest: float = 0.0
    rate: float = 0.0
    age: float = 0.0


@register_type("FrameTree")
class FrameTree(BaseModel):
    """A frame tree as its server sees it at ``time`` (s): every frame with a parent,
    the roots, the history kept (``cache``, s) and the transforms refused by reason."""

    time: float = 0.0
    cache: float = 0.0
    frames: list[FrameTreeEntry] = Field(default_factory=list, max_length=MAX_FRAMES)
    roots: list[str] = Field(default_factory=list, max_length=MAX_FRAMES)
    refused: dict[str, int] = Field(default_factory=dict, max_length=64)


def message_of(transforms: list[Transform]) -> TFMessage:
    """``transforms`` as one :class:`TFMessage`."""
    return TFMessage(transforms=[StampedTransform(frame_id=t.frame_id, child_frame_id=t.child_frame_id,
                                                  stamp_ns=t.stamp_ns, translation=t.translation,
                                                  rotation=t.rotation) for t in transforms])


def transforms_of(message: TFMessage) -> list[Transform]:
    """The transforms of a :class:`TFMessage`."""
    return [Transform(t.frame_id, t.child_frame_id, t.translation, t.rotation, t.stamp_ns) for t in message.transforms]


def tree_entry(info: FrameInfo, now_ns: int) -> FrameTreeEntry:
    """One :class:`FrameInfo` as a :class:`FrameTreeEntry`, its age at ``now_ns``."""
    return FrameTreeEntry(frame=info.name, parent=info.parent, static=info.static, authority=info.authority,
                          kept=info.kept, oldest=info.oldest_ns / 1e9, newest=info.newest_ns / 1e9, rate=info.rate,
                          age=0.0 if info.static else (now_ns - info.newest_ns) / 1e9)
