"""How much of the code's annotations say ``Any``: the figure issue 33 tracks.

Run: ``python benchmarks/count_any.py [--tree PATH] [--files N] [PACKAGE ...]``
(prints a table; no assertions). It parses every ``.py`` file of the packages (default:
``scart``, ``dataflow``, ``scart_yarp``, ``scart_wire``; protoc's ``*_pb2*`` files are
left out, nobody writes them) and walks each annotation: a parameter's, a return's and an
annotated assignment's. An annotation counts once as "with Any" if ``Any`` appears anywhere
in it (``Any``, ``typing.Any``, ``dict[str, Any]``, or the same inside a quoted
annotation); "uses" counts every ``Any`` in them. ``--tree`` points at another checkout to
compare before and after; ``--files N`` lists the N files with the most annotations with Any.
"""

from __future__ import annotations

import argparse
import ast
import tomllib
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: What the type checker checks (pyproject's ``[tool.mypy] files``): every package shipped.
PACKAGES = tuple(tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["mypy"]["files"])


def annotations(tree: ast.AST) -> Iterator[ast.expr]:
    """Every annotation node of a module: parameters, returns, annotated assignments."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            every = [*args.posonlyargs, *args.args, *args.kwonlyargs, args.vararg, args.kwarg]
            yield from (a.annotation for a in every if a is not None and a.annotation is not None)
            if node.returns is not None:
                yield node.returns
        elif isinstance(node, ast.AnnAssign):
            yield node.annotation


def any_uses(annotation: ast.expr) -> int:
    """How many times ``Any`` appears in one annotation (quoted ones are parsed too)."""
    uses = 0
    for node in ast.walk(annotation):
        if isinstance(node, ast.Name) and node.id == "Any":
            uses += 1
        elif isinstance(node, ast.Attribute) and node.attr == "Any":
            uses += 1
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            try:
                quoted = ast.parse(node.value, mode="eval").body
            except SyntaxError:
                continue
            uses += any_uses(quoted)
    return uses


def sources(tree: Path, packages: list[str]) -> Iterator[Path]:
    """The hand-written ``.py`` files of the packages (generated ``*_pb2*`` left out)."""
    for package in packages:
        for path in sorted((tree / package).rglob("*.py")):
            if "_pb2" not in path.name:
                yield path


def count(tree: Path, packages: list[str]) -> tuple[Counter[str], Counter[str], Counter[str]]:
    """Per file: annotations, annotations with Any, and uses of Any."""
    total: Counter[str] = Counter()
    with_any: Counter[str] = Counter()
    uses: Counter[str] = Counter()
    for path in sources(tree, packages):
        name = str(path.relative_to(tree))
        for annotation in annotations(ast.parse(path.read_text(), filename=name)):
            total[name] += 1
            found = any_uses(annotation)
            if found:
                with_any[name] += 1
                uses[name] += found
    return total, with_any, uses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("packages", nargs="*", default=list(PACKAGES))
    parser.add_argument("--tree", type=Path, default=ROOT, help="the checkout to count")
    parser.add_argument("--files", type=int, default=0, help="list the N files with most Any")
    args = parser.parse_args()
    total, with_any, uses = count(args.tree, args.packages)
    print(f"{'package':<12} {'annotations':>12} {'with Any':>9} {'uses':>6}")
    for package in args.packages:
        def part(counter: Counter[str]) -> int:
            return sum(n for name, n in counter.items() if name.split("/")[0] == package)
        print(f"{package:<12} {part(total):>12} {part(with_any):>9} {part(uses):>6}")
    print(f"{'all':<12} {sum(total.values()):>12} {sum(with_any.values()):>9} {sum(uses.values()):>6}")
    for name, n in with_any.most_common(args.files):
        print(f"  {n:>5}  {name}")


if __name__ == "__main__":
    main()
