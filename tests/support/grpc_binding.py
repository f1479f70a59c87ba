"""Shared pieces of the binding.grpc suites: components for the gRPC-only scenarios and two
runtimes (provider and client) in one process. (No tests here.)"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import scart
from scart.bindings.grpc._binding import GrpcServiceBinding
from support.sca import composite, py, write

GCOMPONENTS = '''
from __future__ import annotations

import threading
from typing import Protocol

from pydantic import BaseModel

import scart

STARTED = threading.Event()
RELEASE = threading.Event()
DONE: list[str] = []


class Point(BaseModel):
    x: float
    y: float


class Rejected(Exception):
    pass


@scart.interface
class Geometry(Protocol):
    def centroid(self, points: list[Point]) -> Point: ...
    def scale(self, values: list[float], k: float) -> list[float]: ...
    def tags(self, names: list[str], meta: dict) -> dict: ...
    def nothing(self) -> None: ...
    def fail(self, why: str) -> int: ...

    @scart.oneway
    def explode(self) -> None: ...

    @scart.oneway
    def slow(self, n: int) -> None: ...


@scart.component(services=[Geometry])
class GeometryImpl:
    def centroid(self, points: list[Point]) -> Point:
        assert all(isinstance(p, Point) for p in points)
        return Point(x=sum(p.x for p in points) / len(points), y=sum(p.y for p in points) / len(points))

    def scale(self, values: list[float], k: float) -> list[float]:
        return [v * k for v in values]

    def tags(self, names: list[str], meta: dict) -> dict:
        return {"names": names, "meta": meta, "n": len(names)}

    def nothing(self) -> None:
        return None

    def fail(self, why: str) -> int:
        raise Rejected(why)

    def explode(self) -> None:
        raise RuntimeError("boom")

    def slow(self, n: int) -> None:
        STARTED.set()
        RELEASE.wait(10)
        DONE.append(f"slow {n}")


class GeometryClient:
    geo: Geometry = scart.reference()


@scart.interface
class Asking(Protocol):
    def confirm(self, question: str) -> bool: ...
    @scart.oneway
    def told(self, what: str) -> None: ...


@scart.interface(callback=Asking)
class Desk(Protocol):
    def decide(self, question: str) -> str: ...
    @scart.oneway
    def decide_later(self, question: str) -> None: ...


@scart.component(services=[Desk])
class DeskImpl:
    caller: Asking = scart.callback()

    def __init__(self) -> None:
        self.results: list[str] = []
        self.done = threading.Event()
        self.callers: set[Any] = set()  # as a provider keeps its clients to call back later

    def decide(self, question: str) -> str:
        self.callers.add(self.caller)
        first = self.caller.confirm(question + "?")
        second = self.caller.confirm(question + "??")
        self.caller.told("decided")
        return f"{question}: {first} {second}"

    def decide_later(self, question: str) -> None:
        self.callers.add(self.caller)
        answer = self.caller.confirm(question)
        self.results.append(f"{question} -> {answer}")
        self.caller.told(f"later {question}")
        self.done.set()


class Asker:
    desk: Desk = scart.reference()

    def __init__(self) -> None:
        self.questions: list[str] = []
        self.told_msgs: list[str] = []
        self.got = threading.Event()

    def confirm(self, question: str) -> bool:
        self.questions.append(question)
        return question.count("?") % 2 == 1

    def told(self, what: str) -> None:
        self.told_msgs.append(what)
        self.got.set()

    def ask(self, q: str) -> str:
        return self.desk.decide(q)

    def ask_later(self, q: str) -> None:
        self.desk.decide_later(q)


class AskerReport(Asker):
    """At @init: a synchronous call with callbacks, then a one-way call whose callbacks come
    later; once both one-way callbacks arrived, writes what it saw as JSON to ``out``."""

    out: str = scart.prop(default="")

    @scart.init
    def go(self) -> None:
        self.lock = threading.Lock()
        self.sync = self.desk.decide("go")
        self.desk.decide_later("q?")

    def told(self, what: str) -> None:
        import json
        with self.lock:
            super().told(what)
            if len(self.told_msgs) == 2:
                import os
                with open(self.out + ".tmp", "w", encoding="utf-8") as fh:
                    json.dump({"sync": self.sync, "questions": self.questions, "told": sorted(self.told_msgs)}, fh)
                os.replace(self.out + ".tmp", self.out)  # readers never see a partial file
'''


def gwrite(folder: Path, files: dict[str, str]) -> Path:
    """``write`` plus the gRPC components module ``gcomps``; returns the first file."""
    first = write(folder, files)
    (folder / "gcomps.py").write_text(GCOMPONENTS, encoding="utf-8")
    return first


def gpy(cls: str) -> str:
    """``implementation.python`` for ``gcomps:CLS``."""
    return f'<scart:implementation.python class="gcomps:{cls}"/>'


def grpc_service(address: str = "127.0.0.1:0", extra: str = "") -> str:
    return f'<scart:binding.grpc address="{address}"{extra}/>'


def grpc_reference(address: str, service: str, timeout: float = 5.0) -> str:
    return f'<scart:binding.grpc address="{address}" service="{service}" timeout="{timeout}"/>'


def grpc_address(rt: scart.Runtime) -> str:
    """The real address of the first binding.grpc service of ``rt``."""
    found = [b.address for b in rt._service_bindings if isinstance(b, GrpcServiceBinding)]
    assert found and found[0], "no binding.grpc service started"
    return found[0]


def grpc_bindings(rt: scart.Runtime) -> list[GrpcServiceBinding]:
    return [b for b in rt._service_bindings if isinstance(b, GrpcServiceBinding)]


def instance(rt: scart.Runtime, path: str) -> Any:
    return rt._managers[path].instance()


def module(name: str) -> Any:
    return sys.modules[name]


@contextmanager
def provider_and_client(folder: Path, provider_body: str, client_body: Any) -> Iterator[tuple[scart.Runtime, scart.Runtime]]:
    """Start the provider composite, then the client composite (``client_body(address)``),
    both in this process; stop client then provider."""
    prov = gwrite(folder, {"provider.composite": composite(provider_body, name="Provider")})
    with scart.Runtime.from_file(str(prov)) as provider:
        address = grpc_address(provider)
        cli = gwrite(folder, {"client.composite": composite(client_body(address), name="Client")})
        with scart.Runtime.from_file(str(cli)) as client:
            yield provider, client


__all__ = ["composite", "py", "gpy", "gwrite", "grpc_service", "grpc_reference", "grpc_address", "grpc_bindings",
           "instance", "module", "provider_and_client"]
