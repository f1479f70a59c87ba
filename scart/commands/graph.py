"""``scart graph FILE``: a composite as Graphviz DOT on stdout (components, wires,
promotions, bindings, and what each extension adds through its
:class:`~scart.spi.LaunchProvider`: names components run under, edges of its own).
Drawing it needs Graphviz's ``dot`` (``apt-get install graphviz``): ``scart graph
X.composite | dot -Tsvg > x.svg``."""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Mapping

from scart.commands._composite import add_launch_options, assemble_or_say, endpoint_text, run_names, settings_of
from scart.assembled import Assembly
from scart.graph import Target
from scart.model import Composite
from scart.settings import Settings
from scart.spi import GraphEdge, GraphNode

HELP = "print a composite as Graphviz DOT (draw it with Graphviz: | dot -Tsvg > x.svg)"
DESCRIPTION = ("Print a composite as Graphviz DOT. Drawing it needs Graphviz's dot (apt-get install graphviz): "
               "scart graph X.composite | dot -Tsvg > x.svg")


def add_arguments(graph: argparse.ArgumentParser) -> None:
    """The file and the launch options."""
    graph.add_argument("file", help="the .composite file")
    add_launch_options(graph, "graph")


def main(args: argparse.Namespace) -> int:
    """Print the DOT text; 2 when the composite is invalid."""
    return cmd_graph(args)


def cmd_graph(args: argparse.Namespace) -> int:
    """Print the composite as Graphviz DOT; 2 (problems on stderr) if invalid."""
    settings = settings_of(args, "graph")
    if settings is None:
        return 2
    assembly = assemble_or_say(args.file, args.overrides, settings, contributions=args.contributions)
    if assembly is None:
        return 2
    print(to_dot(assembly, settings))
    return 0


def _clusters(assembly: Assembly, prefix: str, depth: int, names: Mapping[str, str]) -> list[str]:
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
        shown = names.get(path, rest)  # the name an extension runs it under
        label = f"{shown}\\n[{', '.join(node.ctype.services)}]"
        lines.append(f'{pad}{_q(path)} [label="{label}"];')
    for sub in subs:
        lines.append(f"{pad}subgraph {_q('cluster_' + sub.rstrip('/'))} {{")
        lines.append(f"{pad}  label={_q(sub.rstrip('/') + ' (implementation.composite)')};")
        lines += _clusters(assembly, sub, depth + 1, names)
        lines.append(f"{pad}}}")
    return lines


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_dot(assembly: Assembly, settings: Settings | None = None) -> str:
    """The assembly as DOT: a box per component (label lists its services, or the name an
    extension runs it under), an edge per wire labelled with the reference, dashed edges
    for promoted services and references, a note-shaped node per binding endpoint, then
    what each extension adds (the data-flow links, as bold edges)."""
    settings = settings if settings is not None else Settings()
    c = assembly.composite
    out = [f"digraph {_q(c.name)} {{", "  rankdir=LR;", "  node [shape=box, fontname=Helvetica];"]
    out += _clusters(assembly, "", 1, run_names(assembly, settings))
    for path, node in assembly.nodes.items():
        for ref, eps in node.references.items():
            for ep in eps:
                if isinstance(ep, Target):
                    out.append(f"  {_q(path)} -> {_q(ep.node)} [label={_q(f'{ref} -> {ep.service}')}];")
                else:
                    bid = f"{path}.{ref}:{ep.binding.kind}"
                    out.append(f"  {_q(bid)} [shape=note, label={_q(endpoint_text(ep))}];")
                    out.append(f"  {_q(path)} -> {_q(bid)} [label={_q(ref)}];")
    for name, t in assembly.services.items():
        out.append(f"  {_q('service:' + name)} [shape=cds, label={_q(name)}];")
        out.append(f"  {_q('service:' + name)} -> {_q(t.node)} [style=dashed, label={_q('promotes ' + t.service)}];")
    out += _promotions(c, "")
    for provider in assembly.registry.launch_providers():
        out += _items(provider.graph(assembly, settings))
    out.append("}")
    return "\n".join(out)


def _items(items: Iterable[GraphNode | GraphEdge]) -> list[str]:
    """An extension's nodes and edges as DOT lines (attributes given, in a fixed order)."""
    out = []
    for item in items:
        if isinstance(item, GraphNode):
            attrs = [("shape", item.shape), ("label", item.label), ("xlabel", item.xlabel)]
            head = _q(item.id)
        else:
            attrs = [("style", item.style), ("color", item.color), ("label", item.label)]
            head = f"{_q(item.source)} -> {_q(item.target)}"
        given = ", ".join(f"{k}={_q(v) if k.endswith('label') else v}" for k, v in attrs if v)
        out.append(f"  {head} [{given}];" if given else f"  {head};")
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
