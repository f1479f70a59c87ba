"""``scart graph FILE``: a composite as Graphviz DOT on stdout (components, wires,
promotions, bindings and the data-flow links, names as remapped). Drawing it needs
Graphviz's ``dot`` (``apt-get install graphviz``): ``scart graph X.composite | dot -Tsvg
> x.svg``."""

from __future__ import annotations

import argparse

from scart.commands._composite import TASK_KIND, add_launch_options, assemble_or_say, endpoint_text, settings_of
from scart.graph import Assembly, Target
from scart.model import Binding, Composite
from scart.settings import Remap

HELP = "print a composite as Graphviz DOT (draw it with Graphviz: | dot -Tsvg > x.svg)"
DESCRIPTION = ("Print a composite as Graphviz DOT. Drawing it needs Graphviz's dot (apt-get install graphviz): "
               "scart graph X.composite | dot -Tsvg > x.svg")


def add_arguments(graph: argparse.ArgumentParser) -> None:
    """The file and the launch options."""
    graph.add_argument("file", help="the .composite file")
    add_launch_options(graph)


def main(args: argparse.Namespace) -> int:
    """Print the DOT text; 2 when the composite is invalid."""
    return cmd_graph(args)


def cmd_graph(args: argparse.Namespace) -> int:
    """Print the composite as Graphviz DOT; 2 (problems on stderr) if invalid."""
    settings = settings_of(args)
    if settings is None:
        return 2
    assembly = assemble_or_say(args.file, args.overrides, settings, contributions=args.contributions)
    if assembly is None:
        return 2
    print(to_dot(assembly, settings.remap))
    return 0


def _clusters(assembly: Assembly, prefix: str, depth: int, remap: Remap) -> list[str]:
    """Component boxes of one composite level; nested composites as nested clusters."""
    pad = "  " * depth
    lines: list[str] = []
    subs: list[str] = []
    for path, node in assembly.nodes.items():
        if not path.startswith(prefix):
            continue
        rest = path[len(prefix):]
        if "/" in rest:
            sub = prefix + rest.split("/")[0] + "/"
            if sub not in subs:
                subs.append(sub)
            continue
        shown = remap.component(path) if node.kind == TASK_KIND else rest  # a task: the name it runs under
        label = f"{shown}\\n[{', '.join(node.ctype.services)}]"
        lines.append(f'{pad}{_q(path)} [label="{label}"];')
    for sub in subs:
        lines.append(f"{pad}subgraph {_q('cluster_' + sub.rstrip('/'))} {{")
        lines.append(f"{pad}  label={_q(sub.rstrip('/') + ' (implementation.composite)')};")
        lines += _clusters(assembly, sub, depth + 1, remap)
        lines.append(f"{pad}}}")
    return lines


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_dot(assembly: Assembly, remap: Remap | None = None) -> str:
    """The assembly as DOT: a box per component (label lists its services), an edge per
    wire labelled with the reference, dashed edges for promoted services and references,
    a note-shaped node per binding endpoint, bold edges for data-flow links (``scart:connect``,
    bridge inputs); task and port names as ``remap`` makes them run."""
    remap = remap or Remap()
    c = assembly.composite
    out = [f"digraph {_q(c.name)} {{", "  rankdir=LR;", "  node [shape=box, fontname=Helvetica];"]
    out += _clusters(assembly, "", 1, remap)
    for path, node in assembly.nodes.items():
        for ref, eps in node.references.items():
            for ep in eps:
                if isinstance(ep, Target):
                    out.append(f"  {_q(path)} -> {_q(ep.node)} [label={_q(f'{ref} -> {ep.service}')}];")
                else:
                    bid = f"{path}.{ref}:{ep.binding.kind}"
                    out.append(f"  {_q(bid)} [shape=note, label={_q(endpoint_text(ep))}];")
                    out.append(f"  {_q(path)} -> {_q(bid)} [label={_q(ref)}];")
                    task = _dataflow_task(assembly, path, ep.binding)
                    if task is not None:  # binding.dataflow: calls become port writes / reads of that task
                        out.append(f"  {_q(bid)} -> {_q(task)} [style=dotted, label={_q('ports')}];")
        for service, models in node.service_bindings.items():
            for model in models:
                task = _dataflow_task(assembly, path, model)
                if task is not None:  # binding.dataflow on a service: the task's samples drive its operations
                    out.append(f"  {_q(task)} -> {_q(path)} [style=dotted, label={_q('samples -> ' + service)}];")
    for name, t in assembly.services.items():
        out.append(f"  {_q('service:' + name)} [shape=cds, label={_q(name)}];")
        out.append(f"  {_q('service:' + name)} -> {_q(t.node)} [style=dashed, label={_q('promotes ' + t.service)}];")
    out += _promotions(c, "")
    out += _dataflow_edges(assembly, remap)
    out.append("}")
    return "\n".join(out)


