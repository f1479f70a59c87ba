"""What every verb of the ``scart`` command line shares, the SCA verbs
(:mod:`scart.commands`) and the data-flow ones (:mod:`dataflow.cli.verbs`) alike: their
common options, printing, errors, the values a user types, and reaching the name service.
It sits in the wire layer, below both worlds, so that each world's verbs use it without
importing the other's command line; it imports no verb and neither world, and nothing
heavy until a verb runs.

Every verb that reads a running system finds it through a name service: ``--ns
HOST:PORT``, else the ``SCART_NS`` environment variable, else ``127.0.0.1:7850``. Data
goes to stdout (with ``--json``: JSON, one document, or one line per sample for
streams), diagnostics to stderr, one line each, never a traceback. ``--timeout`` is the
deadline of each remote call. Exit codes: 0 success, 1 a failure (nothing answers,
unknown name, wrong type, refused value or transition), 2 usage.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Protocol, TypeVar, cast

if TYPE_CHECKING:
    from types import FrameType

    import numpy as np
    from pydantic import JsonValue

from scart_wire.bounds import nesting_depth
from scart_wire.defaults import DEFAULT_NS_ADDRESS, NS_ENV

__all__ = ["add_common", "address_arg", "checked_address", "dump", "err", "jsonable", "listen_arg", "ns_address",
           "out", "parse_value", "rate_of", "seconds_arg", "stopped_by_signals", "wait_until_stopped", "with_client",
           "with_rates"]

#: A value typed on the command line (JSON or YAML), at most this long.
MAX_VALUE_CHARS = 1 << 20
#: ... and nested at most this deep.
MAX_VALUE_DEPTH = 64


class Closable(Protocol):
    """What :func:`with_client` connects: a system it closes when the verb is done."""

    def close(self) -> None: ...


class Named(Protocol):
    """An item :func:`with_rates` lists: anything with a name."""

    @property
    def name(self) -> str: ...


N = TypeVar("N", bound=Named)

_HOST_PORT = re.compile(r"^(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>[0-9]{1,5})$")


def add_common(parser: argparse.ArgumentParser) -> None:
    """``--ns``, ``--json``, ``--timeout`` and the client's security options."""
    from scart_wire.security import add_arguments

    parser.add_argument("--ns", default=None, type=address_arg, metavar="HOST:PORT",
                        help=f"name service HOST:PORT (default ${NS_ENV} or {DEFAULT_NS_ADDRESS})")
    parser.add_argument("--json", action="store_true", help="JSON on stdout")
    parser.add_argument("--timeout", type=seconds_arg, default=3.0, metavar="SECONDS",
                        help="deadline of each remote call (s, > 0)")
    add_arguments(parser, server=False)


def checked_address(text: str, what: str, free_port: bool = False) -> str:
    """``text`` when it is ``HOST:PORT`` with a port in 1..65535 (0..65535 with
    ``free_port``: where a server listens); else ``ValueError`` naming ``what``
    (``localhost`` alone would go to gRPC's default port, 443)."""
    m = _HOST_PORT.match(text.strip())
    low = 0 if free_port else 1
    if m is None or not low <= int(m["port"]) <= 65535:
        raise ValueError(f"{what} {text[:80]!r}: expected HOST:PORT with a port in {low}..65535 "
                         f"(e.g. {DEFAULT_NS_ADDRESS})")
    return text.strip()


def address_arg(text: str) -> str:
    """argparse type of an address option: :func:`checked_address` (a usage error, exit 2)."""
    try:
        return checked_address(text, "")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).strip()) from None


def listen_arg(text: str) -> str:
    """argparse type of an address a server may listen on (port 0: a free one)."""
    try:
        return checked_address(text, "", free_port=True)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).strip()) from None


