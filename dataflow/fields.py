"""Field paths into samples: ``joints[2].position``, ``joints[*].position``.

A path is ``.name`` (a model field or a dict key; the first may omit the dot), ``[N]`` (an
item of a list) and ``[*]`` (every item: the rest of the path applies to each). The bridge
(``scart:bridge field=``) and ``scart echo --field`` use it.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["MAX_PATH_STEPS", "apply_path", "parse_path"]

MAX_PATH_STEPS = 32
_STEP = re.compile(r"\.?([A-Za-z_]\w*)|\[(\*|\d{1,6})\]")


def parse_path(text: str, leading: str | None = None) -> tuple[str | int, ...] | None:
    """``joints[*].position`` → ``("joints", -1, "position")`` (``-1`` stands for ``[*]``);
    None when malformed or longer than :data:`MAX_PATH_STEPS`. A first step equal to
    ``leading`` (a bridge input's own name) is dropped when more follow."""
    steps: list[str | int] = []
    pos = 0
    text = text.strip()
    while pos < len(text):
        m = _STEP.match(text, pos)
        if m is None or (pos == 0 and text.startswith(".")) or len(steps) >= MAX_PATH_STEPS:
            return None
        steps.append(m[1] if m[1] is not None else (-1 if m[2] == "*" else int(m[2])))
        pos = m.end()
    if leading is not None and len(steps) > 1 and steps[0] == leading:
        steps = steps[1:]
    return tuple(steps) if steps else None


def apply_path(value: Any, path: tuple[str | int, ...]) -> Any:
    """The part of ``value`` a parsed path names; raises ``KeyError``, ``IndexError``,
    ``AttributeError`` or ``TypeError`` when the value has no such part."""
    for i, step in enumerate(path):
        if isinstance(step, int) and step < 0:
            return [apply_path(item, path[i + 1:]) for item in value]
        if isinstance(step, int) or isinstance(value, dict):
            value = value[step]
        else:
            value = getattr(value, step)
    return value
