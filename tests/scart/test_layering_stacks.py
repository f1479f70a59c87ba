"""The protocol stacks are libraries of their own (issue 33): a ROS 1 node
(``scart_ros1``), a DDS participant with ROS 2's names (``scart_ros2``) and YARP's
protocols (``scart_yarp``) know nothing of scart's ports.

* no module of a stack imports ``dataflow``, ``scart``, ``scart_wire``, pydantic or grpc,
  nor another stack (lazy and annotation-only imports count too);
* a fresh interpreter that imports every module of a stack has loaded none of those;
* each stack is tested on its own, against the real peer: ``tests/<stack>/`` exists and
  its tests import no module of scart's either;
* no stack keeps mutable state at module level (constant tables are read-only), but the
  process-wide registries of :data:`PROCESS_WIDE`, each for its reason;
* pyproject ships each stack and type-checks it.
"""

from __future__ import annotations

import dataclasses
import enum
import importlib
import json
import pkgutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from support import ROOT
from support.imports import imports_of

#: The protocol stacks, and what no module of theirs may import.
STACKS = ("scart_yarp", "scart_ros1", "scart_ros2")
SCART = ("scart", "dataflow", "scart_wire", "pydantic", "grpc")


def _within(module: str, *packages: str) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


def offenders(folder: Path, forbidden: tuple[str, ...]) -> set[str]:
    """``path: module`` for each import under ``folder`` of a module within ``forbidden``."""
    found = set()
    for path in sorted(folder.rglob("*.py")):
        found |= {f"{path.relative_to(ROOT)}: {m}" for m in imports_of(path) if _within(m, *forbidden)}
    return found


@pytest.mark.parametrize("stack", STACKS)
def test_a_stack_imports_nothing_of_scart_nor_another_stack(stack: str) -> None:
    others = tuple(s for s in STACKS if s != stack)
    assert len(list((ROOT / stack).rglob("*.py"))) > 5
    assert offenders(ROOT / stack, (*SCART, *others)) == set()


def test_the_import_check_can_fail() -> None:
    """The same check finds the adapter's imports of scart's own modules."""
    assert offenders(ROOT / "dataflow" / "transports" / "ros1", ("dataflow",))


@pytest.mark.parametrize("stack", STACKS)
def test_a_fresh_interpreter_importing_a_stack_loads_nothing_of_scart(stack: str) -> None:
    probe = (f"import importlib, json, pkgutil, sys, {stack}\n"
             f"for m in pkgutil.walk_packages({stack}.__path__, '{stack}.'):\n"
             f"    importlib.import_module(m.name)\n"
             f"print(json.dumps(sorted(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    assert {f"{stack}.{m.name}" for m in pkgutil.iter_modules([str(ROOT / stack)])} <= loaded
    assert sorted(m for m in loaded if _within(m, *SCART, *(s for s in STACKS if s != stack))) == []


@pytest.mark.parametrize("stack", STACKS)
def test_a_stack_is_tested_on_its_own(stack: str) -> None:
    """Its tests drive it alone (against the real peer, through tests/support's helpers
    that start it): they import no module of scart's."""
    folder = ROOT / "tests" / stack
    assert len(list(folder.glob("test_*.py"))) >= 2
    assert offenders(folder, SCART) == set()


#: Every process-wide registry of a stack, and why it cannot belong to an object a caller owns.
PROCESS_WIDE = {
    "scart_ros2.network.DOMAINS": "the Cyclone DDS domains: a process joins a domain once, shared by its "
                                  "participants and counted",
}


def _modules(stack: str) -> list[str]:
    package = importlib.import_module(stack)
    return [stack, *(m.name for m in pkgutil.walk_packages(package.__path__, stack + "."))]


def _stateful(value: object, stack: str) -> bool:
    """An instance of one of the stack's classes that holds state in its ``__dict__`` (not
    a class, enum, exception, frozen value, slotted value or stateless sentinel)."""
    kind = type(value)
    if not _within(kind.__module__, stack) or isinstance(value, (type, enum.Enum, BaseException, tuple)):
        return False
    if dataclasses.is_dataclass(value) and kind.__dataclass_params__.frozen:  # type: ignore[attr-defined]
        return False
    return bool(getattr(value, "__dict__", None))


@pytest.mark.parametrize("stack", STACKS)
def test_a_stack_keeps_no_mutable_state_at_module_level(stack: str) -> None:
    mutable = (dict, list, set, bytearray)
    found = []
    for name in _modules(stack):
        for attr, value in vars(importlib.import_module(name)).items():
            if attr.startswith("__") and attr.endswith("__"):
                continue
            if isinstance(value, mutable) or (_stateful(value, stack) and type(value).__module__ == name):
                found.append(f"{name}.{attr}")
    assert sorted(found) == sorted(k for k in PROCESS_WIDE if _within(k, stack))
    assert all(len(reason) > 40 for reason in PROCESS_WIDE.values())


def test_pyproject_ships_and_type_checks_every_stack() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert {f"{s}*" for s in STACKS} <= set(project["tool"]["setuptools"]["packages"]["find"]["include"])
    assert set(STACKS) <= set(project["tool"]["mypy"]["files"])
