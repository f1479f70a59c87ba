"""The verbs ``scart run``, ``scart validate`` and ``scart graph`` (the ``sca`` group).

``scart run`` fills a :class:`scart.Settings` (``--ns``, else ``SCART_NS``; ``serve=True``)
and runs the composite with it. When the composite has ``implementation.task``
components, the data-flow extension then serves them over gRPC once every component has
started, so ``scart ls``/``describe``/``echo`` see them: with the name service embedded
at ``--ns HOST:PORT`` (else ``SCART_NS``, else the default 127.0.0.1:7850), or — when a
name service already answers there — registered with that one. The start summary then
has a line per thing served (``scart: dataflow server at HOST:PORT (N task(s))``,
``scart: name service at HOST:PORT (embedded|joined)``). ``binding.dataflow`` and
``scart:connect`` resolve tasks of other processes through that same name service.

Loading is offline: ``scart validate`` never touches the network unless ``--online``,
which lets the extensions' checks ask the name service (``--ns``) about remote tasks.
``scart validate`` makes every check ``scart run`` makes before it starts anything (and
each one it would only meet at start that needs no running peer, such as a task
property's bounds), with the same ``path:line: message [CODE]``; ``scart run --dry-run``
loads exactly as ``run`` does and starts nothing. Warnings (``path:line: warning: ...``)
do not fail either.

Exit codes: 0 success (``run``: after a clean stop on SIGINT/SIGTERM), 2 an invalid
composite (every problem listed on stderr as ``path:line: message [CODE]``, nothing
started), 1 a failure while starting or stopping. A second SIGINT/SIGTERM while ``run``
stops exits at once with 128+signal (130/143) after a message on stderr. One-way calls
still running ``--stop-timeout`` seconds into the stop are logged and left behind.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import signal
import sys
import threading
from types import FrameType
from typing import TYPE_CHECKING, Any

from dataflow import DataflowError
from dataflow.cli import _ros as ros_args
from dataflow.remote.defaults import DEFAULT_NS_ADDRESS, NS_ENV
from dataflow.remote.security import add_arguments, from_args
from scart.assembly import assemble
from scart.errors import Problem, ScartError, ScdlError
from scart.graph import Assembly, Bound, Target
from scart.model import SCART_NS, Binding, Composite, Location
from scart.settings import Remap, Settings

if TYPE_CHECKING:
    from scart.runtime import Runtime

TASK_KIND = "implementation.task"  # the data-flow extension's kind (the core does not import it)
SERVICES_DEFAULT = "localhost:0"  # apart from any binding.grpc server of the composite (they share by address)


def register(subparsers: argparse._SubParsersAction) -> None:  # noqa: SLF001
    """Add ``run``, ``validate`` and ``graph``."""
    run = subparsers.add_parser("run", help="run a composite until Ctrl-C or SIGTERM")
    run.add_argument("file", help="the .composite file (or a contribution folder with one deployable)")
    _add_set(run)
    run.add_argument("--workers", type=int, default=8, help="size of the one-way worker pool (default 8)")
    run.add_argument("--stop-timeout", type=float, default=10.0, metavar="SECONDS",
                     help="on stop, how long one-way calls may still run before they are left behind "
                          "(logged by operation; default 10)")
    run.add_argument("--ns", default=None, metavar="HOST:PORT",
                     help="name service of data-flow tasks: where the embedded one listens, or the running one "
                          f"to join (default: ${NS_ENV}, else {DEFAULT_NS_ADDRESS})")
    run.add_argument("--services", default=SERVICES_DEFAULT, metavar="HOST:PORT",
                     help="serve every component service here (binding.grpc, the server's TLS and tokens) for "
                          f"`scart services --at` and `scart call --at`; default {SERVICES_DEFAULT} (loopback, a free "
                          "port); 'off' to serve none")
    run.add_argument("--foxglove", default=None, metavar="[HOST:]PORT",
                     help="also serve the data-flow tasks live to the Foxglove app here (as `scart foxglove`: "
                          "ports, properties, operations; 0: a free port; a routable HOST needs --insecure)")
    run.add_argument("--dry-run", action="store_true",
                     help="load and check the composite exactly as run would (settings, --set, --remap), print "
                          "what would run, and start nothing")
    add_arguments(run, server=True)
    ros_args.add_arguments(run)
    run.set_defaults(func=cmd_run)

    validate = subparsers.add_parser("validate", help="check composites without running them (offline)")
    validate.add_argument("files", nargs="+", help=".composite files (or contribution folders)")
    _add_set(validate)
    validate.add_argument("--online", action="store_true",
                          help="also check remote data-flow tasks against the running name service")
    validate.add_argument("--ns", default=None, metavar="HOST:PORT",
                          help=f"name service for --online (default: ${NS_ENV}, else {DEFAULT_NS_ADDRESS})")
    add_arguments(validate, server=False)
    validate.set_defaults(func=cmd_validate)

    graph = subparsers.add_parser("graph", help="print a composite as Graphviz DOT")
    graph.add_argument("file", help="the .composite file")
    _add_set(graph)
    graph.set_defaults(func=cmd_graph)


def _add_set(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="COMPONENT.PROP=VALUE",
                        help="override a component property (repeatable)")
    parser.add_argument("--remap", action="append", default=[], metavar="FROM=TO",
                        help="rename a data-flow task or port at launch (FROM:=TO too; TASK.PORT=NAME for one "
                             "task's port; __ns=NAMESPACE puts every task under NAMESPACE/); repeatable")
    parser.add_argument("--contribution", dest="contributions", action="append", default=[], metavar="DIR",
                        help="another contribution folder the composite is resolved in: its exported "
                             "namespaces and its Python modules (repeatable)")


def parse_overrides(items: list[str]) -> dict[str, str]:
    """``["Comp.prop=value", ...]`` to a dict; raises ``ValueError`` naming a malformed item."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or "." not in key:
            raise ValueError(f"--set {item!r}: expected COMPONENT.PROPERTY=VALUE")
        out[key.strip()] = value
    return out


