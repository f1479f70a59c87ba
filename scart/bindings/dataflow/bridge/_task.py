"""The data-flow task a bridge runs as (:class:`BridgeTask`): its input ports, its output,
and what it does each cycle by its trigger."""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

from dataflow import FlowStatus, InputPort, OutputPort, PeriodicActivity, TaskContext
from dataflow.introspection import PropertyDescription, TaskDescription
from scart.bindings.dataflow.settings import Remap

from ._resolve import Resolved

__all__ = ["BridgeTask"]

log = logging.getLogger("scart.dataflow")

@dataclass
class _Input:
    port: InputPort[object]
    value: object = None  # the last sample accepted, converted
    has_value: bool = False
    fresh: bool = False  # a sample not yet used by an output
    arrived: float | None = None  # monotonic time of the last sample
    samples: int = 0


class BridgeTask(TaskContext):
    """The data-flow task a bridge runs as (see the module docstring)."""

    def __init__(self, resolved: Resolved, remap: Remap | None = None) -> None:
        spec = resolved.spec
        remap = remap or Remap()
        super().__init__(remap.component(spec.name))
        self.resolved = resolved
        event = spec.trigger in ("any", "all")
        self._inputs: dict[str, _Input] = {}
        for inp in spec.inputs:
            tp = resolved.sources[inp.name]
            origin = inp.origin if inp.topic is not None else ".".join(remap.endpoint(*inp.source))
            port: InputPort[object] = InputPort(tp if tp is not None else object, remap.port(spec.name, inp.name),
                                                f"from {origin}", event=event)
            self._inputs[inp.name] = _Input(self.add_port(port))
        self.output: OutputPort[object] = self.add_port(
            OutputPort(resolved.output_type, remap.port(spec.name, spec.output), f"built by bridge {self.name}"))
        self.outputs = 0
        self.errors = 0  # samples a converter or the builder refused (logged, then skipped)
        self._lock = threading.Lock()
        if spec.trigger == "periodic" and spec.period is not None:
            self.set_activity(PeriodicActivity(spec.period))

    def update_hook(self) -> None:
        now = time.monotonic()
        with self._lock:
            for name, state in self._inputs.items():
                status, value = state.port.read_newest()
                if status is not FlowStatus.NEW_DATA:
                    continue
                state.samples += 1
                convert = self.resolved.converters[name]
                try:  # converted once, on arrival: a refused sample is counted once and not held
                    value = convert(value) if convert is not None else value
                except Exception as exc:  # noqa: BLE001 - a converter refusing a sample
                    self._refused(f"converting input {name}", exc)
                    continue
                state.value, state.has_value, state.fresh, state.arrived = value, True, True, now
            values = self._sync() if self.resolved.spec.trigger == "all" else self._gather()
            if values is None:
                return
            for state in self._inputs.values():
                state.fresh = False
            try:
                self.output.write(self.resolved.build(**values))
            except Exception as exc:  # noqa: BLE001 - a builder refusing (or building the wrong type)
                self._refused(f"building {self.resolved.spec.output}", exc)
                return
            self.outputs += 1

    def _refused(self, what: str, exc: Exception) -> None:
        """Count a refused sample; log the first and every 1000th (one bad input must not flood)."""
        self.errors += 1
        if self.errors == 1 or self.errors % 1000 == 0:
            log.warning("bridge %s: %s failed (%d so far): %s: %s", self.name, what, self.errors,
                        type(exc).__name__, exc)

    def _gather(self) -> dict[str, object] | None:
        """Periodic and any-input triggers: each input's value by its missing-input rule."""
        if not any(s.fresh for s in self._inputs.values()) and self.resolved.spec.trigger == "any":
            return None
        values: dict[str, object] = {}
        for inp in self.resolved.spec.inputs:
            state = self._inputs[inp.name]
            if inp.missing == "default" and not state.has_value:
                values[inp.name] = self.resolved.defaults.get(inp.name)
            elif (inp.missing == "skip" and not state.fresh) or not state.has_value:
                return None
            else:
                values[inp.name] = state.value
        return values

    def _sync(self) -> dict[str, object] | None:
        """All inputs fresh within the window (an older sample waits for a newer one)."""
        states = self._inputs.values()
        if not all(s.fresh for s in states):
            return None
        arrivals = [s.arrived or 0.0 for s in states]
        if max(arrivals) - min(arrivals) > self.resolved.spec.window:
            newest = max(arrivals)
            for s in states:  # too old for the newest: wait for its next sample
                if newest - (s.arrived or 0.0) > self.resolved.spec.window:
                    s.fresh = False
            return None
        return {name: s.value for name, s in self._inputs.items()}

    def ages(self) -> dict[str, float | None]:
        """Seconds since each input's last sample (None before the first)."""
        now = time.monotonic()
        return {n: (None if s.arrived is None else now - s.arrived) for n, s in self._inputs.items()}

    def describe(self) -> TaskDescription:
        """The task, with each input's age and sample count and the outputs written."""
        d = super().describe()
        extra = []
        for name, age in self.ages().items():
            extra.append(PropertyDescription(name=f"{name}.age", type_name="float64",
                                             value=None if age is None else round(age, 6),
                                             doc=f"seconds since input {name} got a sample (read-only)"))
            extra.append(PropertyDescription(name=f"{name}.samples", type_name="int64",
                                             value=self._inputs[name].samples,
                                             doc=f"samples input {name} got (read-only)"))
        extra.append(PropertyDescription(name="outputs", type_name="int64", value=self.outputs,
                                         doc=f"samples written to {self.resolved.spec.output} (read-only)"))
        extra.append(PropertyDescription(name="errors", type_name="int64", value=self.errors,
                                         doc="samples a converter or the builder refused (read-only)"))
        return d.model_copy(update={"properties": [*d.properties, *extra]})