def seconds_arg(text: str) -> float:
    """argparse type of a duration: a finite number of seconds > 0 (exit 2 otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text[:80]!r}: expected a number of seconds > 0")
    return value


def ns_address(args: argparse.Namespace) -> str:
    """The name service to use: ``--ns``, else ``$SCART_NS``, else the default. Raises
    ``ValueError`` naming ``$SCART_NS`` when it is not ``HOST:PORT``."""
    if args.ns:
        return str(args.ns)
    env = os.environ.get(NS_ENV)
    return checked_address(env, f"${NS_ENV}") if env else DEFAULT_NS_ADDRESS


def err(message: str) -> None:
    """One diagnostic line on stderr, ``scart `` first; at most
    :data:`scart_wire.errors.MAX_ECHO` characters of it (what an argument echoes is cut in
    the middle, and said)."""
    from scart_wire.errors import bounded

    print(f"scart {bounded(message)}", file=sys.stderr, flush=True)


def out(text: str) -> None:
    """A line of data on stdout, flushed (pipes see each sample at once)."""
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def dump(obj: object) -> str:
    """``obj`` as one line of JSON."""
    return json.dumps(obj, ensure_ascii=False)


def jsonable(value: object) -> object:
    """A sample or result as JSON-able data (the type registry's form); a numpy array
    (an image, a point cloud) as a summary: its shape, element type, mean, min and max."""
    from scart_wire.types import registry

    kind = type(value)
    if kind.__name__ == "ndarray" and kind.__module__ == "numpy":
        return array_summary(cast("np.ndarray", value))
    return registry.to_jsonable(value)


def array_summary(value: np.ndarray) -> dict[str, object]:
    """What ``scart echo`` shows of an array: not its data."""
    summary: dict[str, object] = {"shape": list(value.shape), "dtype": value.dtype.name}
    if value.size and value.dtype.kind in "biuf":
        summary.update(mean=float(value.mean()), min=value.min().item(), max=value.max().item())
    return summary


def parse_value(text: str) -> JsonValue:
    """A value typed on the command line: JSON, else YAML as ``ros2 topic pub`` takes it
    (``"{x: 1, y: [2, 3]}"``, ``"data: hi"``), else the text itself (a bare word is a
    string). Raises ``ValueError`` for text over :data:`MAX_VALUE_CHARS` or nested deeper
    than :data:`MAX_VALUE_DEPTH`."""
    if len(text) > MAX_VALUE_CHARS:
        raise ValueError(f"a value of {len(text)} characters: at most {MAX_VALUE_CHARS}")
    try:
        value = json.loads(text)
    except (ValueError, RecursionError):
        value = _yaml(text)
    if nesting_depth(value, MAX_VALUE_DEPTH, MAX_VALUE_CHARS) > MAX_VALUE_DEPTH:
        raise ValueError(f"a value nested deeper than {MAX_VALUE_DEPTH} levels")
    return value


def _yaml(text: str) -> JsonValue:
    import yaml

    try:
        value = yaml.safe_load(text)
    except (yaml.YAMLError, RecursionError):
        return text
    if value is None and text.strip() not in ("null", "~", ""):
        return text  # a comment or a document marker: the text is what was meant
    return value


def with_client(args: argparse.Namespace, connect: Callable[..., Closable],
                body: Callable[[argparse.Namespace], int]) -> int:
    """Run a verb's ``body`` with ``args.system`` connected to the name service by
    ``connect(address, timeout=..., security=...)`` (the data-flow world's
    :func:`dataflow.remote.connect`: this layer imports neither world); every error it can
    meet becomes one stderr line and exit code 1 (2: ``$SCART_NS`` is no address)."""
    from scart_wire.errors import DataflowError, RemoteTimeoutError, UnavailableError
    from scart_wire.security import from_args

    try:
        address = ns_address(args)
    except ValueError as exc:
        err(f"{args.command}: {exc}")
        return 2
    source = "--ns" if args.ns else (f"${NS_ENV}" if os.environ.get(NS_ENV) else "the default")
    try:
        system = connect(address, timeout=args.timeout, security=from_args(args))
    except (UnavailableError, RemoteTimeoutError) as exc:
        err(f"{args.command}: no name service answers at {address} (from {source}): {exc}\n"
            f"  start one with `scart nameserver --listen {address}`, or host tasks with "
            f"`scart deploy pkg.mod:Class` (embeds one on {DEFAULT_NS_ADDRESS}),\n"
            f"  or point --ns / {NS_ENV} at a running name service or deployer.")
        return 1
    except DataflowError as exc:  # credentials refused, unusable security files
        err(f"{args.command}: {exc}")
        return 1
    try:
        args.system = system
        return body(args)
    except (DataflowError, ValueError) as exc:
        err(f"{args.command}: {exc}")
        return 1
    finally:
        system.close()


@contextlib.contextmanager
def stopped_by_signals(done: threading.Event) -> Iterator[None]:
    """SIGINT and SIGTERM set ``done`` inside the block (then the former handlers again):
    set before a subscription starts printing, so a Ctrl-C after its first line stops it."""
    def handler(signum: int, frame: FrameType | None) -> None:
        done.set()

    old = [signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)]
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old[0])
        signal.signal(signal.SIGTERM, old[1])


def wait_until_stopped(done: threading.Event, duration: float | None, tick: float = 1.0,
                       on_tick: Callable[[], None] | None = None) -> None:
    """Block until ``done``, SIGINT/SIGTERM, or ``duration`` s; call ``on_tick`` every ``tick`` s."""
    with stopped_by_signals(done):
        deadline = None if duration is None else time.monotonic() + duration
        while not done.is_set():
            wait = tick if deadline is None else min(tick, max(0.0, deadline - time.monotonic()))
            if done.wait(wait):
                break
            if deadline is not None and time.monotonic() >= deadline:
                break
            if on_tick is not None:
                on_tick()


def rate_of(periods: int, span: float) -> float:
    """The rate ``hz`` reports, from ``periods`` intervals between events that together
    span ``span`` seconds: one over their mean (0.0 when nothing was measured). ``ls`` and
    ``topics`` give their rates with it too, from the events' own times."""
    return periods / span if periods > 0 and span > 0 else 0.0


def with_rates(listing: Callable[[], Sequence[N]], count: Callable[[N], int],
               sample: float) -> list[tuple[N, float]]:
    """Each item of ``listing()`` with its rate (count per second) measured over ``sample`` s:
    listed twice, ``sample`` s apart; an item that appeared in between has rate 0."""
    first = {item.name: (count(item), time.monotonic()) for item in listing()}
    if sample > 0:
        threading.Event().wait(sample)
    rows = []
    for item in listing():
        count0, t0 = first.get(item.name, (count(item), time.monotonic()))
        dt = time.monotonic() - t0
        rows.append((item, round((count(item) - count0) / dt, 2) if dt > 0 else 0.0))
    return rows