def settings_of(args: argparse.Namespace, **fields: object) -> Settings | None:
    """The settings of a verb: ``--ns`` (else ``SCART_NS``) and ``fields``; None (after
    printing why) when a value is invalid."""
    ns = getattr(args, "ns", None)
    try:
        try:
            fields["security"] = from_args(args)
            fields["remap"] = Remap.parse(getattr(args, "remap", None) or [])
        except (DataflowError, ValueError) as exc:
            raise ScartError(str(exc)) from None
        if ns:
            try:
                return Settings.from_env(ns=ns, **fields)
            except ScartError as exc:
                raise ScartError(f"--ns {ns!r}: {str(exc).partition(': ')[2]}") from None
        return Settings.from_env(**fields)
    except ScartError as exc:
        print(f"scart: {exc}", file=sys.stderr)
        return None


def _assemble(file: str, raw_overrides: list[str], settings: Settings, unused: set[str] | None = None,
              contributions: list[str] | None = None) -> Assembly | None:
    """Assemble ``file`` or print its problems. With ``unused`` (a set), overrides naming no
    property of this file are no problem: their keys are added to ``unused`` instead."""
    try:
        result = assemble(file, parse_overrides(raw_overrides), strict_overrides=unused is None, settings=settings,
                          contributions=contributions or [])
        if unused is not None:
            unused |= result.unused_overrides
        _print_warnings(result.warnings)
        return result
    except ScdlError as exc:
        if unused is not None:
            unused |= exc.unused_overrides
        print(str(exc), file=sys.stderr)
        _print_warnings(exc.warnings)
        print(f"scart: {file}: {len(exc.errors)} problem(s); nothing started", file=sys.stderr)
    except ValueError as exc:
        if unused is not None:
            unused.add("")  # malformed --set: fails every file
        print(f"scart: {exc}", file=sys.stderr)
    return None


def _print_warnings(warnings: list[Problem]) -> None:
    """Each warning as ``path:line: warning: message [CODE]`` on stderr."""
    for warning in warnings:
        print(warning, file=sys.stderr)


