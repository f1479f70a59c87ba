"""SCA runtime benchmark: wired-call cost vs a direct call, one-way cost, load+start time.

Run: ``python benchmarks/bench_sca.py [--quick | --smoke]`` (prints a table; no assertions;
``--quick``: fewer rounds, ``--smoke``: a few seconds, that every path runs). Goals: a local
wired call costs at most 2x a direct method call; a 1000-component composite validates
and starts in under 2 s.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import textwrap
import time
import timeit
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import scart  # noqa: E402

N = 200_000

MODULE = '''
from typing import Protocol
import scart


@scart.interface
class Adder(Protocol):
    def add(self, a: int, b: int) -> int: ...

    @scart.oneway
    def fire(self, a: int) -> None: ...


@scart.interface
class Notify(Protocol):
    def done(self) -> None: ...


@scart.interface(callback=Notify)
class BiAdder(Protocol):
    def add(self, a: int, b: int) -> int: ...


@scart.interface(remotable=True)
class RemoteAdder(Protocol):
    def add(self, a: int, b: int) -> int: ...


@scart.component(services=[Adder])
class AdderImpl:
    def add(self, a: int, b: int) -> int:
        return a + b

    def fire(self, a: int) -> None:
        pass


@scart.component(services=[BiAdder])
class BiAdderImpl:
    def add(self, a: int, b: int) -> int:
        return a + b


@scart.component(services=[RemoteAdder])
class RemoteAdderImpl:
    def add(self, a: int, b: int) -> int:
        return a + b


class Caller:
    adder: Adder = scart.reference()
    bi: BiAdder = scart.reference(required=False)
    remote: RemoteAdder = scart.reference(required=False)

    def done(self) -> None:
        pass


class Chain:
    prev: Adder = scart.reference(required=False)
    value: int = scart.prop(default=0)

    def add(self, a: int, b: int) -> int:
        return a + b

    @scart.oneway
    def fire(self, a: int) -> None:
        pass
'''


def _write(folder: Path, body: str, name: str) -> Path:
    (folder / "benchcomps.py").write_text(MODULE, encoding="utf-8")
    path = folder / f"{name}.composite"
    path.write_text(
        '<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0" '
        f'targetNamespace="urn:bench" name="{name}">\n{textwrap.dedent(body)}\n</composite>\n', encoding="utf-8")
    return path


def _per_call(stmts: list[str], env: dict[str, object], rounds: int = 7, number: int = N) -> list[float]:
    """ns per call of each statement: rounds interleaved, best round kept (robust to noise)."""
    timers = [timeit.Timer(stmt, globals=env) for stmt in stmts]
    best = [float("inf")] * len(stmts)
    for _ in range(rounds):
        for i, timer in enumerate(timers):
            best[i] = min(best[i], timer.timeit(number=number) / number * 1e9)
    return best


def bench_calls(folder: Path, rounds: int = 7, number: int = N) -> list[tuple[str, str, str]]:
    path = _write(folder, """
      <component name="A"><scart:implementation.python class="benchcomps:AdderImpl"/></component>
      <component name="Bi"><scart:implementation.python class="benchcomps:BiAdderImpl"/></component>
      <component name="R"><scart:implementation.python class="benchcomps:RemoteAdderImpl"/></component>
      <component name="C"><scart:implementation.python class="benchcomps:Caller"/>
        <reference name="adder" target="A"/><reference name="bi" target="Bi"/><reference name="remote" target="R"/>
      </component>""", "calls")
    rows = []
    with scart.Runtime.from_file(str(path)) as rt:
        caller = rt._managers["C"].instance()
        direct = rt._managers["A"].instance()
        caller.direct = direct  # the same shape as a wired call: an attribute holding the target
        env = {"caller": caller, "svc": rt.service("A")}
        labels = [
            ("direct method call self.direct.add(1, 2)", "caller.direct.add(1, 2)"),
            ("wired reference call self.adder.add(1, 2) (local binding)", "caller.adder.add(1, 2)"),
            ("rt.service('A').add(1, 2) proxy", "svc.add(1, 2)"),
            ("wired call, bidirectional interface (callback routed)", "caller.bi.add(1, 2)"),
            ("wired call, remotable interface (pass-by-value)", "caller.remote.add(1, 2)"),
        ]
        times = _per_call([stmt for _, stmt in labels], env, rounds, number)
        d = times[0]
        rows += [(label, f"{t:.0f} ns", f"{t / d:.2f}x") for (label, _), t in zip(labels, times)]
        n, best = min(5_000, number), float("inf")
        for _ in range(min(5, rounds)):
            t0 = time.perf_counter()
            for _ in range(n):
                caller.adder.fire(1)
            best = min(best, (time.perf_counter() - t0) / n * 1e9)
        rows.append(("one-way call, cost to the caller (the runtime's one-way pool)", f"{best:.0f} ns", f"{best / d:.2f}x"))
    return rows


def bench_load(folder: Path, count: int) -> tuple[str, str, str]:
    body = "".join(
        f'<component name="C{i}"><scart:implementation.python class="benchcomps:Chain"/>'
        + (f'<reference name="prev" target="C{i - 1}"/>' if i else "")
        + f'<property name="value">{i}</property></component>\n'
        for i in range(count))
    path = _write(folder, body, f"load{count}")
    t0 = time.perf_counter()
    rt = scart.Runtime.from_file(str(path))
    t1 = time.perf_counter()
    rt.start()
    t2 = time.perf_counter()
    rt.stop()
    return (f"load+validate / start, {count} component(s)", f"{(t1 - t0) * 1e3:.1f} / {(t2 - t1) * 1e3:.1f} ms",
            f"{(t2 - t0) * 1e3:.1f} ms total")


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds")
    parser.add_argument("--smoke", action="store_true", help="a few seconds: that every path runs")
    args = parser.parse_args()
    rounds, number, sizes = (1, 2_000, (1, 10)) if args.smoke else (3, N, (1, 100, 1000)) if args.quick else \
        (7, N, (1, 100, 1000))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        rows = bench_calls(folder, rounds, number)
        rows += [bench_load(folder, n) for n in sizes]
    width = max(len(r[0]) for r in rows)
    print(f"| {'measure'.ljust(width)} | {'value':>22} | {'vs direct / total':>18} |")
    print(f"|{'-' * (width + 2)}|{'-' * 24}|{'-' * 20}|")
    for a, b, c in rows:
        print(f"| {a.ljust(width)} | {b:>22} | {c:>18} |")


if __name__ == "__main__":
    main()
