"""``scart run FILE``: run a composite until Ctrl-C or SIGTERM.

It fills a :class:`scart.Settings` from its options (every extension adds its own and
makes its own settings from them, through its :class:`~scart.spi.LaunchProvider`) and
runs the composite with it. Every component service is served on one ``binding.grpc``
endpoint (``--services``); then each launch provider may serve more beside the running
composite (:meth:`~scart.spi.LaunchProvider.launch`), for example register that endpoint
in a name service, so that ``scart services`` and ``scart call Component/Service.op``
find it by name.

What scart itself says goes to stderr, as ROS's logs do (the start summary, a line per
thing served: ``scart: WHAT at WHERE``, ``scart: SCA services at ...``; ``started``,
``stopping``, ``stopped``); stdout carries only what the components print (held back
until the whole start succeeded: no URL of a demo that then fails).

``scart run --dry-run`` loads and checks exactly as ``run`` does (the checks ``scart
validate`` makes) and starts nothing. Warnings (``path:line: warning: ...``) fail neither.

Exit codes: 0 success (after a clean stop on SIGINT/SIGTERM), 2 an invalid composite
(every problem listed on stderr as ``path:line: message [CODE]``, nothing started), 1 a
failure while starting or stopping. A second SIGINT/SIGTERM while stopping exits at once
with 128+signal (130/143) after a message on stderr. One-way calls still running
``--stop-timeout`` seconds into the stop are logged and left behind.

Starting is bounded too: a component whose start (``@init``, ``configure_hook``,
``start_hook``) has not returned ``--start-timeout`` seconds after the start began fails
the start with one line naming the component and the hook, and a SIGINT/SIGTERM during
the start is obeyed at once, saying where the start was; either way what started is
stopped (the hook that hangs is left behind) and ``run`` exits with 1. Every stop is
bounded: if it has not finished ``--stop-timeout`` + 30 s after it began, ``run`` says
so and exits with 1.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import signal
import sys
import threading
import time
from types import FrameType
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, cast

from scart.commands._composite import add_launch_options, assemble_or_say, endpoint_text, run_names, settings_of
from scart.errors import ScartError
from scart.assembled import Assembly
from scart.model import SCART_NS, Binding, Location
from scart.settings import Settings
from scart.spi import LaunchContext, Launched, ServiceEndpoint

if TYPE_CHECKING:
    from scart.runtime import Runtime

HELP = "run a composite until Ctrl-C or SIGTERM"
SERVICES_DEFAULT = "localhost:0"  # apart from any binding.grpc server of the composite (they share by address)
#: A signal's handler, as signal.signal takes and returns it.
SignalHandler = Callable[[int, FrameType | None], object] | int | signal.Handlers | None


class _Served(Protocol):
    """A started service binding of ``--services`` (binding.grpc's): where, under which names."""

    @property
    def address(self) -> str | None: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def endpoint(self) -> ServiceEndpoint: ...
    def stop(self) -> None: ...


START_TIMEOUT = 60.0  # s: the whole start (every @init and start_hook)
STOP_MARGIN = 30.0  # s past --stop-timeout after which a stop that has not finished is given up


def _seconds(text: str) -> float:
    """A positive, finite number of seconds (argparse type)."""
    value = float(text)
    if not 0 < value < 1e6:
        raise argparse.ArgumentTypeError(f"{text}: expected seconds, > 0")
    return value


def add_arguments(run: argparse.ArgumentParser) -> None:
    """The composite, the launch options (the extensions' among them), where to serve, and
    the server's security options."""
    from scart_wire.security import add_arguments as add_security

    run.add_argument("file", help="the .composite file (or a contribution folder with one deployable)")
    run.add_argument("--workers", type=int, default=8, help="size of the one-way worker pool (default 8)")
    run.add_argument("--stop-timeout", type=float, default=10.0, metavar="SECONDS",
                     help="on stop, how long one-way calls may still run before they are left behind "
                          "(logged by operation; default 10)")
    run.add_argument("--start-timeout", type=_seconds, default=START_TIMEOUT, metavar="SECONDS",
                     help="how long starting may take: then the start fails, naming the component and the hook "
                          f"(@init, start_hook...) still running (default {START_TIMEOUT:g})")
    run.add_argument("--services", default=SERVICES_DEFAULT, metavar="HOST:PORT",
                     help="serve every component service here (binding.grpc, the server's TLS and tokens), "
                          "registered with the name service for `scart services` and `scart call`; default "
                          f"{SERVICES_DEFAULT} (loopback, a free port); 'off' to serve none")
    run.add_argument("--dry-run", action="store_true",
                     help="load and check the composite exactly as run would (settings, --set, the extensions' "
                          "options), print what would run, and start nothing")
    add_launch_options(run, "run")
    add_security(run, server=True)


def main(args: argparse.Namespace) -> int:
    """Run until a signal; the exit code."""
    return cmd_run(args)


def say(text: str) -> None:
    """One of scart's own lines: stderr, flushed."""
    print(text, file=sys.stderr, flush=True)


def cmd_run(args: argparse.Namespace) -> int:
    """Install SIGINT/SIGTERM handlers, load, start (tasks and services served), say what
    runs, wait for a signal, stop."""
    from scart.runtime import Runtime

    stop = threading.Event()
    previous = _handle_signals(stop)
    try:
        settings = settings_of(args, "run")
        if settings is None:
            return 2
        assembly = assemble_or_say(args.file, args.overrides, settings, contributions=args.contributions)
        if assembly is None:
            return 2
        if getattr(args, "dry_run", False):
            say(summary(assembly, {}, run_names(assembly, settings)))
            say(f"scart: dry run: {len(assembly.nodes)} component(s) would start; nothing started")
            return 0
        runtime = Runtime(assembly, settings=settings, max_workers=args.workers, drain_timeout=args.stop_timeout)
        # What components print while starting (e.g. the youBot monitor's URL) is held back
        # and shown only once the whole start succeeded: no URL of a demo that then fails.
        announced = io.StringIO()
        failure = _start(runtime, announced, stop, args.start_timeout)
        if failure is not None:
            say(f"scart: {failure}")
            _stop_listening(runtime, limit=args.stop_timeout + STOP_MARGIN)
            return 1
        extras = _Extras(runtime, settings)
        try:
            problem = extras.start(args)
            if problem:
                say(f"scart: start failed: {problem}")
                return 1
            sys.stdout.write(announced.getvalue())
            sys.stdout.flush()
            _say_started(assembly, runtime, settings, extras)
            while not stop.wait(0.5):
                pass
            say("scart: stopping")
        finally:
            extras.stop()
            # the services endpoint first, then SCA components (their one-way calls drain while
            # the tasks they use still run; then the components, task components included,
            # are destroyed in reverse start order), the data-flow server last (a stop hook).
            _stop_listening(runtime, extras.services, limit=args.stop_timeout + STOP_MARGIN)
        say("scart: stopped")
        return 0
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _handle_signals(stop: threading.Event) -> dict[int, SignalHandler]:
    """SIGINT/SIGTERM set ``stop``; a second one while stopping exits at once. Returns the
    former handlers."""
    def on_signal(signum: int, frame: FrameType | None) -> None:
        if stop.is_set():  # a second Ctrl-C/SIGTERM while stopping: give up at once
            os.write(2, f"scart: {signal.Signals(signum).name} again while stopping; exiting at once "
                        "(components not destroyed)\n".encode())
            os._exit(128 + signum)
        stop.set()

    return {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}


class _Extras:
    """What ``scart run`` serves beside the runtime: the services endpoint, then what each
    launch provider serves (:meth:`scart.spi.LaunchProvider.launch`). :meth:`stop` undoes
    what :meth:`start` did, in reverse (the endpoint itself stops with the runtime, see
    :func:`_stop_listening`)."""

    def __init__(self, runtime: Runtime, settings: Settings) -> None:
        self.runtime, self.settings = runtime, settings
        self.services: list[_Served] = []
        self.launched: list[Launched] = []

    def start(self, args: argparse.Namespace) -> str:
        """Serve the services, then each provider's; what failed ("" when all started)."""
        try:
            self.services = _serve_services(self.runtime, args.services)
        except ScartError as exc:
            return f"--services {args.services}: {exc}"
        context = LaunchContext(self.settings, self.runtime.served(),
                                self.services[0].address if self.services else None)
        for provider in self.runtime.assembly.registry.launch_providers():
            try:
                launched = provider.launch(context)
                if launched is not None:
                    launched.start()  # a provider that raises has undone its own start
                    self.launched.append(launched)
            except Exception as exc:  # noqa: BLE001 - a bad option, a port taken: said, all stopped
                return str(exc) if isinstance(exc, ScartError) else f"{provider.name}: {type(exc).__name__}: {exc}"
        return ""

    def stop(self) -> None:
        """Stop what the providers serve, in reverse."""
        for launched in reversed(self.launched):
            launched.stop()
        self.launched = []


def _say_started(assembly: Assembly, runtime: Runtime, settings: Settings, extras: _Extras) -> None:
    """The start summary and a line per thing served (stderr)."""
    say(summary(assembly, runtime.addresses(), run_names(assembly, settings)))
    if extras.services:
        lister = next((x for x in extras.launched if x.services_option() is not None), None)
        say(_services_line(extras.services, lister))
    for launched in extras.launched:
        for what, where in launched.addresses().items():
            say(f"scart: {what} at {where}")
    for what, where in runtime.served().items():
        say(f"scart: {what} at {where}")
    for launched in extras.launched:
        for note in launched.notes():
            say(f"scart: {note}")
    say(f"scart: started {len(assembly.nodes)} component(s); Ctrl-C or SIGTERM to stop")


def _services_line(services: list[_Served], lister: Launched | None) -> str:
    """Where the services are, and a call to paste (a promoted service's first operation if
    any): by name when a launch provider lists them (``lister``: its options find them, its
    names name them), else with ``--at``."""
    where = services[0].address
    first = max(services, key=lambda b: len(b.names) > 2)  # one the composite promotes, when there is one
    name = first.names[-1] if len(first.names) > 2 else first.names[0]
    ops = list(first.endpoint.interface.operations)
    how = lister.services_option() if lister is not None else None
    target = f"{lister.service_name(name) if lister is not None else name}.{ops[0] if ops else 'op'}"
    if how is not None:
        return (f"scart: SCA services at {where} (list them: scart services{how}; "
                f"call one: scart call{how} {target} ARGS...)")
    return (f"scart: SCA services at {where} (list them: scart services --at {where}; "
            f"call one: scart call --at {where} {target} ARGS...)")


def _serve_services(runtime: Runtime, address: str) -> list[_Served]:
    """Every component service of ``runtime`` on one ``binding.grpc`` server at ``address``
    (through the extension registry, as a composite's binding would be): started service
    bindings, [] with ``off``. Raises ``ScartError`` when it cannot listen."""
    if address == "off":
        return []
    provider = runtime.assembly.registry.binding("binding.grpc")
    if provider is None:
        return []
    started: list[_Served] = []
    try:
        for path, node in runtime.assembly.nodes.items():
            for service in node.ctype.services:
                model = Binding(kind="binding.grpc", namespace=SCART_NS, attributes={"address": address},
                                name="services", loc=Location(path="<scart run --services>", line=0))
                binding = provider.service(model, runtime.endpoint(f"{path}/{service}"), runtime)
                binding.start()
                started.append(cast("_Served", binding))  # binding.grpc's: it names its services too
    except BaseException:
        for served in reversed(started):
            served.stop()
        raise
    return started


def _start(runtime: Runtime, announced: io.StringIO, stop: threading.Event, timeout: float) -> str | None:
    """Start ``runtime`` on a thread of its own while this (main) thread waits in short
    slices (it must stay free to run the signal handlers) for the start to end, for
    ``stop`` (a signal) or for ``timeout`` s. What components print meanwhile goes to
    ``announced``. None when started; else what went wrong, in one line naming the
    component and what its start was doing when it did not return."""
    outcome: list[BaseException] = []

    def run() -> None:
        try:
            runtime.start()
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread
            outcome.append(exc)

    starter = threading.Thread(target=run, name="scart-start", daemon=True)  # a hung hook is left behind
    deadline = time.monotonic() + timeout
    with contextlib.redirect_stdout(announced):
        starter.start()
        while starter.is_alive() and not stop.is_set() and time.monotonic() < deadline:
            starter.join(0.1)
    if not starter.is_alive():
        if not outcome:
            return None
        exc = outcome[0]
        return f"start failed: {exc}" if isinstance(exc, ScartError) else f"start failed: {type(exc).__name__}: {exc}"
    where = runtime.starting()
    doing = f"component {where[0]} ({where[1]})" if where is not None else "the runtime"
    if stop.is_set():
        return f"stopping while starting: {doing} had not returned"
    return f"start failed: {doing} did not return within {timeout:g} s (--start-timeout); stopping"


def _stop_listening(runtime: Runtime, services: list[_Served] | None = None, limit: float | None = None) -> None:
    """Stop the ``services`` endpoint, then ``runtime``, on a thread of their own while this
    (main) thread waits in short slices. Python runs signal handlers only on the main
    thread, and the kernel may deliver a signal to any thread: a main thread blocked in one
    long wait (a drain deadline of minutes) would not run the second Ctrl-C's handler until
    that wait ended. A stop not done within ``limit`` s is given up: said, and the process
    exits with 1 (what hangs cannot be ended otherwise)."""
    def stop() -> None:
        try:
            for binding in reversed(services or []):
                binding.stop()
        finally:
            runtime.stop()

    stopper = threading.Thread(target=stop, name="scart-stop", daemon=True)
    stopper.start()
    deadline = None if limit is None else time.monotonic() + limit
    while stopper.is_alive():
        if deadline is not None and time.monotonic() > deadline:
            os.write(2, f"scart: the stop has not finished within {limit:g} s; exiting (what hangs is left "
                        "behind)\n".encode())
            os._exit(1)
        stopper.join(0.2)


def summary(assembly: Assembly, addresses: dict[str, str | None], names: dict[str, str] | None = None) -> str:
    """A short text of what runs: components (and the name one runs under when an extension
    renames it: ``names``), their wires, promoted services, bound addresses."""
    c = assembly.composite
    lines = [f"scart: composite {c.name} ({assembly.contribution.display(c.loc.path)})"]
    for path, node in assembly.nodes.items():
        impl = node.model.implementation
        what = (impl.attributes.get("class") or "") if impl else ""
        runs_as = (names or {}).get(path, path)
        renamed = f" (runs as {runs_as})" if runs_as != path else ""
        lines.append(f"  component {path}{renamed} [{node.kind} {what}] services: {', '.join(node.ctype.services) or '-'}")
        for ref, eps in node.references.items():
            targets = ", ".join(endpoint_text(e) for e in eps) or "(unwired)"
            lines.append(f"    {ref} -> {targets}")
    for name, t in assembly.services.items():
        lines.append(f"  service {name} -> {t.node}/{t.service}")
    for name, addr in addresses.items():
        lines.append(f"  binding {name} at {addr}")
    return "\n".join(lines)
