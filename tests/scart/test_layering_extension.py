"""The shape of the data-flow extension, and what the examples may import.

* the examples (``composites/``) import public modules only: no ``_``-prefixed module,
  and of an extension package (``scart.bindings``) only its settings module — the rest of
  an extension is reached through the composite's XML;
* the data-flow extension has one module per composite element, named after it;
* the bridge is split into its spec, its checks and its runtime: the spec imports
  neither, and the checks load nothing of the runtime (an ``activate`` may, lazily);
* the youBot monitor (``scart_monitor``) is part of the package, page included, knows
  nothing of scart or ``dataflow``, and the examples keep no copy of it.
"""

from __future__ import annotations

import tomllib
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from support import ROOT
from support.imports import imports_of as _imports

EXTENSION = "scart.bindings.dataflow"
BRIDGE = ROOT / "scart" / "bindings" / "dataflow" / "bridge"


def _examples() -> list[Path]:
    return sorted((ROOT / "composites").rglob("*.py"))


def _private(module: str) -> bool:
    return any(part.startswith("_") for part in module.split(".") if part != "__future__")


def test_the_examples_import_no_private_module() -> None:
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _examples() for m in _imports(p) if _private(m)}
    assert not offenders


def test_the_examples_import_of_an_extension_only_its_settings() -> None:
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in _examples() for m in _imports(p)
                 if m.split(".")[:2] == ["scart", "bindings"] and not (len(m.split(".")) == 4 and m.endswith(".settings"))}
    assert not offenders


def test_the_rules_above_see_a_private_import() -> None:
    """The check itself: what it would refuse."""
    assert _private("dataflow.transports.ros2._calls") and _private("scart.bindings.dataflow._host")
    assert not _private("scart.bindings.dataflow.settings") and not _private("__future__")


def _module_of_element(name: str) -> str:
    """``implementation.task`` → ``task``, ``binding.dataflow`` → ``binding``, ``connect`` → ``connect``."""
    if name.startswith("implementation."):
        return name.removeprefix("implementation.")
    return "binding" if name.startswith("binding.") else name


ELEMENTS = sorted(e.name for e in entry_points(group="scart.extensions") if e.value.startswith(EXTENSION))


def test_the_extension_has_elements() -> None:
    assert {"implementation.task", "connect", "bridge", "stream", "rosservice", "yarprpc", "frames"} <= set(ELEMENTS)


@pytest.mark.parametrize("name", ELEMENTS)
def test_each_composite_element_has_a_module_of_its_own(name: str) -> None:
    (ep,) = [e for e in entry_points(group="scart.extensions") if e.name == name]
    module = ep.load().__module__
    home = f"{EXTENSION}.{_module_of_element(name)}"
    assert module == home or module.startswith(home + "."), (name, module)


def test_the_bridge_spec_imports_neither_its_checks_nor_its_runtime() -> None:
    assert [m for m in _imports(BRIDGE / "_spec.py") if m.startswith(f"{EXTENSION}.bridge.")] == []


@pytest.mark.parametrize("checks", ["_resolve.py", "_element.py"])
def test_the_bridge_checks_load_nothing_of_its_runtime(checks: str) -> None:
    runtime = {f"{EXTENSION}.bridge._runtime", f"{EXTENSION}.bridge._task"}
    assert not runtime & set(_imports(BRIDGE / checks, top_level_only=True))


MONITOR = ROOT / "scart_monitor"


def test_the_monitor_knows_nothing_of_scart_or_dataflow() -> None:
    offenders = {f"{p.relative_to(ROOT)}: {m}" for p in sorted(MONITOR.rglob("*.py")) for m in _imports(p)
                 if m.split(".")[0] in ("scart", "dataflow")}
    assert not offenders


def test_the_wheel_ships_the_monitor_and_its_page() -> None:
    """The package list takes ``scart_monitor``, and its package data every file of the page."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    assert "scart_monitor*" in config["packages"]["find"]["include"]
    shipped = config["package-data"]["*"]
    page = sorted((MONITOR / "static").iterdir())
    assert page and all(f"*{f.suffix}" in shipped for f in page), page


def test_the_examples_keep_no_copy_of_the_monitor() -> None:
    assert not (ROOT / "composites" / "youbot" / "monitor").exists()
    component = (ROOT / "composites" / "youbot" / "monitor_component.py")
    assert "scart_monitor" in _imports(component)
