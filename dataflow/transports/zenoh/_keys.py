"""Zenoh key scheme of scart (private; see :mod:`dataflow.transports.zenoh`)."""

from __future__ import annotations

import re
from urllib.parse import quote

from dataflow.transports.limits import MAX_FRAME_BYTES

__all__ = ["DEFAULT_NS", "ENCODING_PREFIX", "MAX_PAYLOAD", "MAX_REPLIES", "ROOT", "SERVED", "check_topic", "key_of",
           "served_key"]

DEFAULT_NS = "default"
ROOT = "scart"
SERVED = "scart-served"  #: root of the tokens saying where a component is served
MAX_REPLIES = 10_000  #: liveliness replies read per lookup, at most
ENCODING_PREFIX = "scart.dataflow.v1.Value;"
MAX_PAYLOAD = MAX_FRAME_BYTES  #: bytes of one sample, at most: a writer refuses more, a subscriber decodes no more
_WORD = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,127}$")


def key_of(ns: str, component: str, port: str | None = None) -> str:
    """The key of a component (its liveliness token) or of one of its output ports.
    Raises ``ValueError`` for a name that is no single key chunk."""
    parts = [ns, component] + ([port] if port is not None else [])
    for part in parts:
        if not _WORD.match(part):
            raise ValueError(f"{part!r} cannot be a Zenoh key chunk (letters, digits, _ . -; at most 128)")
    return "/".join([ROOT, *parts])


def served_key(ns: str, component: str, address: str, boot_id: str) -> str:
    """The liveliness token saying that the deployer at ``address`` (gRPC), process
    ``boot_id``, serves ``component``."""
    key_of(ns, component)
    return f"{SERVED}/{ns}/{component}/{quote(address, safe='')}/{quote(boot_id, safe='')}"




def check_topic(topic: str) -> str:
    """``topic`` as a Zenoh key a stream may publish or subscribe to (plain chunks
    separated by ``/``, no wildcards); ``ValueError`` naming what is wrong."""
    chunks = topic.strip("/").split("/")
    if not topic or len(topic) > 256 or not all(_WORD.match(chunk) for chunk in chunks):
        raise ValueError(f"Zenoh topic {topic[:80]!r}: expected chunks of letters, digits, _ . - separated by /")
    return "/".join(chunks)
