"""The runtime: turns a checked :class:`~scart.assembly.Assembly` into running components.

Lifecycle (one table; anything else raises ``RuntimeStateError``)::

    state     start()                                  stop()
    CREATED   -> STARTED (instances, @init, bindings)   -> STOPPED (nothing ran)
    STARTED   error                                    -> STOPPED (bindings, pool, @destroy)
    STOPPED   error                                    no-op (idempotent)

``start()``: creates the bounded one-way pool, starts reference bindings, creates
composite-scoped instances and runs their ``@init`` targets first (dependency order),
starts the participants of the extensions the composite uses (``Extension.activate``,
see :mod:`scart.spi`), then service bindings. A failing ``@init`` raises ``ScartError``
(the cause chained) after stopping what started.

``stop()``: stops service bindings, then extension participants (reverse), closes the
one-way pool and drains it with a deadline (``drain_timeout``, default 10 s, counted from
the start of the stop): queued and in-flight one-way calls may finish until then; after
it, queued calls are dropped (logged and counted) and calls still running are logged by
operation and left behind on their daemon worker threads. Then ``@destroy`` runs in
reverse init order under the same deadline (at least ``MIN_DESTROY_S``; those left
when it is up start together and share one more ``MIN_DESTROY_S``): one that hangs is
logged and left behind (also when ``stop()`` is called from a one-way worker:
the *other* workers are drained first, the caller's own call is still running),
reference bindings stop, and every proxy handed out (by ``service()`` or injected as a
reference) is switched to raising ``RuntimeStateError``.

One-way calls queue on a bounded pool: at most ``max_pending`` (default 10 000) waiting
calls; beyond that the caller gets a ``ScartError`` at once (backpressure), counted in
``oneway_rejected``.

Thread-safety: ``service()`` and the proxies are thread-safe; ``start``/``stop`` change
the state under a lock, which ``start`` does not hold while components start: ``stop()``
from another thread ends a start that hangs (see :meth:`Runtime.start`). ``stop()`` may be
called from a component (even a one-way worker).
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import os
import logging
import queue
import threading
import time
import weakref
from collections.abc import Callable, Sequence
from typing import Any, NoReturn, TypeVar

from pydantic import BaseModel

from scart.api import ComponentContext, InterfaceInfo, interface_info
from scart.assembly import assemble
from scart.errors import InvocationError, RuntimeStateError, ScartError, ServiceNotFoundError
from scart.extensions import ExtensionRegistry
from scart.assembled import Assembly
from scart.graph import DEFAULT, Bound, Node, Target
from scart.local import LocalReferenceBinding, wrap_operation
from scart.pool import WORKER_PREFIX, Args, Job, Kwargs, OnewayPool
from scart.model import Binding
from scart.settings import Settings
from scart.spi import (
    ComponentManager, Extension, Invocation, Invoker, Participant, ReferenceBinding, ServiceBinding,
)

log = logging.getLogger("scart.runtime")
T = TypeVar("T")
MIN_DESTROY_S = 0.5  #: every @destroy gets at least this long, even past the stop deadline


class RuntimeState(enum.Enum):
    """See the lifecycle table in the module docstring."""

    CREATED = "created"
    STARTED = "started"
    STOPPED = "stopped"


class ServiceProxy:
    """A proxy with one attribute per operation (plain callables built at wiring time).

    At the runtime's ``stop()`` every operation is swapped for a stub raising
    ``RuntimeStateError`` (:meth:`_scart_disable`), so calls cost nothing extra before."""

    def __init__(self, name: str, invokers: dict[str, Invoker]) -> None:
        self.__dict__.update(invokers)
        self.__dict__["_scart_name"] = name
        self.__dict__["_scart_ops"] = tuple(invokers)

    def _scart_disable(self, why: str) -> None:
        name = self.__dict__["_scart_name"]
        for op in self.__dict__["_scart_ops"]:
            self.__dict__[op] = _stopped_stub(f"{name}.{op}: {why}")

    def __repr__(self) -> str:
        return f"<scart proxy {self.__dict__['_scart_name']}>"


def _stopped_stub(message: str) -> Callable[..., NoReturn]:
    def stopped(*args: object, **kwargs: object) -> NoReturn:
        raise RuntimeStateError(message)
    return stopped


class _Endpoint:
    """A component service inside this runtime (the ``ServiceEndpoint`` of the SPI)."""

    def __init__(self, runtime: Runtime, node: Node, service: str, manager: ComponentManager) -> None:
        self.component = node.path
        self.service = service
        self.interface: InterfaceInfo = node.ctype.services[service]
        self._runtime = runtime
        self._manager = manager

    def by_value(self) -> _Endpoint:
        """A view of this endpoint with pass-by-value (remotable) semantics."""
        view = copy.copy(self)
        view.interface = dataclasses.replace(self.interface, remotable=True)
        return view

    def method(self, operation: str) -> Invoker:
        """The raw callable of ``operation`` (scope handled by the component's manager)."""
        if operation not in self.interface.operations:
            raise KeyError(operation)
        return self._manager.method(operation)

    def operation(self, name: str, callback: object | None) -> Invoker:
        """The full per-operation callable (see :func:`scart.local.wrap_operation`)."""
        op = self.interface.operations.get(name)
        if op is None:
            raise InvocationError(f"{self.component}/{self.service} has no operation {name!r}")
        return wrap_operation(self._manager.method(name), op, callback=callback,
                              by_value=self.interface.remotable,
                              submit=self._runtime.submitter(f"{self.component}/{self.service}.{name}"))

    def invoke(self, invocation: Invocation) -> Any:
        """Perform ``invocation`` (one-way: queued, returns None at once)."""
        return self.operation(invocation.operation, invocation.callback)(*invocation.args, **invocation.kwargs)


class Runtime:
    """Runs one assembled composite. Use ``with Runtime.from_file(path) as rt:``.

    The runtime is the :class:`scart.spi.Host` of its extensions: ``settings``,
    ``assembly``, ``submit``, ``endpoint``, ``shared``, ``add_stop_hook``."""

    def __init__(self, assembly: Assembly, *, settings: Settings | None = None, max_workers: int = 8,
                 max_pending: int = 10_000, drain_timeout: float = 10.0) -> None:
        self.assembly = assembly
        self._settings = settings if settings is not None else assembly.registry.settings_from_env()
        self.max_workers = max_workers
        self.max_pending = max_pending
        self.drain_timeout = drain_timeout
        self.state = RuntimeState.CREATED
        self.oneway_failures = 0
        self.oneway_rejected = 0
        self._failures_lock = threading.Lock()
        self._lock = threading.RLock()
        self._pool: OnewayPool | None = None
        self._all_proxies: weakref.WeakSet[ServiceProxy] = weakref.WeakSet()
        self._managers: dict[str, ComponentManager] = {}
        self._endpoints: dict[tuple[str, str], _Endpoint] = {}
        self._ref_bindings: dict[tuple[str, str], list[ReferenceBinding]] = {}
        self._service_bindings: list[ServiceBinding] = []
        self._started: list[str] = []
        self._participants: list[Participant] = []
        self._shared_lock = threading.RLock()
        self._stopped = threading.Event()
        self._shared: dict[str, Any] = {}
        self._stop_hooks: list[Callable[[], None]] = []
        self._stopping_thread: threading.Thread | None = None
        self._proxies: dict[str, ServiceProxy] = {}
        self._starting: str | None = None  # the component whose start runs now

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], *, overrides: dict[str, str] | None = None,
                  settings: Settings | None = None, extensions: ExtensionRegistry | None = None,
                  contributions: Sequence[str | os.PathLike[str]] = (),
                  max_workers: int = 8, max_pending: int = 10_000, drain_timeout: float = 10.0) -> Runtime:
        """Load and check the composite at ``path`` (raises ``ScdlError``); nothing starts yet.

        ``path`` is a ``.composite`` file, or a contribution folder whose
        ``META-INF/sca-contribution.xml`` lists one deployable composite; ``contributions``
        are more contribution folders it is resolved in (see :mod:`scart.contribution`).
        ``overrides`` maps "Component.property" to a raw value (like ``--set``);
        ``settings`` configure the runtime and its extensions (default: from the
        environment, :meth:`ExtensionRegistry.settings_from_env`); ``extensions`` is the
        registry of kinds (default: the installed entry points). Warnings of the composite
        (``assembly.warnings``) are logged."""
        extensions = extensions if extensions is not None else ExtensionRegistry()
        settings = settings if settings is not None else extensions.settings_from_env()
        assembly = assemble(str(path), overrides, extensions=extensions, settings=settings,
                            contributions=contributions)
        for warning in assembly.warnings:
            log.warning("%s", warning)
        return cls(assembly, settings=settings, max_workers=max_workers, max_pending=max_pending,
                   drain_timeout=drain_timeout)

    @property
    def settings(self) -> Settings:
        """The settings this runtime and its extensions run with."""
        return self._settings

    def __enter__(self) -> Runtime:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # --- lifecycle --------------------------------------------------------------------

    def start(self) -> None:
        """Start everything (see the module docstring). Raises ``RuntimeStateError`` unless
        CREATED. The lock is not held while components start, so another thread may
        ``stop()`` a start that hangs (an ``@init`` or ``start_hook`` that never returns):
        what started is stopped, and this start raises ``RuntimeStateError`` if its
        component ever returns."""
        with self._lock:
            if self.state is not RuntimeState.CREATED:
                raise RuntimeStateError(f"cannot start a runtime in state {self.state.value}")
            self.state = RuntimeState.STARTED
            self._pool = OnewayPool(self.max_workers, self.max_pending, self._run_oneway)
        try:
            self._create_managers()
            self._create_reference_bindings()
            for path in self.assembly.order:
                self._next_step(path)
                try:
                    self._managers[path].start()
                except Exception as exc:
                    raise ScartError(f"starting component {path} failed: {type(exc).__name__}: {exc}") from exc
                with self._lock:
                    late = self.state is RuntimeState.STOPPED
                if late:  # its start returned after a stop that left it behind: destroyed now
                    _quietly(self._managers[path].stop, f"destroying {path}")
            self._next_step(None)
            self._start_participants()
            self._start_service_bindings()
        except BaseException:
            self.stop()
            raise
        finally:
            self._starting = None

    def _next_step(self, path: str | None) -> None:
        """Go on starting (``path``: that component next), unless stopped meanwhile."""
        with self._lock:
            if self.state is not RuntimeState.STARTED:
                raise RuntimeStateError("the runtime was stopped while it started")
            if path is not None:
                self._started.append(path)
            self._starting = path

    def starting(self) -> tuple[str, str] | None:
        """While ``start()`` runs: the component starting now and what it is doing (its
        manager's ``stage``, e.g. ``"@init open"``, ``"start_hook"``); None otherwise."""
        path = self._starting
        manager = self._managers.get(path) if path is not None else None
        return (path, manager.stage) if path is not None and manager is not None else None

    def stop(self) -> None:
        """Stop everything, in reverse; idempotent; errors in @destroy are logged, not raised.

        Blocks until stopped, except when called from a one-way worker or by the thread
        already stopping (then it returns at once instead of deadlocking). The lock is
        held only for the state transition, so a worker calling ``stop()`` while another
        thread drains the pool never deadlocks."""
        in_worker = threading.current_thread().name.startswith(WORKER_PREFIX)
        with self._lock:
            first = self.state is not RuntimeState.STOPPED
            self.state = RuntimeState.STOPPED
        if not first:
            if not in_worker and threading.current_thread() is not self._stopping_thread:
                limit = self.drain_timeout + 30.0
                if not self._stopped.wait(limit):
                    log.warning("stop(): the stop begun by thread %s has not finished within %.0f s; returning",
                                getattr(self._stopping_thread, "name", "?"), limit)
            return
        self._stopping_thread = threading.current_thread()
        deadline = time.monotonic() + self.drain_timeout
        hung = self._starting  # a component whose start has not returned: nothing of it to destroy yet
        if hung is not None:
            log.warning("stop: component %s had not returned from its start; not waited for (destroyed if it ever "
                        "returns)", hung)
        try:
            for binding in reversed(self._service_bindings):
                _quietly(binding.stop, "stopping a service binding")
            for participant in reversed(self._participants):
                _quietly(participant.stop, "stopping an extension participant")
            if self._pool is not None:
                self._drain_pool(self._pool, deadline)
            self._destroy_all([p for p in reversed(self._started) if p != hung], deadline)
            for bindings in self._ref_bindings.values():
                for rb in bindings:
                    _quietly(rb.stop, "stopping a reference binding")
            for hook in reversed(self._stop_hooks):
                _quietly(hook, "running a stop hook")
        finally:
            self._disable_proxies()
            self._stopped.set()

    def _destroy_all(self, paths: list[str], deadline: float) -> None:
        """Stop components (their ``@destroy``) in the order given, each on a thread of its
        own, one after the other until ``deadline`` (or :data:`MIN_DESTROY_S` from now if
        that is later). Once that time is up, the rest start together and get one more
        :data:`MIN_DESTROY_S` between them: one that hangs is logged and left behind (a
        daemon thread), so a stop never outlasts its timeout by more than twice that."""
        until = max(deadline, time.monotonic() + MIN_DESTROY_S)
        late: list[tuple[str, threading.Event]] = []
        for path in paths:
            if late or time.monotonic() >= until:
                late.append((path, self._start_destroy(path)))
            elif not self._start_destroy(path).wait(until - time.monotonic()):
                log.warning("stop: destroying %s did not finish within the stop timeout (%.1f s); left behind",
                            path, self.drain_timeout)
        end = time.monotonic() + MIN_DESTROY_S
        for path, done in late:
            if not done.wait(max(0.0, end - time.monotonic())):
                log.warning("stop: destroying %s did not finish within the stop timeout (%.1f s); left behind",
                            path, self.drain_timeout)

    def _start_destroy(self, path: str) -> threading.Event:
        """Run one component's stop (its ``@destroy``) on a daemon thread; the event is set when it is done."""
        manager = self._managers[path]
        done = threading.Event()

        def run() -> None:
            try:
                _quietly(manager.stop, f"destroying {path}")
            finally:
                done.set()

        threading.Thread(target=run, name=f"scart-destroy-{path}", daemon=True).start()
        return done

    def _drain_pool(self, pool: OnewayPool, deadline: float) -> None:
        dropped, stuck = pool.close(deadline)
        if dropped:
            with self._failures_lock:
                self.oneway_failures += dropped
            log.warning("stop: %d queued one-way call(s) dropped after %.1f s", dropped, self.drain_timeout)
        if stuck:
            log.warning("stop: %d one-way call(s) still running after %.1f s, left behind on daemon threads: %s",
                        len(stuck), self.drain_timeout, ", ".join(stuck))

    def _disable_proxies(self) -> None:
        why = "runtime is stopped"
        for proxy in list(self._all_proxies):
            proxy._scart_disable(why)
        for proxy in list(self._proxies.values()):
            proxy._scart_disable(why)

    def _create_managers(self) -> None:
        registry = self.assembly.registry
        for path, node in self.assembly.nodes.items():
            provider = registry.implementation(node.kind)
            if provider is None:
                raise ScartError(f"{node.model.loc}: {path}: no implementation kind <{node.kind}> in this runtime")
            manager = _guarded(f"{provider.name} for component {path}", provider.manager, node, self)
            self._managers[path] = manager
            for service in node.ctype.services:
                self._endpoints[(path, service)] = _Endpoint(self, node, service, manager)

    def _create_reference_bindings(self) -> None:
        for path, node in self.assembly.nodes.items():
            for ref, endpoints in node.references.items():
                iface = _iface_of(node, ref)
                made: list[ReferenceBinding] = []
                for ep in endpoints:
                    if isinstance(ep, Target):
                        target = self._endpoints[(ep.node, ep.service)]
                        if iface is not None and iface.remotable and not target.interface.remotable:
                            target = target.by_value()  # the reference's interface says remotable
                        made.append(LocalReferenceBinding(None, target.interface, self, target=target))
                    else:
                        made.append(self._binding_reference(ep, iface, f"{path}/{ref}"))
                self._ref_bindings[(path, ref)] = made
        for bindings in self._ref_bindings.values():
            for rb in bindings:
                _guarded(f"starting a {rb.model.kind if rb.model else 'binding.sca'} reference", rb.start)

    def _binding_reference(self, ep: Bound, iface: InterfaceInfo | None, where: str) -> ReferenceBinding:
        provider = self.assembly.registry.binding(ep.binding.kind)
        if provider is None or "reference" not in provider.sides:
            raise ScartError(f"{ep.binding.loc}: {where}: binding <{ep.binding.kind}> cannot be used on a reference")
        return _guarded(f"{ep.binding.loc}: {where}: {provider.name}", provider.reference, ep.binding,
                        iface or InterfaceInfo("?", {}), self)

    def _service_binding_models(self) -> list[tuple[tuple[str, str], Binding]]:
        todo = [((p, s), b) for p, n in self.assembly.nodes.items() for s, bs in n.service_bindings.items() for b in bs]
        todo += [((t.node, t.service), b) for name, t in self.assembly.services.items()
                 for b in self.assembly.service_bindings.get(name, [])]
        return todo

    def _used_extensions(self) -> list[Extension]:
        """The providers this composite uses, each once, in a stable order."""
        registry = self.assembly.registry
        names = [n.kind for n in self.assembly.nodes.values()]
        names += [ep.binding.kind for n in self.assembly.nodes.values() for eps in n.references.values()
                  for ep in eps if isinstance(ep, Bound)]
        names += [model.kind for _, model in self._service_binding_models()]
        names += [el.kind for _, el in self.assembly.elements]
        return [p for p in map(registry.get, dict.fromkeys(names)) if p is not None]

    def _start_participants(self) -> None:
        for provider in self._used_extensions():
            participant = _guarded(f"starting {provider.name} failed", provider.activate, self)
            if participant is None or any(p is participant for p in self._participants):
                continue
            self._participants.append(participant)
            _guarded(f"starting {provider.name} failed", participant.start)

    def _start_service_bindings(self) -> None:
        for key, model in self._service_binding_models():
            provider = self.assembly.registry.binding(model.kind)
            if provider is None or "service" not in provider.sides:
                raise ScartError(f"{model.loc}: binding <{model.kind}> cannot be used on a service")
            where = f"{model.loc}: {key[0]}/{key[1]}: {provider.name}"
            binding = _guarded(where, provider.service, model, self._endpoints[key], self)
            _guarded(where, binding.start)
            self._service_bindings.append(binding)

    # --- what bindings and managers use ------------------------------------------------

    def shared(self, key: str, factory: Callable[[], T]) -> T:
        """A per-runtime resource for extensions (e.g. the data-flow ``Deployer``), created
        by ``factory`` on first use, once; thread-safe (``factory`` may call ``shared``)."""
        with self._shared_lock:  # re-entrant: a factory may use another shared resource
            if key not in self._shared:
                self._shared[key] = factory()
            return self._shared[key]

    def add_stop_hook(self, hook: Callable[[], None]) -> None:
        """Run ``hook`` at the very end of ``stop()`` (after every @destroy and binding stop),
        hooks in reverse order of registration; errors are logged."""
        self._stop_hooks.append(hook)

    def submit(self, fn: Job, *args: object, **kwargs: object) -> None:
        """Queue ``fn`` on the one-way pool (bounded worker count); failures are logged and
        counted in ``oneway_failures``. After stop, the call is counted and dropped with a log.
        With ``max_pending`` calls already waiting, raises ``ScartError`` (counted in
        ``oneway_rejected``)."""
        self._submit(getattr(fn, "__qualname__", None) or repr(fn), fn, args, kwargs)

    def submitter(self, label: str) -> Callable[..., None]:
        """A ``submit`` whose calls are named ``label`` in logs (e.g. "Comp/Service.op")."""
        def submit(fn: Job, *args: object, **kwargs: object) -> None:
            self._submit(label, fn, args, kwargs)
        return submit

    def _submit(self, label: str, fn: Job, args: Args, kwargs: Kwargs) -> None:
        pool = self._pool
        try:
            if pool is None:
                raise RuntimeError("runtime not started")
            pool.submit(label, fn, args, kwargs)
        except RuntimeError as exc:
            self._count_failure()
            log.error("one-way call %s dropped: %s", label, exc)
        except queue.Full:
            with self._failures_lock:
                self.oneway_rejected += 1
            raise ScartError(f"one-way call {label} refused: {self.max_pending} one-way calls already "
                             "pending (backpressure); retry later") from None

    def _run_oneway(self, label: str, fn: Job, args: Args, kwargs: Kwargs) -> None:
        try:
            fn(*args, **kwargs)
        except Exception:
            self._count_failure()
            log.exception("one-way call %s failed", label)

    def _count_failure(self) -> None:
        with self._failures_lock:
            self.oneway_failures += 1

    def endpoint(self, name: str) -> _Endpoint:
        """The endpoint of service ``name`` (same forms as :meth:`service`)."""
        target = self._resolve(name)
        return self._endpoints[(target.node, target.service)]

    def configure(self, node: Node, instance: object) -> None:
        """Inject properties, references and context into ``instance`` (before its @init)."""
        ctype = node.ctype
        for name, value in node.properties.items():
            if value is DEFAULT:
                value = ctype.properties[name][0].default_value()
            elif isinstance(value, (list, dict, set, BaseModel)):
                value = copy.deepcopy(value)
            setattr(instance, name, value)
        for ref, (spec, _) in ctype.references.items():
            proxies = [self._reference_proxy(instance, node, ref, rb) for rb in self._ref_bindings.get((node.path, ref), [])]
            setattr(instance, ref, proxies if spec.multiple else (proxies[0] if proxies else None))
        for name in ctype.contexts:
            setattr(instance, name, ComponentContext(node.path, self.service, self._settings))

    def _reference_proxy(self, instance: object, node: Node, ref: str, rb: ReferenceBinding) -> ServiceProxy:
        iface = rb.interface
        callback = _LocalCallback(instance, iface.callback, self) if iface.callback is not None else None
        invokers = {name: rb.invoker(op, callback) for name, op in iface.operations.items()}
        proxy = ServiceProxy(f"{node.path}.{ref}", invokers)
        if self.state is RuntimeState.STOPPED:
            proxy._scart_disable("runtime is stopped")
        else:
            self._all_proxies.add(proxy)
        return proxy

    # --- lookup -----------------------------------------------------------------------

    def service(self, name: str) -> ServiceProxy:
        """A proxy to a service: ``"Component"`` (one service), ``"Component/Service"``, a nested
        ``"Outer/Inner/Service"``, or a service the top-level composite promotes.

        Calls go through the runtime (stateless: fresh instance per call; one-way: None at
        once). Raises ``ServiceNotFoundError`` listing the known services, or
        ``RuntimeStateError`` when not started."""
        if self.state is not RuntimeState.STARTED:
            raise RuntimeStateError(f"service({name!r}): runtime is {self.state.value}, not started")
        proxy = self._proxies.get(name)
        if proxy is not None:
            return proxy
        ep = self.endpoint(name)
        invokers = {op: ep.operation(op, None) for op in ep.interface.operations}
        proxy = self._proxies[name] = ServiceProxy(name, invokers)
        return proxy

    def _resolve(self, name: str) -> Target:
        a = self.assembly
        if name in a.services:
            return a.services[name]
        if name in a.aliases:
            return a.aliases[name]
        path, _, service = name.rpartition("/")
        node = a.nodes.get(path)
        if node is not None and service in node.ctype.services:
            return Target(path, service)
        node = a.nodes.get(name)
        if node is not None and len(node.ctype.services) == 1:
            return Target(name, next(iter(node.ctype.services)))
        raise ServiceNotFoundError(f"no service {name!r}; known: {', '.join(self.service_names())}")

    def service_names(self) -> list[str]:
        """Every name :meth:`service` accepts in the "Component/Service" form, plus promoted names."""
        names = list(self.assembly.services)
        names += [f"{p}/{s}" for p, n in self.assembly.nodes.items() for s in n.ctype.services]
        return names

    def addresses(self) -> dict[str, str | None]:
        """Started service bindings: "Component/Service (kind)" -> real address."""
        return {f"{b.endpoint.component}/{b.endpoint.service} ({b.model.kind})": b.address for b in self._service_bindings}

    def served(self) -> dict[str, str]:
        """What the extensions' participants serve, once started: ``{"what": "where"}``
        (for example ``{"dataflow server": "127.0.0.1:40101 (1 task(s))"}``)."""
        out: dict[str, str] = {}
        for participant in self._participants:
            out.update(participant.addresses())
        return out