def cmd_run(args: argparse.Namespace) -> int:
    """Install SIGINT/SIGTERM handlers, load, start (tasks served), print a summary, wait, stop."""
    from scart.runtime import Runtime

    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        if stop.is_set():  # a second Ctrl-C/SIGTERM while stopping: give up at once
            os.write(2, f"scart: {signal.Signals(signum).name} again while stopping; exiting at once "
                        "(components not destroyed)\n".encode())
            os._exit(128 + signum)
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        settings = settings_of(args, serve=True)
        if settings is None:
            return 2
        assembly = _assemble(args.file, args.overrides, settings, contributions=args.contributions)
        if assembly is None:
            return 2
        if getattr(args, "dry_run", False):
            print(summary(assembly, {}, settings.remap), flush=True)
            print(f"scart: dry run: {len(assembly.nodes)} component(s) would start; nothing started", flush=True)
            return 0
        try:
            ros_args.apply(args)
        except (DataflowError, ValueError) as exc:
            print(f"scart: start failed: {exc}", file=sys.stderr)
            return 1
        runtime = Runtime(assembly, settings=settings, max_workers=args.workers, drain_timeout=args.stop_timeout)
        # What components print while starting (e.g. the youBot monitor's URL) is held back
        # and shown only once the whole start succeeded: no URL of a demo that then fails.
        announced = io.StringIO()
        try:
            with contextlib.redirect_stdout(announced):
                runtime.start()
        except ScartError as exc:
            _stop_listening(runtime)
            print(f"scart: start failed: {exc}", file=sys.stderr)
            return 1
        services: list[Any] = []
        foxglove: Any = None
        try:
            try:
                services = _serve_services(runtime, args.services)
            except ScartError as exc:
                print(f"scart: start failed: --services {args.services}: {exc}", file=sys.stderr)
                return 1
            if args.foxglove is not None:
                try:
                    foxglove = _serve_foxglove(runtime, args.foxglove, settings)
                except Exception as exc:  # noqa: BLE001 - bad address, port taken, no tasks: said, all stopped
                    print(f"scart: start failed: --foxglove {args.foxglove}: {exc}", file=sys.stderr)
                    return 1
            sys.stdout.write(announced.getvalue())
            print(summary(assembly, runtime.addresses(), settings.remap), flush=True)
            if services:
                print(_services_line(services), flush=True)
            if foxglove is not None:
                print(f"scart: Foxglove at {foxglove.url} ({foxglove.channels} channel(s))", flush=True)
            for what, where in runtime.served().items():
                print(f"scart: {what} at {where}", flush=True)
            print(f"scart: started {len(assembly.nodes)} component(s); Ctrl-C or SIGTERM to stop", flush=True)
            while not stop.wait(0.5):
                pass
            print("scart: stopping", flush=True)
        finally:
            if foxglove is not None:
                foxglove.stop()
            # the services endpoint first, then SCA components (their one-way calls drain while
            # the tasks they use still run; then the components, task components included,
            # are destroyed in reverse start order), the data-flow server last (a stop hook).
            _stop_listening(runtime, services)
        print("scart: stopped", flush=True)
        return 0
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _services_line(services: list[Any]) -> str:
    """Where the services are, and a call to paste (a promoted service's first operation if any)."""
    where = services[0].address
    first = max(services, key=lambda b: len(b.names) > 2)  # one the composite promotes, when there is one
    name = first.names[-1] if len(first.names) > 2 else first.names[0]
    ops = list(first.endpoint.interface.operations)
    example = f"scart call --at {where} {name}.{ops[0]} ARGS..." if ops else f"scart call --at {where} NAME.op ARGS..."
    return f"scart: SCA services at {where} (list them: scart services --at {where}; call one: {example})"


def _serve_services(runtime: Runtime, address: str) -> list[Any]:
    """Every component service of ``runtime`` on one ``binding.grpc`` server at ``address``
    (through the extension registry, as a composite's binding would be): started service
    bindings, [] with ``off``. Raises ``ScartError`` when it cannot listen."""
    if address == "off":
        return []
    provider = runtime.assembly.registry.binding("binding.grpc")
    if provider is None:
        return []
    started: list[Any] = []
    try:
        for path, node in runtime.assembly.nodes.items():
            for service in node.ctype.services:
                model = Binding(kind="binding.grpc", namespace=SCART_NS, attributes={"address": address},
                                name="services", loc=Location(path="<scart run --services>", line=0))
                binding = provider.service(model, runtime.endpoint(f"{path}/{service}"), runtime)
                binding.start()
                started.append(binding)
    except BaseException:
        for binding in reversed(started):
            binding.stop()
        raise
    return started