def _dataflow_task(assembly: Assembly, path: str, binding: Binding) -> str | None:
    """The task component a ``binding.dataflow`` of component ``path`` names, when it is in
    this composite (a sibling in the same nested composite first, then a top-level one)."""
    if binding.kind != "binding.dataflow" or binding.attributes.get("ns"):
        return None
    name = binding.attributes.get("component", "")
    prefix = path.rpartition("/")[0]
    for candidate in (f"{prefix}/{name}" if prefix else name, name):
        node = assembly.nodes.get(candidate)
        if node is not None and node.kind == TASK_KIND:
            return candidate
    return None


def _dataflow_edges(assembly: Assembly, remap: Remap) -> list[str]:
    """``scart:connect`` links and ``scart:bridge`` inputs as bold edges between tasks (a
    task of another deployer as an ellipse), labelled with the ports; names as they run."""
    out: list[str] = []
    remote: set[str] = set()
    bridges = {prefix + el.attributes.get("name", "") for prefix, el in assembly.elements_of("bridge")}

    def end(prefix: str, ref: str) -> tuple[str, str] | None:
        comp, dot, port = ref.strip().rpartition(".")
        if not dot or not comp or not port:
            return None
        path = prefix + comp
        task, shown_port = remap.endpoint(path, port)
        if path in assembly.nodes:
            return path, shown_port
        if path in bridges:
            return "bridge:" + path, shown_port
        node_id = "task:" + task
        if node_id not in remote:
            remote.add(node_id)
            out.append(f"  {_q(node_id)} [shape=ellipse, label={_q(task)}];")
        return node_id, shown_port

    for prefix, el in assembly.elements_of("bridge"):
        name = prefix + el.attributes.get("name", "")
        bid = "bridge:" + name
        outputs = [c.attributes.get("name", "") for c in el.children if c.kind == "output"]
        out.append(f"  {_q(bid)} [shape=hexagon, label={_q(remap.component(name) + ' (bridge)')}];")
        for child in el.children:
            source = end(prefix, child.attributes.get("from", "")) if child.kind == "input" else None
            if source is not None:
                label = f"{source[1]} -> {remap.port(name, child.attributes.get('name', ''))}"
                out.append(f"  {_q(source[0])} -> {_q(bid)} [style=bold, color=blue, label={_q(label)}];")
        for output in outputs:
            out.append(f"  {_q(bid)} [xlabel={_q(remap.port(name, output))}];")
    for prefix, el in assembly.elements_of("connect"):
        source, sink = end(prefix, el.attributes.get("from", "")), end(prefix, el.attributes.get("to", ""))
        if source is not None and sink is not None:
            policy = el.attributes.get("policy", "data")
            out.append(f"  {_q(source[0])} -> {_q(sink[0])} [style=bold, color=blue, "
                       f"label={_q(f'{source[1]} -> {sink[1]} [{policy}]')}];")
    return out


def _promotions(composite: Composite, prefix: str) -> list[str]:
    """Composite references (this level and nested levels): a node each, a dashed edge from
    each leaf component whose reference it promotes (through nested composites)."""
    out: list[str] = []
    for cr in composite.references:
        rid = "reference:" + prefix + cr.name
        out.append(f"  {_q(rid)} [shape=cds, label={_q(prefix + cr.name)}];")
        for uri in cr.promote:
            for leaf in _promoted_leaves(composite, prefix, uri, 0):
                out.append(f"  {_q(leaf)} -> {_q(rid)} [style=dashed, label={_q('promoted')}];")
    for comp in composite.components:
        impl = comp.implementation
        if impl is not None and impl.kind == "implementation.composite" and impl.composite is not None:
            if prefix.count("/") < 32:  # bounded (cycles are refused at load, this is a guard)
                out += _promotions(impl.composite, f"{prefix}{comp.name}/")
    return out


def _promoted_leaves(composite: Composite, prefix: str, uri: str, depth: int) -> list[str]:
    """Leaf component paths behind ``uri`` ("Comp/ref"), following nested promotions."""
    name, _, ref = uri.partition("/")
    comp = next((c for c in composite.components if c.name == name), None)
    if comp is None or depth > 32:
        return []
    impl = comp.implementation
    if impl is None or impl.kind != "implementation.composite" or impl.composite is None:
        return [prefix + name]
    inner = impl.composite
    return [leaf for cr in inner.references if cr.name == ref.split("/")[0]
            for u in cr.promote for leaf in _promoted_leaves(inner, f"{prefix}{name}/", u, depth + 1)]