class _LocalCallback:
    """The callback target of a calling instance: one attribute per callback operation."""

    def __init__(self, instance: object, iface: InterfaceInfo, runtime: Runtime) -> None:
        for name, op in iface.operations.items():
            method = getattr(instance, name, None) or _missing(type(instance).__name__, name)
            setattr(self, name, wrap_operation(method, op, callback=None, by_value=iface.remotable,
                                               submit=runtime.submitter(f"callback {iface.name}.{name}")))


def _missing(cls: str, op: str) -> Callable[..., NoReturn]:
    def fail(*args: object, **kwargs: object) -> NoReturn:
        raise InvocationError(f"callback {op!r}: the calling component {cls} has no method {op!r}")
    return fail


def _iface_of(node: Node, ref: str) -> InterfaceInfo | None:
    if ref in node.ref_interfaces:
        return node.ref_interfaces[ref]
    ref_type = node.ctype.references[ref][1]
    return interface_info(ref_type) if ref_type is not None else None


def _guarded(what: str, fn: Callable[..., T], *args: object) -> T:
    """``fn(*args)``; an extension's failure other than a ``ScartError`` becomes one that
    says ``what`` failed (the cause chained), so callers see one error tree."""
    try:
        return fn(*args)
    except ScartError:
        raise
    except Exception as exc:
        raise ScartError(f"{what}: {type(exc).__name__}: {exc}") from exc


def _quietly(fn: Callable[[], None], what: str) -> None:
    try:
        fn()
    except Exception:
        log.exception("error while %s", what)


__all__ = ["Runtime", "RuntimeState", "ServiceProxy"]
