"""Which way imports go, and what each entry point loads.

* ``import scart``, ``scart --help`` and ``scart validate`` of a composite without remote
  bindings load no grpc, no protobuf and no protoc (fresh interpreters);
* the runtime loads a binding's transport only when a composite uses it;
* the core never imports an extension; an extension reaches scart only through
  ``scart.spi`` (and the public error tree); ``dataflow`` never imports ``scart``;
* the wire layer (``scart_wire``) imports neither world; ``dataflow``'s core imports no
  remote module; ``scart/commands`` imports no extension, and the composite verbs name no
  data-flow concept;
* the runtime import graph (module-level and lazy imports) has no circle;
* the README's layer table is what the import graph says;
* no module of ``scart``, ``dataflow`` or ``scart_wire`` keeps mutable state at module
  level, but the process-wide registries of :data:`PROCESS_WIDE`, each for its reason.
"""

from __future__ import annotations

import ast
import collections
import importlib
import json
import dataclasses
import enum
import pkgutil
import re
import subprocess
import sys
import weakref
from pathlib import Path

import pydantic
import pytest

import dataflow
import scart
import scart_wire
import scart_yarp
from support import DATA, ROOT
from support.imports import imports_of as _imports

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


def _within(module: str, *packages: str) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


def test_the_wire_layer_imports_neither_world() -> None:
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _sources("scart_wire") for m in _imports(p)
                 if _within(m, "scart", "dataflow")}
    assert offenders == set()


#: The protocol stacks: libraries of their own, which know nothing of scart (RTT's rtt_ros, YARP's os::impl).
STACKS = ("scart_yarp", "scart_ros1", "scart_ros2")


@pytest.mark.parametrize("stack", STACKS)
def test_a_protocol_stack_imports_nothing_of_scart(stack: str) -> None:
    """Lazy and annotation-only imports count too; and a fresh interpreter that imports the
    stack has loaded no module of scart's."""
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _sources(stack) for m in _imports(p)
                 if _within(m, "scart", "dataflow", "scart_wire", "pydantic", "grpc")}
    assert offenders == set()
    loaded = loaded_after(f"import importlib, pkgutil, {stack}\n"
                          f"for m in pkgutil.walk_packages({stack}.__path__, '{stack}.'): importlib.import_module(m.name)")
    assert not loaded & {"scart", "dataflow", "scart_wire", "pydantic", "grpc"}


#: dataflow's core: its top-level modules, and the transport SPI the core reads names from.
DATAFLOW_CORE = [*sorted((ROOT / "dataflow").glob("*.py")),
                 *(ROOT / "dataflow" / "transports" / f"{m}.py"
                   for m in ("__init__", "ends", "frames", "served", "sinks", "streams"))]


def test_dataflows_core_imports_no_remote_module() -> None:
    """Lazy and annotation-only imports count too: the control plane (``dataflow.remote``)
    and the command line sit above the core, which finds its server through the
    ``scart.servers`` entry points (``Deployer.serve``)."""
    assert len(DATAFLOW_CORE) > 15
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in DATAFLOW_CORE for m in _imports(p)
                 if _within(m, "dataflow.remote", "dataflow.cli")}
    assert offenders == set()


COMPOSITE_VERBS = ["run", "validate", "graph", "_composite"]
DATAFLOW_WORDS = re.compile(r"implementation\.task|TASK_KIND|_dataflow|\bremap\b|Remap|foxglove|\bserve=|\.ns_address")


def test_scart_commands_import_no_extension_and_the_composite_verbs_name_no_data_flow() -> None:
    """What an extension adds to ``run``, ``validate`` and ``graph`` comes through its
    ``LaunchProvider``: these verbs import nothing of ``dataflow`` and say none of its words."""
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _sources("scart.commands") for m in _imports(p)
                 if _within(m, "scart.bindings")}
    assert offenders == set()
    for verb in COMPOSITE_VERBS:
        path = ROOT / "scart" / "commands" / f"{verb}.py"
        assert [m for m in _imports(path) if _within(m, "dataflow")] == [], verb
        assert DATAFLOW_WORDS.findall(path.read_text(encoding="utf-8")) == [], verb


