"""Shared fixtures of the SCA suites: a sample component module and contribution writer.

(No tests here: pytest collects it only because of its name, which keeps it in the SCA
stream's files.)
"""

from __future__ import annotations

import textwrap
from pathlib import Path

SCA = "http://docs.oasis-open.org/ns/opencsa/sca/200912"
OSOA = "http://www.osoa.org/xmlns/sca/1.0"

COMPONENTS = '''
from __future__ import annotations

import threading
from typing import Protocol

from pydantic import BaseModel

import scart

EVENTS: list[str] = []
GATE = threading.Event()


class Point(BaseModel):
    x: float
    y: float


@scart.interface
class Greeter(Protocol):
    def greet(self, name: str) -> str: ...


@scart.interface
class Farewell(Protocol):
    def bye(self, name: str) -> str: ...


@scart.component(services=[Greeter])
class GreeterImpl:
    greeting: str = scart.prop(default="Hello")

    def greet(self, name: str) -> str:
        return f"{self.greeting}, {name}"


@scart.component(services=[Greeter, Farewell])
class TwoFaced:
    def greet(self, name: str) -> str:
        return "hi " + name

    def bye(self, name: str) -> str:
        return "bye " + name


@scart.component(services=[Farewell])
class FarewellImpl:
    def bye(self, name: str) -> str:
        return "bye " + name


class Props:
    text: str = scart.prop(default="default")
    number: int = scart.prop(default=1)
    ratio: float = scart.prop(default=0.5)
    flag: bool = scart.prop(default=False)
    many: list[int] = scart.prop(default=[])
    names: list[str] = scart.prop(default=[])
    config: dict = scart.prop(default={})
    point: Point | None = scart.prop(default=None)

    def values(self) -> dict:
        return {k: getattr(self, k) for k in
                ("text", "number", "ratio", "flag", "many", "names", "config", "point")}

    def add_name(self, name: str) -> list:
        self.names.append(name)
        return self.names


class NeedsValue:
    value: int = scart.prop(required=True)

    def get(self) -> int:
        return self.value


class Client:
    one: Greeter = scart.reference()
    maybe: Greeter = scart.reference(required=False)
    some: list[Greeter] = scart.reference(multiple=True, required=False)

    def report(self) -> dict:
        return {
            "one": self.one.greet("one"),
            "maybe": None if self.maybe is None else self.maybe.greet("maybe"),
            "some": [g.greet("some") for g in self.some],
        }


class Single:
    one: Greeter = scart.reference()

    def call(self, name: str) -> str:
        return self.one.greet(name)


class AtLeastOne:
    many: list[Greeter] = scart.reference(multiple=True)

    def call(self, name: str) -> list:
        return [g.greet(name) for g in self.many]


class OptionalOne:
    maybe: Greeter = scart.reference(required=False)

    def call(self) -> object:
        return self.maybe


class ByeClient:
    one: Farewell = scart.reference()


class Tracker:
    """Records init/destroy in EVENTS and, when log_file is set, in that file."""

    log_file: str = scart.prop(default="")
    next: Greeter = scart.reference(required=False)
    ctx: scart.ComponentContext = scart.context()

    def _log(self, what: str) -> None:
        EVENTS.append(f"{what} {self.ctx.name}")
        if self.log_file:
            with open(self.log_file, "a", encoding="utf-8") as fh:
                fh.write(f"{what} {self.ctx.name}\\n")

    @scart.init
    def start(self) -> None:
        self._log("init")

    @scart.destroy
    def close(self) -> None:
        self._log("destroy")

    def greet(self, name: str) -> str:
        return self.ctx.name


@scart.component(eager_init=False)
class LazyTracker(Tracker):
    pass


@scart.interface
class Notifying(Protocol):
    def notify(self, msg: str) -> None: ...


@scart.interface(callback=Notifying)
class Worker(Protocol):
    def work(self, n: int) -> int: ...

    @scart.oneway
    def work_async(self, n: int) -> None: ...


@scart.component(services=[Worker])
class WorkerImpl:
    caller: Notifying = scart.callback()

    def work(self, n: int) -> int:
        self.caller.notify(f"sync {n}")
        return n * 2

    def work_async(self, n: int) -> None:
        GATE.wait(10)
        self.caller.notify(f"async {n} on {threading.current_thread().name}")


class Deaf:
    """Calls a Worker, which calls back, but implements no callback method."""
    worker: Worker = scart.reference()


class Boss:
    worker: Worker = scart.reference()

    def __init__(self) -> None:
        self.received: list[str] = []
        self.got = threading.Event()

    def notify(self, msg: str) -> None:
        self.received.append(msg)
        self.got.set()

    def run_sync(self, n: int) -> int:
        return self.worker.work(n)

    def run_async(self, n: int) -> None:
        self.worker.work_async(n)

    def wait_message(self, timeout: float) -> list:
        self.got.wait(timeout)
        return list(self.received)


@scart.interface
class Progress(Protocol):
    @scart.oneway
    def progress(self, pct: int) -> None: ...


@scart.interface(callback=Progress)
class Job(Protocol):
    def run(self) -> str: ...


@scart.component(services=[Job])
class JobImpl:
    caller: Progress = scart.callback()

    def run(self) -> str:
        self.caller.progress(50)
        return "started"


class JobClient:
    job: Job = scart.reference()

    def __init__(self) -> None:
        self.seen: list[str] = []
        self.got = threading.Event()

    def progress(self, pct: int) -> None:
        self.seen.append(f"{pct} on {threading.current_thread().name}")
        self.got.set()

    def go(self) -> str:
        return self.job.run()


@scart.component(scope="stateless")
class StatelessCounter:
    def __init__(self) -> None:
        self.count = 0

    def hit(self) -> int:
        self.count += 1
        return self.count


class CompositeCounter:
    def __init__(self) -> None:
        self.count = 0

    def hit(self) -> int:
        self.count += 1
        return self.count


@scart.interface(remotable=True)
class RemoteMutator(Protocol):
    def mutate(self, items: list) -> list: ...


@scart.interface
class LocalMutator(Protocol):
    def mutate(self, items: list) -> list: ...


@scart.component(services=[RemoteMutator])
class RemoteMutatorImpl:
    def mutate(self, items: list) -> list:
        items.append("callee")
        return items


@scart.component(services=[LocalMutator])
class LocalMutatorImpl:
    def mutate(self, items: list) -> list:
        items.append("callee")
        return items


@scart.interface
class BadOneWay(Protocol):
    @scart.oneway
    def fire(self) -> int: ...


@scart.component(services=[BadOneWay])
class BadOneWayImpl:
    def fire(self) -> int:
        return 1


@scart.component(services=[Greeter])
class LacksGreet:
    def hello(self) -> str:
        return "x"


class Slow:
    @scart.oneway
    def fire(self, n: int) -> None:
        GATE.wait(10)
        EVENTS.append(f"fired {n}")
'''


