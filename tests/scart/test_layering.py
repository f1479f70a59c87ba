"""Which way imports go, and what each entry point loads.

* ``import scart``, ``scart --help`` and ``scart validate`` of a composite without remote
  bindings load no grpc, no protobuf and no protoc (fresh interpreters);
* the runtime loads a binding's transport only when a composite uses it;
* the core never imports an extension; an extension reaches scart only through
  ``scart.spi`` (and the public error tree); ``dataflow`` never imports ``scart``;
* no module of ``scart`` or ``dataflow`` keeps mutable state at module level.
"""

from __future__ import annotations

import ast
import collections
import importlib
import json
import pkgutil
import subprocess
import sys
import weakref
from pathlib import Path

import pytest

import dataflow
import scart
from support import DATA, ROOT

CALCULATOR = ROOT / "composites" / "calculator" / "calculator.composite"
HEAVY = ("grpc", "google.protobuf", "grpc_tools")


def loaded_after(code: str) -> set[str]:
    """The top-level names of the modules a fresh interpreter has after running ``code``
    (which may print to stdout: the last line is ours)."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def heavy(modules: set[str]) -> list[str]:
    return sorted(m for m in modules if m.startswith(HEAVY))


def test_import_scart_loads_no_grpc_protobuf_or_protoc() -> None:
    assert heavy(loaded_after("import scart")) == []


def test_the_probe_can_see_grpc() -> None:
    """The check above can fail: the same probe sees grpc when something imports it."""
    assert "grpc" in loaded_after("import scart, dataflow.remote.client")


def test_help_and_validate_load_no_grpc() -> None:
    run_cli = "from scart.cli import main\nimport contextlib, io\n"
    assert heavy(loaded_after(run_cli + "with contextlib.redirect_stdout(io.StringIO()):\n"
                              "    try:\n        main(['--help'])\n    except SystemExit:\n        pass")) == []
    assert heavy(loaded_after(run_cli + f"assert main(['validate', {str(CALCULATOR)!r}]) == 0")) == []


def test_the_runtime_loads_a_transport_only_when_the_composite_uses_it(tmp_path: Path) -> None:
    local = f"import scart\nwith scart.Runtime.from_file({str(CALCULATOR)!r}) as rt:\n" \
            "    assert rt.service('CalculatorServiceComponent').add(3, 2) == 5"
    assert heavy(loaded_after(local)) == []
    for module in CALCULATOR.parent.glob("*.py"):  # the same components, served over binding.grpc
        (tmp_path / module.name).write_text(module.read_text(encoding="utf-8"), encoding="utf-8")
    provider = (DATA / "grpc_calculator" / "provider.composite").read_text(encoding="utf-8")
    remote = tmp_path / "provider.composite"
    remote.write_text(provider.replace('address="127.0.0.1:50751"', 'address="127.0.0.1:0"'), encoding="utf-8")
    validate = f"import scart\nscart.Runtime.from_file({str(remote)!r})"
    assert heavy(loaded_after(validate)) == []  # its check needs no transport either
    run = f"import scart\nwith scart.Runtime.from_file({str(remote)!r}) as rt:\n    assert rt.addresses()"
    assert "grpc" in loaded_after(run)


def _imports(path: Path) -> list[str]:
    """Every module named by an import statement of ``path`` (relative ones resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


def _sources(package: str) -> list[Path]:
    return sorted(p for p in (ROOT / package.replace(".", "/")).rglob("*.py") if "proto/scart" not in p.as_posix())


def test_the_core_imports_no_extension() -> None:
    core = [p for p in _sources("scart") if "scart/bindings/" not in p.as_posix()]
    offenders = {str(p.relative_to(ROOT)): m for p in core for m in _imports(p) if m == "scart.bindings" or m.startswith("scart.bindings.")}
    assert offenders == {}


def test_extensions_reach_scart_only_through_the_spi() -> None:
    allowed = ("scart.spi", "scart.errors", "scart.bindings")
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _sources("scart.bindings") for m in _imports(p)
                 if (m == "scart" or m.startswith("scart.")) and not (m in allowed or m.startswith("scart.bindings."))}
    assert offenders == set()