def _runtime_imports(path: Path, module: str, known: set[str]) -> set[str]:
    """The modules of ``known`` that ``path`` (module ``module``) imports when it runs:
    module-level and lazy imports; not those under ``if TYPE_CHECKING:`` (annotations
    only). ``from pkg import sub`` imports ``pkg.sub``; ``import a.b`` imports ``a.b``."""
    base = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()

    class Visitor(ast.NodeVisitor):
        def visit_If(self, node: ast.If) -> None:
            if "TYPE_CHECKING" in ast.unparse(node.test):
                for child in node.orelse:
                    self.visit(child)
                return
            self.generic_visit(node)

        def visit_Import(self, node: ast.Import) -> None:
            found.update(_nearest(a.name, known) for a in node.names)

        def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
            source = base
            for _ in range(node.level - 1):
                source = source.rpartition(".")[0]
            name = (f"{source}.{node.module}" if node.module else source) if node.level else (node.module or "")
            for alias in node.names:
                found.add(f"{name}.{alias.name}" if f"{name}.{alias.name}" in known else _nearest(name, known))

    Visitor().visit(ast.parse(path.read_text(encoding="utf-8")))
    return found - {"", module}


def _nearest(name: str, known: set[str]) -> str:
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name


def import_graph() -> dict[str, set[str]]:
    """``{module: modules it imports when it runs}`` over scart, dataflow and scart_wire."""
    paths = {".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
             for package in ("scart", "dataflow", "scart_wire", *STACKS) for p in _sources(package)}
    return {name: _runtime_imports(path, name, set(paths)) for name, path in paths.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                group = []
                while True:
                    member = stack.pop()
                    group.append(member)
                    if member == node:
                        break
                if len(group) > 1:
                    found.append(sorted(group))
    return found


def test_the_runtime_import_graph_has_no_circle() -> None:
    graph = import_graph()
    assert "scart_wire.rpc" in graph["dataflow.remote.server"]  # module level
    assert "dataflow.transports.streams" in graph["dataflow.deployer"]  # lazy, in Deployer.stream
    assert circles(graph) == []


def test_the_circle_finder_can_fail() -> None:
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    graph = import_graph()
    graph["scart_wire.types"].add("dataflow.ports")  # what a wire module importing a port would make
    assert any("scart_wire.types" in group for group in circles(graph))


#: The README's layers, most specific first (a module belongs to the first that names it).
LAYERS = (*STACKS, "scart_wire", "dataflow.transports", "dataflow.remote", "dataflow.foxglove", "dataflow.recording",
          "dataflow.launch", "dataflow.cli", "dataflow", "scart.bindings", "scart.spi", "scart.errors", "scart")


def _layer(module: str) -> str:
    return next(layer for layer in LAYERS if _within(module, layer))


def _readme_layers() -> dict[str, set[str]]:
    """The README's layer table: ``{layer: the layers it imports}``."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("<!-- layers:"):text.index("<!-- /layers -->")]
    table: dict[str, set[str]] = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0].startswith("`"):
            table[cells[0].strip("`")] = set(re.findall(r"`([\w.]+)`", cells[3]))
    return table


def test_the_readmes_layer_table_is_the_import_graph() -> None:
    """Every import statement (lazy and annotation-only ones too), by layer: the README's
    Architecture table says exactly which layers each one imports."""
    found: dict[str, set[str]] = {}
    for package in ("scart", "dataflow", "scart_wire", *STACKS):
        for path in _sources(package):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            source = _layer(module)
            source = "scart" if source in ("scart.spi", "scart.errors") else source
            targets = {_layer(m) for m in _imports(path) if _within(m, "scart", "dataflow", "scart_wire", *STACKS)}
            if source == "scart":
                targets -= {"scart.spi", "scart.errors"}
            found.setdefault(source, set()).update(targets - {source})
    assert _readme_layers() == found


MUTABLE = (dict, list, set, bytearray, collections.deque, weakref.WeakKeyDictionary, weakref.WeakValueDictionary)


def _modules(package: object) -> list[str]:
    names = [package.__name__]  # type: ignore[attr-defined]
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):  # type: ignore[attr-defined]
        if ".proto.scart" not in info.name and not info.name.endswith("__main__"):
            names.append(info.name)
    return names


@pytest.mark.parametrize("package", [scart, dataflow, scart_wire, scart_yarp],
                         ids=["scart", "dataflow", "scart_wire", "scart_yarp"])
def test_no_module_level_mutable_state(package: object) -> None:
    """Constant tables are read-only (MappingProxyType, tuples, frozensets); registries and
    settings belong to objects a caller owns, but the process-wide registries of
    :data:`PROCESS_WIDE` (objects, each for its reason)."""
    found = []
    for name in _modules(package):
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if attr.startswith("__") and attr.endswith("__"):
                continue
            if isinstance(value, MUTABLE):
                found.append(f"{name}.{attr} ({type(value).__name__})")
    assert found == []


#: Every process-wide registry, and why it cannot belong to an object a caller owns.
PROCESS_WIDE = {
    "scart_wire.types.registry": "the type registry: types register at import (@register_type), and every "
                                 "decode, in any thread and either world, must find them",
    "dataflow.transports.default": "the transport registry: the scart.transports entry points are "
                                   "process-wide; each transport is loaded once, and one that failed is not "
                                   "imported again on every reconnect",
    "dataflow.transports.ipc._hub.Hub._the": "the ipc hub: one io thread reads every ipc socket of the process "
                                             "(RTT's mqueue dispatcher), counted by acquire/release",
    "dataflow.transports.zenoh._default": "the Zenoh default session: the one this process's streams use when "
                                          "they name none (scart deploy --zenoh); its opener owns it",
}


def _stateful(value: object) -> bool:
    """An instance of one of our classes that holds state (not a class, enum, frozen value
    or stateless sentinel)."""
    kind = type(value)
    if kind.__module__.partition(".")[0] not in ("scart", "dataflow", "scart_wire"):
        return False
    if isinstance(value, (type, enum.Enum, BaseException, tuple)) or not vars(value):
        return False
    if dataclasses.is_dataclass(value) and kind.__dataclass_params__.frozen:  # type: ignore[attr-defined]
        return False
    return not (isinstance(value, pydantic.BaseModel) and value.model_config.get("frozen"))


def _process_wide() -> set[str]:
    """Module-level stateful objects (by the module that makes them), names a ``global``
    statement rebinds, and class attributes set through ``cls`` outside
    ``__init_subclass__`` (a class-held singleton)."""
    found = set()
    for package in (scart, dataflow, scart_wire):
        for name in _modules(package):
            for attr, value in vars(importlib.import_module(name)).items():
                if _stateful(value) and type(value).__module__ == name:
                    found.add(f"{name}.{attr}")
    for package in ("scart", "dataflow", "scart_wire"):
        for path in _sources(package):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            tree = ast.parse(path.read_text(encoding="utf-8"))
            found |= {f"{module}.{n}" for node in ast.walk(tree) if isinstance(node, ast.Global) for n in node.names}
            for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
                for fn in (n for n in cls.body if isinstance(n, ast.FunctionDef) and n.name != "__init_subclass__"):
                    found |= {f"{module}.{cls.name}.{target.attr}" for node in ast.walk(fn)
                              if isinstance(node, ast.Assign) for target in node.targets
                              if isinstance(target, ast.Attribute) and ast.unparse(target.value) == "cls"}
    return found


def test_the_process_wide_registries_are_these_each_for_its_reason() -> None:
    assert _process_wide() == set(PROCESS_WIDE)
    assert all(len(reason) > 40 for reason in PROCESS_WIDE.values())


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
    """What verbs share inside the command line (running a verb connected, the composite and
    SCA helpers) imports no verb module. What they share outside it (the output module, the
    Foxglove server, MCAP files, the ROS/YARP/Zenoh options) imports no command line at all:
    ``test_layering_cli.py``."""
    graph = _cli_imports()
    verbs = {m for m in graph if m.startswith("dataflow.cli.verbs.") or
             (m.startswith("scart.commands.") and not m.rpartition(".")[2].startswith("_"))}
    shared = [m for m in graph if m not in verbs and m not in ("scart.cli", "dataflow.cli.verbs")]
    assert {m: sorted(graph[m] & verbs) for m in shared if graph[m] & verbs} == {}
    assert "dataflow.cli.connected" in shared and "scart.commands._composite" in shared


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


def test_every_type_ignore_names_its_code_and_says_why() -> None:
    """mypy runs in CI (``.ci/run``); where it is told to look away, the line says which
    error and why: ``# type: ignore[code]  # reason``."""
    bare = re.compile(r"#\s*type:\s*ignore(?!\[[\w-]+(?:,\s*[\w-]+)*\]  # \S)")
    offenders = [f"{p.relative_to(ROOT)}:{n}" for package in ("scart", "dataflow", "scart_wire", *STACKS)
                 for p in _sources(package)
                 for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if bare.search(line)]
    assert offenders == []
