"""Each transport plug-in is whole, in its own room (issue 33):

* no transport imports another (a transport's home is the package or module its
  ``scart.transports`` entry point names, ``dataflow.transports.<name>``; what transports
  share lives in the SPI and in ``dataflow/transports/_*`` modules, which are no
  transport's and import none);
* the control plane (``dataflow.remote``) holds no transport's serving code: it imports
  no transport's home (only the SPI) and answers none of the methods a transport's
  serving half lists; each serving half is in its transport's home;
* the transports import the control plane only where Zenoh's name service still does;
* a process that only connects (a client: ``scart echo``) loads no serving code.

Every import statement counts: module-level, lazy and annotation-only ones.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

from support import ROOT

from dataflow.remote._servicer import DeployerServicer
from dataflow.transports import BUILTIN, load, names

TRANSPORTS = ROOT / "dataflow" / "transports"


def _module_of(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def _imports(path: Path) -> set[str]:
    """Every module an import statement of ``path`` names (relative ones resolved;
    ``from pkg import name`` names ``pkg.name`` too: it may be a module)."""
    package = _module_of(path) if path.name == "__init__.py" else _module_of(path).rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package
            for _ in range(node.level - 1):
                base = base.rpartition(".")[0]
            module = (f"{base}.{node.module}" if node.module else base) if node.level else (node.module or "")
            found |= {module} | {f"{module}.{alias.name}" for alias in node.names}
    return found


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def homes() -> dict[str, str]:
    """``{transport name: its home}`` for scart's own transports: ``dataflow.transports.X``
    of the module its entry point names (``shm``'s is ipc's: it is ipc's big-sample path)."""
    return {name: ".".join(target.partition(":")[0].split(".")[:3]) for name, target in BUILTIN.items()}


def _sources(module: str) -> list[Path]:
    """The files of ``module`` (a package's every file, or one module's)."""
    folder = ROOT / module.replace(".", "/")
    return sorted(folder.rglob("*.py")) if folder.is_dir() else [folder.with_suffix(".py")]


def transport_imports() -> dict[str, set[str]]:
    """``{file's module: modules it imports}`` over every transport's home."""
    return {_module_of(path): _imports(path) for home in set(homes().values()) for path in _sources(home)}


def crossings(graph: dict[str, set[str]], home_of: dict[str, str]) -> set[str]:
    """``module -> imported`` for each import of one transport's home by another's."""
    found = set()
    for module, imported in graph.items():
        own = next(h for h in home_of.values() if _within(module, h))
        found |= {f"{module} -> {m}" for m in imported for h in home_of.values() if h != own and _within(m, h)}
    return found


def test_the_homes_are_the_transport_folders() -> None:
    assert homes() == {"ipc": "dataflow.transports.ipc", "shm": "dataflow.transports.ipc",
                       "grpc": "dataflow.transports.grpc", "zenoh": "dataflow.transports.zenoh",
                       "ros1": "dataflow.transports.ros1", "ros2": "dataflow.transports.ros2",
                       "yarp": "dataflow.transports.yarp"}
    assert all(_sources(home) and all(p.exists() for p in _sources(home)) for home in homes().values())


def test_no_transport_imports_another() -> None:
    graph = transport_imports()
    folders = {p.parent for p in TRANSPORTS.glob("*/__init__.py")}
    assert len(graph) == sum(1 for f in folders for _ in f.rglob("*.py")) > 20  # every file of every transport read
    assert crossings(graph, homes()) == set()


def test_the_crossing_check_can_fail() -> None:
    """What shm's old folder did (it imported ipc's hub) is found."""
    graph = transport_imports()
    graph["dataflow.transports.shm"] = {"dataflow.transports.ipc._hub"}
    assert crossings(graph, {**homes(), "shm": "dataflow.transports.shm"}) == {
        "dataflow.transports.shm -> dataflow.transports.ipc._hub"}


def test_what_transports_share_imports_no_transport() -> None:
    """The SPI and the shared modules (``dataflow/transports/*.py``): a transport's module
    here would be a crossing in disguise (ipc and grpc share ``_shared``, ROS's two share
    ``_ros*``)."""
    shared = {_module_of(path): _imports(path) for path in sorted(TRANSPORTS.glob("*.py"))}
    assert "dataflow.transports._shared" in shared and "dataflow.transports.serving" in shared
    offenders = {f"{module} -> {m}" for module, imported in shared.items() for m in imported
                 for home in homes().values() if _within(m, home)}
    assert offenders == set()


def _remote_imports() -> dict[str, set[str]]:
    return {_module_of(path): _imports(path) for path in _sources("dataflow.remote")}


def test_the_control_plane_imports_no_transport_only_the_spi() -> None:
    offenders = {f"{module} -> {m}" for module, imported in _remote_imports().items() for m in imported
                 for home in homes().values() if _within(m, home)}
    assert offenders == set()
    spi = {m for imported in _remote_imports().values() for m in imported if _within(m, "dataflow.transports")}
    assert "dataflow.transports.serving" in spi  # the check sees the SPI it allows


def test_the_control_plane_answers_no_method_a_transport_serves_and_each_serving_half_is_at_home() -> None:
    served: dict[str, str] = {}
    for name in names():
        transport = load(name)
        kind = transport.serving()
        if kind is None:
            continue
        assert _within(kind.__module__, homes()[name]), f"{name}'s serving half is in {kind.__module__}"
        served.update({method: name for method in kind.methods})
    assert set(served) == {"Subscribe", "Link", "OpenIpcWriter", "OpenIpcReader"}
    own = {m for m in served if m in vars(DeployerServicer)}
    assert own == set(), f"the control plane's servicer answers {own} itself"


#: The transports' imports of the control plane still there: Zenoh's name service (its
#: lookups resolve to the name service's entries and make a system proxy) and its
#: subscriptions' events (the remote API's ``SampleEvent``).
ZENOH_NAMES = {"dataflow.transports.zenoh -> dataflow.remote.api.SampleEvent",
               "dataflow.transports.zenoh -> dataflow.remote.api",
               "dataflow.transports.zenoh._names -> dataflow.remote._registry",
               "dataflow.transports.zenoh._names -> dataflow.remote._registry.NameEntry",
               "dataflow.transports.zenoh._names -> dataflow.remote.client",
               "dataflow.transports.zenoh._names -> dataflow.remote.client.GrpcSystem"}


def test_transports_import_the_control_plane_only_for_zenohs_name_service() -> None:
    graph = {_module_of(path): _imports(path) for path in sorted(TRANSPORTS.rglob("*.py"))}
    found = {f"{module} -> {m}" for module, imported in graph.items() for m in imported
             if _within(m, "dataflow.remote")}
    assert found == ZENOH_NAMES


#: What a process that only connects must not load: the transports' serving halves.
SERVING = {"dataflow.transports.serving", "dataflow.transports.grpc._serve", "dataflow.transports.ipc._serve",
           "dataflow.transports.ipc._tickets", "dataflow.transports.ipc._shm_serve"}


def _loaded_after(code: str) -> set[str]:
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def test_the_connecting_half_loads_no_serving_code() -> None:
    connect = "from dataflow.transports import load\nfor n in ('ipc', 'shm', 'grpc'): load(n)\nimport dataflow.remote.client"
    assert _loaded_after(connect) & SERVING == set()
    assert _loaded_after(connect + "\nfor n in ('ipc', 'grpc'): load(n).serving()") >= SERVING  # the probe sees them