def test_dataflow_never_imports_scart() -> None:
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _sources("dataflow") for m in _imports(p)
                 if m == "scart" or m.startswith("scart.")}
    assert offenders == set()


MUTABLE = (dict, list, set, bytearray, collections.deque, weakref.WeakKeyDictionary, weakref.WeakValueDictionary)


def _modules(package: object) -> list[str]:
    names = [package.__name__]  # type: ignore[attr-defined]
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):  # type: ignore[attr-defined]
        if ".proto.scart" not in info.name and not info.name.endswith("__main__"):
            names.append(info.name)
    return names


@pytest.mark.parametrize("package", [scart, dataflow], ids=["scart", "dataflow"])
def test_no_module_level_mutable_state(package: object) -> None:
    """Constant tables are read-only (MappingProxyType, tuples, frozensets); registries and
    settings belong to objects a caller owns. The one process-wide registry is
    ``dataflow.registry`` (a TypeRegistry object, by design: types register at import)."""
    found = []
    for name in _modules(package):
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if attr.startswith("__") and attr.endswith("__"):
                continue
            if isinstance(value, MUTABLE):
                found.append(f"{name}.{attr} ({type(value).__name__})")
    assert found == []


CLI_PACKAGES = ("scart/commands", "dataflow/cli")


def _cli_imports() -> dict[str, set[str]]:
    """``{module: CLI modules it imports}`` over scart.cli, scart.commands and dataflow.cli
    (``from pkg import sub`` counts as importing ``pkg.sub``; lazy imports count too)."""
    paths = [ROOT / "scart" / "cli.py"] + [p for pkg in CLI_PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))]
    names = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p for p in paths}
    graph: dict[str, set[str]] = {}
    for name, path in names.items():
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module:
                found.add(node.module)
                found |= {f"{node.module}.{a.name}" for a in node.names}
        graph[name] = {m for m in found if m in names and m != name}
    return graph


def test_the_cli_modules_import_each_other_in_no_circle() -> None:
    graph = _cli_imports()
    cycles: list[list[str]] = []

    def visit(node: str, path: list[str]) -> None:
        for nxt in sorted(graph[node]):
            if nxt in path:
                cycles.append(path[path.index(nxt):] + [nxt])
            elif len(path) < 20:
                visit(nxt, path + [nxt])

    for start in graph:
        visit(start, [start])
    assert cycles == []


def test_shared_cli_helpers_import_no_verb() -> None:
    """What verbs share (output, Zenoh options, MCAP files, JSON Schemas, the Foxglove
    server, the composite and SCA helpers) imports no verb module."""
    graph = _cli_imports()
    verbs = {m for m in graph if m.startswith("dataflow.cli.verbs.") or
             (m.startswith("scart.commands.") and not m.rpartition(".")[2].startswith("_"))}
    shared = [m for m in graph if m not in verbs and m not in ("scart.cli", "dataflow.cli.verbs")]
    assert {m: sorted(graph[m] & verbs) for m in shared if graph[m] & verbs} == {}
    assert "dataflow.cli.output" in shared and "scart.commands._composite" in shared


def test_a_verb_loads_its_own_module_only() -> None:
    """``scart describe --help`` imports the describe verb, not the others (ros2cli's shape)."""
    code = ("from scart.cli import main\nimport contextlib, io\nwith contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n        main(['describe', '--help'])\n    except SystemExit:\n        pass")
    loaded = {m for m in _loaded_modules(code) if m.startswith(("dataflow.cli.verbs.", "scart.commands."))}
    assert loaded == {"dataflow.cli.verbs.describe"}


def _loaded_modules(code: str) -> set[str]:
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stdout.strip().splitlines()[-1]))
