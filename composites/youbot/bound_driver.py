"""``BoundYouBotDriver``: the youBot proxy without data-flow client code (``binding.dataflow``).

The same services as :class:`sca_driver.SCAYouBotDriver` (``RetrievingStatus``,
``SendingCommands``, ``SettingPeriod``; callback ``Notifying``), but the component never
connects, subscribes or writes by itself — the composite binds it to the driver task:

* reference ``ports: DriverPorts`` with ``<scart:binding.dataflow component="youBotDriver"/>``:
  ``self.ports.commands(values)`` *is* a write of the task's ``commands`` input port;
* service ``StatusFeed`` with the same binding: every ``jointStatus`` sample is a call of
  :meth:`BoundYouBotDriver.jointStatus` (on the binding's subscription thread);
* reference ``operations: DriverOperations`` wired to the task component's own service
  (its ``@operation`` s): ``set_period`` answers at once whether the driver accepted.

What the component cannot see without the client library (the task's lifecycle state) is
inferred from the samples: ``RUNNING`` while they arrive, ``connected`` while the newest
is younger than ``stale_after`` s. See ``youbot-binding.composite``.
"""

from __future__ import annotations

import itertools
import time
from typing import Any, Protocol

import scart
from interfaces import RetrievingStatus, SendingCommands, SettingPeriod
from proxy_core import DriverProxyCore
from youbot_model import MAX_PERIOD, MIN_PERIOD, YouBotStatus

__all__ = ["BoundYouBotDriver", "DriverPorts", "DriverOperations", "StatusFeed"]


@scart.interface
class DriverPorts(Protocol):
    """The driver task's input ports as an SCA interface (for ``binding.dataflow``)."""

    def commands(self, values: list[float]) -> None:
        """Write the ``commands`` port."""
        ...

    def period(self, seconds: float) -> None:
        """Write the ``period`` port."""
        ...


@scart.interface
class DriverOperations(Protocol):
    """The part of the driver task's ``@operation`` s this proxy uses."""

    def set_period(self, seconds: float) -> bool:
        """Request a new period; True if the driver accepted it."""
        ...


@scart.interface
class StatusFeed(Protocol):
    """Called with each ``jointStatus`` sample (``binding.dataflow`` service)."""

    def jointStatus(self, sample: YouBotStatus) -> None:  # noqa: N802 - named after the port
        """One new sample."""
        ...


@scart.component(services=[RetrievingStatus, SendingCommands, SettingPeriod, StatusFeed])
class BoundYouBotDriver(DriverProxyCore):
    """See the module docstring."""

    stale_after: float = scart.prop(default=1.0)
    ports: DriverPorts = scart.reference()
    operations: DriverOperations = scart.reference(required=False)

    @scart.init
    def open(self) -> None:
        """Nothing to connect: the bindings do it."""
        self._core_open()
        self._period: float | None = None

    @scart.destroy
    def close(self) -> None:
        """Stop the notifiers (the bindings close themselves)."""
        self._core_close()

    # --- StatusFeed --------------------------------------------------------------------

    def jointStatus(self, sample: YouBotStatus) -> None:  # noqa: N802 - named after the port
        """A sample from the binding: stored, waiters woken, clients refreshed."""
        self._on_status(sample)

    # --- DriverProxyCore ---------------------------------------------------------------

    def _write_commands(self, values: list[float]) -> None:
        self.ports.commands(values)

    def _driver_info(self) -> dict[str, Any]:
        with self._lock:
            age = time.monotonic() - self._received_at if self._sample is not None else None
            stamps = list(itertools.islice(reversed(self._arrivals), 50))[::-1]
        live = age is not None and age < self.stale_after
        period = self._period
        if period is None and len(stamps) > 10:  # not told yet: the median spacing of arrivals
            gaps = sorted(b - a for a, b in zip(stamps, stamps[1:]))
            period = round(gaps[len(gaps) // 2], 4)
        return {"state": "RUNNING" if live else "UNKNOWN", "period": period,
                "period_status": "", "connected": live, "address": "binding.dataflow"}

    # --- SettingPeriod -----------------------------------------------------------------

    def set_period(self, seconds: float) -> dict:
        """Through the task's ``set_period`` operation when wired (the driver's answer),
        else a write of its ``period`` port (accepted means sent)."""
        try:
            value = float(seconds)
        except (TypeError, ValueError):
            return {"accepted": False, "period": self._period, "message": f"not a number: {seconds!r}"}
        try:
            if self.operations is None:
                self.ports.period(value)
                accepted, message = True, f"sent {value:g} s to the period port"
            else:
                accepted = bool(self.operations.set_period(value))
                message = f"accepted {value:g} s" if accepted else \
                    f"rejected {value!r}: the period must be in [{MIN_PERIOD:g}, {MAX_PERIOD:g}] s"
        except Exception as exc:  # noqa: BLE001 - reported, not raised
            return {"accepted": False, "period": self._period, "message": f"{type(exc).__name__}: {exc}"}
        if accepted:
            self._period = value
        return {"accepted": accepted, "period": self._period, "message": message}