def _serve_foxglove(runtime: Runtime, spec: str, settings: Settings) -> Any:
    """A started Foxglove server at ``[HOST:]PORT`` showing the tasks of the name service
    ``runtime`` serves or joined (``scart foxglove``'s, on this process's credentials).
    Raises when the composite serves no tasks or the server cannot start."""
    host, _, port = spec.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    if not port.isdigit() or int(port) > 65535:
        raise ValueError("expected [HOST:]PORT with PORT in 0..65535")
    where = runtime.served().get("name service")
    if where is None:
        raise ScartError("this composite serves no data-flow tasks to show")
    from dataflow.cli.foxglove import FoxgloveLive
    from dataflow.remote import connect

    system = connect(where.split()[0], security=settings.security)
    try:
        live = FoxgloveLive(system, host, int(port), insecure_host=settings.security.insecure, owns_system=True)
    except BaseException:
        system.close()
        raise
    live.start()  # its stop (also when start raises) closes the client
    return live


def _stop_listening(runtime: Runtime, services: list[Any] | None = None) -> None:
    """Stop the ``services`` endpoint, then ``runtime``, on a thread of their own while this
    (main) thread waits in short slices. Python runs signal handlers only on the main
    thread, and the kernel may deliver a signal to any thread: a main thread blocked in one
    long wait (a drain deadline of minutes) would not run the second Ctrl-C's handler until
    that wait ended."""
    def stop() -> None:
        try:
            for binding in reversed(services or []):
                binding.stop()
        finally:
            runtime.stop()

    stopper = threading.Thread(target=stop, name="scart-stop", daemon=True)
    stopper.start()
    while stopper.is_alive():
        stopper.join(0.2)


def summary(assembly: Assembly, addresses: dict[str, str | None], remap: Remap | None = None) -> str:
    """A short text of what runs: components, their wires, promoted services, bound addresses."""
    c = assembly.composite
    lines = [f"scart: composite {c.name} ({assembly.contribution.display(c.loc.path)})"]
    for path, node in assembly.nodes.items():
        impl = node.model.implementation
        what = (impl.attributes.get("class") or "") if impl else ""
        runs_as = remap.component(path) if remap and node.kind == TASK_KIND else path
        renamed = f" (runs as {runs_as})" if runs_as != path else ""
        lines.append(f"  component {path}{renamed} [{node.kind} {what}] services: {', '.join(node.ctype.services) or '-'}")
        for ref, eps in node.references.items():
            targets = ", ".join(_endpoint_text(e) for e in eps) or "(unwired)"
            lines.append(f"    {ref} -> {targets}")
    for name, t in assembly.services.items():
        lines.append(f"  service {name} -> {t.node}/{t.service}")
    for name, addr in addresses.items():
        lines.append(f"  binding {name} at {addr}")
    return "\n".join(lines)


def _endpoint_text(ep: Target | Bound) -> str:
    if isinstance(ep, Target):
        return f"{ep.node}/{ep.service}"
    return f"<{ep.binding.kind} {' '.join(f'{k}={v}' for k, v in ep.binding.attributes.items())}>"


def cmd_validate(args: argparse.Namespace) -> int:
    """Check each file; print "ok" lines or every problem; 0 if all valid, else 2."""
    settings = settings_of(args, online=args.online)
    if settings is None:
        return 2
    failed = 0
    several = len(args.files) > 1
    unused_in: list[set[str]] = []
    for file in args.files:
        unused: set[str] | None = set() if several else None
        assembly = _assemble(file, args.overrides, settings, unused, args.contributions)
        if unused is not None:
            unused_in.append(unused)
        if assembly is None:
            failed += 1
        else:
            warned = f", {len(assembly.warnings)} warning(s)" if assembly.warnings else ""
            print(f"{file}: ok ({len(assembly.nodes)} component(s){warned})")
    if several and args.overrides:  # an override must fit at least one of the files
        try:
            keys = parse_overrides(args.overrides)
        except ValueError:
            keys = {}
        for key in sorted(k for k in keys if all(k in u for u in unused_in)):
            print(f"<command line>:0: --set {key}: no such component property in any of the files "
                  f"[SCART-C005]", file=sys.stderr)
            failed += 1
    return 2 if failed else 0


def cmd_graph(args: argparse.Namespace) -> int:
    """Print the composite as Graphviz DOT; 2 (problems on stderr) if invalid."""
    settings = settings_of(args)
    if settings is None:
        return 2
    assembly = _assemble(args.file, args.overrides, settings, contributions=args.contributions)
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
                    out.append(f"  {_q(bid)} [shape=note, label={_q(_endpoint_text(ep))}];")
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
