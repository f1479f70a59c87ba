"""One command-line tree, and libraries outside it (issue 33, as ros2cli keeps its library
apart from its verbs).

* nothing outside the command line (``scart/cli.py``, ``scart/commands/``,
  ``dataflow/cli/``) imports it: the Foxglove server, MCAP files and the ROS/YARP/Zenoh
  options the composite elements use live in ``dataflow.foxglove``, ``dataflow.recording``
  and ``dataflow.launch``, and the output every verb shares in ``scart_wire.console``;
* the SCA verbs (``scart.cli``, ``scart.commands``) import no ``dataflow.cli``;
* one tree of verbs, one verb per module, in ``scart.commands`` or ``dataflow.cli.verbs``;
* so the imports into the command line from below it are none (there were 14 import
  statements, 9 pairs of modules: the SCA verbs' 9 into ``dataflow.cli``'s output, ROS and
  YARP options, and the data-flow extension's 5 into its ROS and YARP options and Foxglove
  server), and the import graph has no circle.

Each rule is held twice: by every import statement (lazy and annotation-only ones too)
and by a fresh interpreter's ``sys.modules`` after importing the modules, or running the
verbs, that used to reach the command line.
"""

from __future__ import annotations

from support import ROOT
from test_layering import STACKS, _imports, _loaded_modules, _sources, _within, circles, import_graph

#: The command line: ``python -m scart``, the dispatcher, the SCA verbs and the data-flow verbs.
CLI = ("scart.__main__", "scart.cli", "scart.commands", "dataflow.cli")
SCA_CLI = ("scart.cli", "scart.commands")
#: What the command line used to hold or reach that others use: its libraries now.
LIBRARIES = ("dataflow.foxglove.server", "dataflow.foxglove.gate", "dataflow.foxglove.inner_guard",
             "dataflow.recording.mcap", "dataflow.recording.recorder", "dataflow.recording.playlink",
             "dataflow.launch.ros", "dataflow.launch.yarp", "dataflow.launch.zenoh", "scart_wire.console",
             "scart_wire.jsonschema", "scart.bindings.dataflow.launch", "scart.bindings.dataflow._host")


def statements() -> dict[str, list[str]]:
    """``{module: every module its import statements name}`` over the packages."""
    found = {}
    for package in ("scart", "dataflow", "scart_wire", *STACKS):
        for path in _sources(package):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            found[module] = _imports(path)
    return found


def into_the_cli(graph: dict[str, list[str]]) -> list[str]:
    """The imports that break the rules: into the command line from outside it, and from
    the SCA verbs into the data-flow verbs' package (``importer -> imported``)."""
    return sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets
                  if (_within(t, *CLI) and not _within(m, *CLI))
                  or (_within(m, *SCA_CLI) and _within(t, "dataflow.cli")))


def test_nothing_outside_the_command_line_imports_it() -> None:
    graph = statements()
    assert all(m in graph for m in LIBRARIES)
    assert into_the_cli(graph) == []


def test_the_check_can_fail() -> None:
    """The two kinds of import the rules forbid are both seen."""
    graph = {"scart.bindings.dataflow.launch": ["dataflow.cli.connected"], "scart.commands.call": ["dataflow.cli"],
             "dataflow.cli.verbs.echo": ["dataflow.cli.connected", "dataflow.launch.zenoh"],
             "scart.commands.services": ["scart_wire.console", "scart.commands._sca"]}
    assert into_the_cli(graph) == ["scart.bindings.dataflow.launch -> dataflow.cli.connected",
                                   "scart.commands.call -> dataflow.cli"]


def test_the_sca_verbs_import_no_data_flow_cli() -> None:
    """By statement: every module of ``scart.commands`` and ``scart.cli``."""
    graph = statements()
    sca = {m: [t for t in targets if _within(t, "dataflow.cli")]
           for m, targets in graph.items() if _within(m, *SCA_CLI)}
    assert len(sca) >= 8
    assert {m: t for m, t in sca.items() if t} == {}


def _cli(modules: set[str], *packages: str) -> list[str]:
    return sorted(m for m in modules if _within(m, *packages))


def test_a_fresh_interpreter_importing_the_libraries_loads_no_command_line() -> None:
    loaded = _loaded_modules("import " + ", ".join(LIBRARIES))
    assert set(LIBRARIES) <= loaded
    assert _cli(loaded, *CLI) == []


def test_the_sca_verbs_running_load_no_data_flow_cli() -> None:
    """``scart call``, ``scart services`` (each against no name service: exit 1) and every
    SCA verb's module, imported: no module of ``dataflow.cli`` is loaded."""
    code = ("import contextlib, io, pkgutil, importlib\nimport scart.commands\nfrom scart.cli import main\n"
            "for info in pkgutil.iter_modules(scart.commands.__path__):\n"
            "    importlib.import_module('scart.commands.' + info.name)\n"
            "with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):\n"
            "    assert main(['call', 'Nobody.op', '--ns', '127.0.0.1:1', '--timeout', '0.5']) == 1\n"
            "    assert main(['services', '--ns', '127.0.0.1:1', '--timeout', '0.5']) == 1")
    loaded = _loaded_modules(code)
    assert {"scart.commands.call", "scart.commands.services", "scart_wire.console"} <= loaded
    assert _cli(loaded, "dataflow.cli") == []


def test_the_probe_sees_the_data_flow_cli_when_it_is_loaded_modules() -> None:
    """The fresh-interpreter checks above can fail: a data-flow verb loads its package."""
    loaded = _loaded_modules("import dataflow.cli.verbs.describe")
    assert "dataflow.cli.verbs.describe" in _cli(loaded, *CLI)


def test_the_import_graph_has_no_circle() -> None:
    """The libraries, the command line and everything else (lazy imports too)."""
    graph = import_graph()
    assert {"dataflow.launch.ros", "scart_wire.console", "dataflow.cli.connected"} <= set(graph)
    assert circles(graph) == []


def test_one_tree_one_verb_per_module() -> None:
    """Every verb of the ``scart.verbs`` entry points is a module of its own (ros2cli's
    shape), in one of the two verb packages, with ``HELP``, ``add_arguments`` and ``main``;
    no module serves two verbs, and no verb module is outside the command line."""
    import importlib
    import tomllib

    verbs = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["entry-points"]["scart.verbs"]
    modules = list(verbs.values())
    assert len(verbs) >= 20 and len(set(modules)) == len(modules)
    assert [m for m in modules if not m.startswith(("scart.commands.", "dataflow.cli.verbs."))] == []
    for module in modules:
        loaded = importlib.import_module(module)
        assert all(hasattr(loaded, attr) for attr in ("HELP", "add_arguments", "main")), module
