"""A sample's way from ``OutputPort.write`` through the fan-out and the channel ends to a
reader is typed (issue 33): no annotation on it says ``Any``, so mypy and a reader follow
the sample's type ``T`` end to end. Read from the sources (annotations only, nothing run);
``benchmarks/count_any.py`` counts the rest of the tree."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

from support import ROOT

_spec = importlib.util.spec_from_file_location("count_any", ROOT / "benchmarks" / "count_any.py")
assert _spec is not None and _spec.loader is not None
count_any = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(count_any)

#: file -> the functions (``Class.method``) on the sample path and the attributes
#: (``Class.attr``, assigned in ``__init__``) that hold what it goes through.
SAMPLE_PATH = {
    "dataflow/ports.py": [
        "OutputPort.write", "OutputPort._write_local", "OutputPort.attach_fanout", "OutputPort._fanout",
        "OutputPort._storages", "OutputPort._single_data", "OutputPort.connect_to",
        "ChannelConnection.write", "ChannelConnection.store", "InputPort.read", "InputPort.read_newest",
        "InputPort._read_many", "InputPort._sources", "Connection.__init__",
    ],
    "dataflow/buffers.py": [
        "Storage.write", "Storage.write_now", "Storage.read", "Storage.read_newest", "Storage.readers",
        "DataObject.write", "DataObject.read", "Buffer.write", "Buffer.read", "Buffer._items",
        "WaitingStorage.write", "WaitingStorage.read",
    ],
    "dataflow/transports/ends.py": [
        "Fanout.__init__", "Fanout.push", "Fanout.ends", "attach", "detach", "WriterEnd.__init__",
        "WriterEnd.offer", "WriterEnd._keep", "WriterEnd._queue", "WriterEnd._inbox",
        "ReaderEnd.receive", "ReaderEnd.storage", "ReaderEnd.on_frame",
    ],
    "dataflow/transports/frames.py": ["feed"],
}


def _annotations(path: Path, name: str) -> list[ast.expr]:
    """The annotations of ``name`` (a function's parameters and return, or an attribute
    annotated in its class's ``__init__``) in the module at ``path``. What a transport
    makes of a sample (its carrier's encoding) is the transport's own: not checked here."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    owner, _, member = name.rpartition(".")
    scope: list[ast.stmt] = tree.body
    if owner:
        found = [n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == owner]
        assert found, f"{path.name}: no class {owner}"
        scope = found[0].body
    for node in scope:
        if isinstance(node, ast.FunctionDef) and node.name == member:
            args = node.args
            every = [*args.posonlyargs, *args.args, *args.kwonlyargs, args.vararg, args.kwarg]
            found = [a.annotation for a in every if a is not None and a.annotation is not None]
            return found + ([node.returns] if node.returns is not None else [])
    for node in scope:
        if isinstance(node, ast.FunctionDef) and node.name == "__init__":
            for sub in ast.walk(node):
                if (isinstance(sub, ast.AnnAssign) and isinstance(sub.target, ast.Attribute)
                        and sub.target.attr == member):
                    return [sub.annotation]
    raise AssertionError(f"{path.name}: no function or annotated attribute {name}")


@pytest.mark.parametrize("where", sorted(SAMPLE_PATH))
def test_no_annotation_on_the_sample_path_says_any(where: str) -> None:
    path = ROOT / where
    offenders = []
    for name in SAMPLE_PATH[where]:
        annotations = _annotations(path, name)
        assert annotations, f"{where}: {name} has no annotation"
        offenders += [f"{name}: {ast.unparse(a)}" for a in annotations if count_any.any_uses(a)]
    assert offenders == [], f"{where}: Any on the sample path"


def test_the_count_sees_any_wherever_an_annotation_says_it(tmp_path: Path) -> None:
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "mod.py").write_text(
        "import typing\nfrom typing import Any\n"
        "def f(a: Any, b: int, *c: 'dict[str, Any]', **d: typing.Any) -> list[Any]: ...\n"
        "x: int = 1\ny: tuple[Any, Any] = (1, 2)\nclass C:\n    def g(self, v: object) -> None:\n"
        "        self.z: Any = v\n")
    (tmp_path / "pkg" / "mod_pb2.py").write_text("from typing import Any\nq: Any = 1\n")
    total, with_any, uses = count_any.count(tmp_path, ["pkg"])
    assert (total["pkg/mod.py"], with_any["pkg/mod.py"], uses["pkg/mod.py"]) == (10, 6, 7)
    assert "pkg/mod_pb2.py" not in total  # protoc's output is nobody's to type