def composite(body: str, name: str = "Test", tns: str = "urn:test", ns: str = SCA, extra: str = "") -> str:
    """A composite document with ``body`` inside (dedented); first line is the XML declaration."""
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<composite xmlns="{ns}" xmlns:scart="urn:scart:1.0" xmlns:t="{tns}" '
        f'targetNamespace="{tns}" name="{name}"{extra}>\n'
        + textwrap.dedent(body).strip("\n") + "\n</composite>\n"
    )


def py(cls: str) -> str:
    """An ``implementation.python`` element for ``comps:CLS``."""
    return f'<scart:implementation.python class="comps:{cls}"/>'


def write(folder: Path, files: dict[str, str], with_components: bool = True) -> Path:
    """Write ``files`` (name -> text) into ``folder`` (plus comps.py); return the first file."""
    folder.mkdir(parents=True, exist_ok=True)
    if with_components:
        (folder / "comps.py").write_text(COMPONENTS, encoding="utf-8")
    first = None
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8")
        first = first or folder / name
    assert first is not None
    return first


def line_of(text: str, marker: str) -> int:
    """1-based line of the first line containing ``marker``."""
    for i, line in enumerate(text.splitlines(), 1):
        if marker in line:
            return i
    raise AssertionError(f"{marker!r} not in text")
