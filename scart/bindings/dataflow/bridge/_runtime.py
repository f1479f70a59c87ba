"""The bridges at run time: the participant that makes the bridges of one runtime,
connects them, joins them to their topics, starts and stops them (the task each runs as
is :mod:`._task`)."""

from __future__ import annotations

import logging
import threading

from dataflow import ConnPolicy, DataflowError
from scart.errors import ScartError
from scart.bindings.dataflow._host import Watcher, host_of
from scart.bindings.dataflow.connect import ConnectParticipant, Link, connect_present
from scart.bindings.dataflow.task import retire
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import Host, Participant

from ._resolve import UNKNOWN as _UNKNOWN
from ._resolve import Resolved, Resolver
from ._spec import ELEMENT, BridgeSpec, TopicSpec, bridges_of
from ._task import BridgeTask

__all__ = ["BridgeParticipant", "RETRY_S"]

log = logging.getLogger("scart.dataflow")

def _fail(resolver: Resolver, spec: BridgeSpec) -> ScartError:
    why = "; ".join(p[1] for p in resolver.problems if p[3] == "error") or "it cannot be resolved"
    return ScartError(f"bridge {spec.name} ({spec.where}): {why}")


class BridgeParticipant(Participant):
    """Creates, connects, starts and stops the bridges of one runtime. A bridge whose
    source of another deployer is not in the name service yet waits for it, as
    ``scart:connect`` does: a watcher resolves it again every :data:`RETRY_S` s and starts
    it once every source is known (one of the wrong type is then logged, not retried)."""

    def __init__(self, host: Host) -> None:
        self.host = host
        self.tasks: list[BridgeTask] = []
        self._connectors: list[ConnectParticipant] = []
        self._pending: list[BridgeSpec] = []
        self._streams: list[str] = []  # the bridges' own ports joined to topics
        self._waiting: Watcher | None = None
        self._lock = threading.Lock()  # the watcher adds bridges while stop may run

    def start(self) -> None:
        """Resolve each bridge (remote sources through the name service now), add its task,
        connect its inputs and start it; one waiting for a remote source starts when it
        appears. Raises ``ScartError`` naming the bridge."""
        dataflow_host = host_of(self.host)
        specs = bridges_of(self.host.assembly.elements_of(ELEMENT))
        resolver = Resolver(self.host.assembly, self.host.settings, self.host.assembly.import_object, specs)
        remote: list[Link] = []
        for spec in specs.values():
            resolved = resolver.resolve(spec, online=True)
            if resolved is None:
                raise _fail(resolver, spec)
            if self._unknown(resolved):
                self._pending.append(spec)
                continue
            remote += self._add(resolved)
        dataflow_host.start()  # served (settings.serve) even when the bridges are the only data-flow parts
        dataflow_host.refresh()
        self._connect_remote(remote)
        if self._pending:
            self._waiting = Watcher("scart-bridge-wait", self._retry, interval=RETRY_S)
            self._waiting.start()

    def _unknown(self, resolved: Resolved) -> list[str]:
        """The inputs of a resolved bridge whose source type is not known yet (logged once)."""
        unknown = [n for n in resolved.sources if resolved.sources[n] is _UNKNOWN]
        if unknown and resolved.spec not in self._pending:
            sources = ", ".join(".".join(i.source) for i in resolved.spec.inputs if i.name in unknown)
            log.warning("bridge %s (%s): waiting for %s in the name service %s", resolved.spec.name,
                        resolved.spec.where, sources, host_of(self.host).ns_address)
        return unknown

    def _add(self, resolved: Resolved) -> list[Link]:
        """Add, configure, connect (in-process inputs) and start one bridge's task; its
        inputs from other deployers, to connect. Raises ``ScartError`` naming the bridge."""
        spec, remap = resolved.spec, DataflowSettings.of(self.host.settings).remap
        deployer = host_of(self.host).deployer
        task = BridgeTask(resolved, remap)
        deployer.add(task)
        with self._lock:
            self.tasks.append(task)
        if not task.configure():
            raise ScartError(f"bridge {spec.name}: configure refused (state {task.state.name})")
        names = set(deployer.names())
        remote: list[Link] = []
        for inp in spec.inputs:
            sink = (task.name, task._inputs[inp.name].port.name)
            if inp.topic is not None:
                self._stream(".".join(sink), inp.topic, inp.policy)
                continue
            source = remap.endpoint(*inp.source)
            if source[0] in names:
                deployer.connect(".".join(source), ".".join(sink), inp.policy)
            else:
                remote.append(Link(source, sink, inp.policy, inp.ns, inp.where))
        if spec.output_topic is not None:
            self._stream(f"{task.name}.{task.output.name}", spec.output_topic, ConnPolicy.data())
        connect_present(self.host, task.name)
        if not task.start():
            raise ScartError(f"bridge {spec.name}: start refused (state {task.state.name})")
        return remote

    def _stream(self, port: str, topic: TopicSpec, policy: ConnPolicy) -> None:
        """Join the bridge's ``port`` to ``topic`` (undone at stop). Raises ``ScartError``."""
        deployer = host_of(self.host).deployer
        try:
            made = deployer.stream(port, policy.with_(transport=topic.transport, topic=topic.topic),
                                   dict(topic.options))
        except (DataflowError, ValueError) as exc:
            raise ScartError(f"bridge stream {port} ({topic.loc}): {exc}") from exc
        with self._lock:
            self._streams.append(made.name)
        log.info("bridge stream %s: %s -> %s", made.name, made.source, made.sink)

    def _connect_remote(self, links: list[Link]) -> None:
        """Connect inputs from other deployers in the background (whenever their source appears)."""
        if not links:
            return
        with self._lock:
            local = {t.name for t in self.tasks}
            connector = ConnectParticipant(links, self.host, local=lambda name: name in local)
            self._connectors.append(connector)
        connector.start()

    def _retry(self) -> None:
        """Watcher step: resolve the waiting bridges again; start those now known."""
        specs = bridges_of(self.host.assembly.elements_of(ELEMENT))
        for spec in list(self._pending):
            resolver = Resolver(self.host.assembly, self.host.settings, self.host.assembly.import_object, specs)
            resolved = resolver.resolve(spec, online=True)
            if resolved is None:  # the source appeared, and does not fit: say so once, stop waiting
                log.error("%s", _fail(resolver, spec))
                self._pending.remove(spec)
                continue
            if self._unknown(resolved):
                continue
            self._pending.remove(spec)
            try:
                links = self._add(resolved)
            except (ScartError, DataflowError) as exc:  # the run goes on without this bridge
                log.error("bridge %s (%s): not started: %s", spec.name, spec.where, exc)
                continue
            host_of(self.host).refresh()
            self._connect_remote(links)
            log.info("bridge %s: its sources appeared: started", spec.name)

    def addresses(self) -> dict[str, str]:
        """What the runtime's data-flow host serves (the same as its tasks' participant says)."""
        return host_of(self.host).addresses()

    def stop(self) -> None:
        """Stop waiting, the connectors and every bridge task (idempotent)."""
        if self._waiting is not None:
            self._waiting.stop()
        with self._lock:
            connectors, self._connectors = list(self._connectors), []
            tasks = list(self.tasks)
            streams, self._streams = list(self._streams), []
        for connector in connectors:
            connector.stop()
        deployer = host_of(self.host).deployer
        for name in reversed(streams):
            deployer.unstream(name)
        for task in reversed(tasks):
            try:
                retire(task)
            except DataflowError as exc:
                log.warning("bridge %s: stopping: %s", task.name, exc)


#: How often (s) a bridge waiting for a source of another deployer looks for it again.
RETRY_S = 0.5

