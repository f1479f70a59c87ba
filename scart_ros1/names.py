"""ROS 1 graph names, as rosgraph and rospy resolve them.

* A **global** name starts with ``/``; a **relative** one (``chatter``) is taken in the
  node's namespace; a **private** one (``~state``) under the node's own name.
* **Remaps** are ``from:=to`` arguments, both sides resolved like any name. The special
  keys ``__name:=`` (the node's base name), ``__ns:=`` (its namespace) and ``__master:=``
  (the master's URI) override what the code said, as on a ROS command line. A
  ``_param:=value`` argument sets a private parameter in ROS: it is not a name, and it is
  ignored here.
* The namespace defaults to ``ROS_NAMESPACE``, the master to ``ROS_MASTER_URI``, then to
  ``http://localhost:11311/`` (ROS's own default).

Everything here is pure and thread-safe; bad names raise :class:`RosNameError`, a
``ValueError`` naming the name and the rule it breaks.
"""

from __future__ import annotations

import os
import re
import urllib.parse
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

__all__ = [
    "DEFAULT_MASTER_URI",
    "NodeNames",
    "RosNameError",
    "canonical",
    "check_name",
    "master_uri_from",
    "node_names",
    "parse_remaps",
    "resolve",
]

DEFAULT_MASTER_URI = "http://localhost:11311/"
SPECIAL_KEYS = frozenset({"__name", "__ns", "__master", "__ip", "__hostname", "__log"})
MAX_NAME = 1024  #: a graph name longer than this is refused (ROS sets no limit; we bound input)
_LEGAL = re.compile(r"^[~/A-Za-z][\w/]*$")
_BASE = re.compile(r"^[A-Za-z][\w]*$")


class RosNameError(ValueError):
    """A graph name, node name, remap or master URI that ROS would refuse."""


def check_name(name: str, what: str = "name") -> str:
    """Return ``name`` if it is a legal ROS graph name, else raise :class:`RosNameError`."""
    if not isinstance(name, str) or not name or len(name) > MAX_NAME:
        raise RosNameError(f"illegal ROS {what} {name!r}: a non-empty string of at most {MAX_NAME} characters")
    if not _LEGAL.match(name) or "//" in name or "~" in name[1:]:
        raise RosNameError(
            f"illegal ROS {what} {name!r}: letters, digits, '_' and '/', starting with a letter, '/' or '~'"
        )
    return name


def canonical(name: str) -> str:
    """``name`` without a trailing ``/`` (the root ``/`` stays)."""
    return name if name == "/" else name.rstrip("/") or "/"


def _namespace_of(node: str) -> str:
    """The namespace a node's relative names live in, with a trailing ``/``."""
    parent = node.rsplit("/", 1)[0]
    return parent + "/"


def resolve(name: str, node: str, remaps: Mapping[str, str] | None = None) -> str:
    """Resolve ``name`` for the node whose full name is ``node``; apply ``remaps`` last.

    ``resolve("chatter", "/ns/talker") == "/ns/chatter"``;
    ``resolve("~x", "/ns/talker") == "/ns/talker/x"``; a global name stays as it is.
    """
    check_name(name)
    if name.startswith("/"):
        resolved = canonical(name)
    elif name.startswith("~"):
        resolved = canonical(node + "/" + name[1:]) if len(name) > 1 else node
    else:
        resolved = canonical(_namespace_of(node) + name)
    return remaps.get(resolved, resolved) if remaps else resolved


def parse_remaps(remaps: Iterable[str] | Mapping[str, str] | None) -> tuple[dict[str, str], dict[str, str]]:
    """Split remaps into ``(special, names)``: ``__name``-like keys, and name remaps.

    Takes ``["from:=to", ...]`` (a command line: other arguments are skipped, as ROS
    does) or a mapping. Private parameters (``_p:=v``) are skipped. Unresolved.
    """
    pairs: Iterable[tuple[str, str]]
    if remaps is None:
        pairs = ()
    elif isinstance(remaps, Mapping):
        pairs = remaps.items()
    else:
        pairs = [(old.strip(), new.strip()) for old, _, new in (arg.partition(":=") for arg in remaps if ":=" in arg)]
    special: dict[str, str] = {}
    names: dict[str, str] = {}
    for src, dst in pairs:
        if not src or not dst or (len(src) > 1 and src[0] == "_" and src[1] != "_"):
            continue
        if src in SPECIAL_KEYS:
            special[src] = dst
        elif src.startswith("__"):
            raise RosNameError(f"unknown special remap {src!r}: ROS knows {', '.join(sorted(SPECIAL_KEYS))}")
        else:
            names[src] = dst
    return special, names


def master_uri_from(uri: str | None, env: Mapping[str, str] | None = None) -> str:
    """The master's URI: ``uri``, else ``ROS_MASTER_URI``, else ROS's default; checked."""
    env = os.environ if env is None else env
    uri = uri or env.get("ROS_MASTER_URI") or DEFAULT_MASTER_URI
    parts = urllib.parse.urlsplit(uri)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in ("http", "https") or not parts.hostname or port is None:
        raise RosNameError(f"ROS master URI {uri!r} is not http://HOST:PORT/ (ROS_MASTER_URI or master_uri=)")
    return uri


@dataclass(frozen=True)
class NodeNames:
    """A node's resolved identity: full name, namespace, master URI and name remaps."""

    node: str  #: the full node name, e.g. ``/robot/scart`` (ROS's caller id)
    namespace: str  #: e.g. ``/robot`` (``/`` for the root)
    master_uri: str
    remaps: Mapping[str, str] = field(default_factory=dict)  #: resolved ``from`` → resolved ``to``

    def resolve(self, name: str) -> str:
        """``name`` resolved for this node, remaps applied (raises :class:`RosNameError`)."""
        return resolve(name, self.node, self.remaps)


def node_names(
    name: str,
    *,
    namespace: str | None = None,
    master_uri: str | None = None,
    remaps: Iterable[str] | Mapping[str, str] | None = None,
    env: Mapping[str, str] | None = None,
) -> NodeNames:
    """Resolve a node's identity as rospy's ``init_node`` does (see the module docstring).

    ``name`` is a base name (no ``/``); ``__name:=``/``__ns:=``/``__master:=`` in
    ``remaps`` override ``name``/``namespace``/``master_uri``; ``namespace`` overrides
    ``ROS_NAMESPACE``. Raises :class:`RosNameError`.
    """
    env = os.environ if env is None else env
    special, raw = parse_remaps(remaps)
    base = special.get("__name", name)
    if not isinstance(base, str) or not _BASE.match(base):
        raise RosNameError(f"illegal ROS node name {base!r}: a base name (letters, digits, '_'; no '/' or '~')")
    ns = special.get("__ns") or namespace or env.get("ROS_NAMESPACE") or "/"
    if check_name(ns, "namespace").startswith("~"):
        raise RosNameError(f"illegal ROS namespace {ns!r}: a namespace is not private ('~')")
    ns = canonical("/" + ns.lstrip("/"))
    node = canonical(ns.rstrip("/") + "/" + base)
    uri = master_uri_from(special.get("__master") or master_uri, env)
    resolved = {resolve(src, node): resolve(dst, node) for src, dst in raw.items()}
    return NodeNames(node=node, namespace=ns, master_uri=uri, remaps=resolved)
