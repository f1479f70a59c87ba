"""The SCA side of the bridge scenario, written both ways.

* :class:`ThermostatProxy` — the paper's way (JOrocos): a component that uses the
  ``dataflow.remote`` client library by hand: connects to the name service in ``@init``,
  writes the ``setpoint`` port, subscribes to ``temperature``, closes in ``@destroy``.
* :class:`Supervisor` — the binding way: the same behaviour with no data-flow code at all;
  ``binding.dataflow`` turns ``self.thermostat.setpoint(v)`` into a port write and every
  ``temperature`` sample into a call of :meth:`Supervisor.temperature`.

Both offer the :class:`Controller` service, so a test drives them identically.
"""

from __future__ import annotations

import threading
from typing import Protocol

import scart
from dataflow import ConnPolicy
from dataflow.remote import SampleEvent, connect
from scart.bindings.dataflow.settings import DataflowSettings


@scart.interface
class Controller(Protocol):
    def set_target(self, value: float) -> None: ...
    def temperatures(self) -> list[float]: ...
    def latest(self) -> float | None: ...


@scart.interface
class ThermostatPorts(Protocol):
    """The thermostat's ports as an SCA interface (for binding.dataflow)."""

    def setpoint(self, value: float) -> None: ...
    def temperature(self) -> float | None: ...


@scart.interface
class TemperatureSink(Protocol):
    """Called with each temperature sample (binding.dataflow service)."""

    def temperature(self, value: float) -> None: ...


class _Record:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.samples: list[float] = []

    def add(self, value: float) -> None:
        with self._lock:
            self.samples.append(value)

    def all(self) -> list[float]:
        with self._lock:
            return list(self.samples)


@scart.component(services=[Controller])
class ThermostatProxy:
    """The paper's way: a hand-written proxy over the data-flow client library."""

    ns: str = scart.prop(default="")
    task: str = scart.prop(default="thermostat")
    ctx: scart.ComponentContext = scart.context()

    @scart.init
    def open(self) -> None:
        self._record = _Record()
        # the property, else the runtime's name service (scart run --ns, SCART_NS, the default)
        ns = self.ns.strip() or DataflowSettings.of(self.ctx.settings).ns_address
        self._system = connect(ns, security=self.ctx.settings.security)
        proxy = self._system.component(self.task)
        self._proxy = proxy
        self._writer = proxy.connect_input("setpoint", ConnPolicy.data())
        self._sub = proxy.subscribe("temperature", self._on_sample, policy=ConnPolicy.buffer(64))

    def _on_sample(self, event: SampleEvent) -> None:
        self._record.add(float(event.value))  # type: ignore[arg-type]

    @scart.destroy
    def close(self) -> None:
        self._system.close()

    def set_target(self, value: float) -> None:
        self._writer.write(value)

    def temperatures(self) -> list[float]:
        return self._record.all()

    def latest(self) -> float | None:
        _, value = self._proxy.read("temperature")
        return None if value is None else float(value)  # type: ignore[arg-type]


@scart.component(services=[Controller, TemperatureSink])
class Supervisor:
    """The binding way: plain SCA code; the ports arrive through binding.dataflow."""

    thermostat: ThermostatPorts = scart.reference()

    @scart.init
    def open(self) -> None:
        self._record = _Record()

    def set_target(self, value: float) -> None:
        self.thermostat.setpoint(value)

    def temperature(self, value: float) -> None:
        self._record.add(value)

    def temperatures(self) -> list[float]:
        return self._record.all()

    def latest(self) -> float | None:
        return self.thermostat.temperature()
