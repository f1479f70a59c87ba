"""``<scart:external task="youBotDriver" ns="HOST:PORT"/>``: a data-flow task this
composite uses and another process serves (another ``scart run``, a ``scart deploy``).

An SCA composite says what it needs from outside at its boundary (a composite
``<reference>``), and refuses a wire to a component it does not know; the data-flow
side does the same. A ``scart:connect`` end or a bridge input that names no task or
bridge of the composite is an error ("did you mean"), unless that task is declared
external here (or the element names its own ``ns``): a typo such as ``to="filtr.inp"``
no longer passes ``scart validate`` to wait forever under ``scart run``.

* ``task``: the task's name as the composite writes it (``--remap`` applies to it as to
  the others);
* ``ns``: the name service to find it in (default: the runtime's, ``scart run --ns``).

``scart validate --online`` asks that name service whether the task is there; ``scart
run`` makes the links when it appears, saying once what it waits for. Declaring a task
of this composite external is an error, as is declaring one twice.
"""

from __future__ import annotations

from collections.abc import Mapping

from scart.bindings.dataflow._host import TASK_KIND
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Problem, parse_host_port

__all__ = ["EXTERNAL", "ExternalElement", "externals"]

EXTERNAL = "SCART-T008"  # scart:external: no task name, a task of this composite, declared twice, a bad ns


def externals(assembly: AssemblyView) -> Mapping[str, str | None]:
    """The tasks the composite declares external, by written name (with its nesting
    prefix), each with its ``ns`` (None: the runtime's name service)."""
    return {prefix + el.attributes.get("task", "").strip(): el.attributes.get("ns")
            for prefix, el in assembly.elements_of("external")}


class ExternalElement(ElementProvider):
    """The ``scart:external`` composite element (see the module docstring). It runs
    nothing: the links naming the task are made by ``scart:connect`` and bridges."""

    name = "external"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        """No name, a task or bridge of this composite, a second declaration, a bad ``ns``."""
        out: list[Problem] = []
        bridges = {prefix + el.attributes.get("name", "") for prefix, el in assembly.elements_of("bridge")}
        seen: set[str] = set()
        for prefix, el in elements:
            task = prefix + el.attributes.get("task", "").strip()
            ns = el.attributes.get("ns")

            def add(message: str, _el: Element = el) -> None:
                out.append(Problem(EXTERNAL, f"<scart:external> {message}", _el.loc.path, _el.loc.line))

            if task == prefix:
                add("needs task=\"NAME\", the task another process serves")
            elif task in bridges or (task in assembly.nodes and assembly.nodes[task].kind == TASK_KIND):
                add(f"task {task!r} is a {'bridge' if task in bridges else 'task'} of this composite, not external")
            elif task in seen:
                add(f"task {task!r} is declared external twice")
            if ns is not None and parse_host_port(ns.strip()) is None:
                add(f"ns {ns[:80]!r}: expected HOST:PORT")
            seen.add(task)
        return out
