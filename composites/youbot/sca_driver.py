"""``SCAYouBotDriver``: the SCA proxy of the data-flow ``youBotDriver`` (the paper's guideline).

As in the JOrocos SCA–Orocos integration, the proxy is a plain SCA component that uses
the data-flow client library: at ``@init`` it connects to the data-flow system through
the name service (property ``name_service``), gets the ``component`` proxy, subscribes
to its ``jointStatus`` output port (push, or JOrocos-style polling every ``poll_period``
s, at most half the driver period) and keeps the newest sample; it writes the
``commands`` and ``period`` input ports. Property ``transport`` is the push
subscription's ``ConnPolicy.transport``: ``auto`` (default: ``ipc`` when the driver runs
on this host, else ``grpc``), ``ipc`` (``shm`` is taken for it), ``grpc`` (or any other
name ``ConnPolicy.transport`` accepts); a bad one fails ``@init``; polling reads
over gRPC whatever it says. ``get_driver_info`` tells the transport in use
(``transport``: ``ipc`` or ``grpc`` — polling is always ``grpc`` — or None while not
subscribed) and the
one asked for (``transport_policy``). Services ``RetrievingStatus``,
``SendingCommands`` (see :mod:`proxy_core`) and ``SettingPeriod``; callback ``Notifying``.

Threads (all owned: created in ``@init``, signalled then joined in ``@destroy``):

* the *supervisor* connects (retrying every ``retry_interval`` s while the driver is
  not up — ``@init`` never waits for it), subscribes, then refreshes the cached driver
  info (state, accepted period, period status) every ``info_interval`` s, logs
  connection changes and tells the clients (``connected`` / ``disconnected``);
* the subscription's own threads (client library) hand each sample to
  :meth:`~proxy_core.DriverProxyCore._on_status`, which never blocks;
* one notifier per registered client (:class:`proxy_core.Listener`).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any

import scart
from dataflow import ConnPolicy, WriteStatus
from dataflow.remote import ClosedError, RemoteTimeoutError, System, UnavailableError, connect
from scart.bindings.dataflow.settings import DataflowSettings
from interfaces import RetrievingStatus, SendingCommands, SettingPeriod
from proxy_core import DriverProxyCore

__all__ = ["SCAYouBotDriver"]

log = logging.getLogger("youbot.sca_driver")

PERIOD_ANSWER_TIMEOUT = 2.0
"""How long ``set_period`` waits for the driver's ``period_status`` to reflect a request."""

# errors meaning "the driver does not answer" (RemoteTimeoutError is also a TimeoutError)
_OFFLINE_ERRORS: tuple[type[BaseException], ...] = (
    UnavailableError, ClosedError, RemoteTimeoutError, TimeoutError, ConnectionError,
)


@scart.component(services=[RetrievingStatus, SendingCommands, SettingPeriod])
class SCAYouBotDriver(DriverProxyCore):
    """SCA proxy of the data-flow youBot driver (see the module docstring)."""

    name_service: str = scart.prop(default="")
    transport: str = scart.prop(default="auto")
    poll_period: float = scart.prop(default=0.0)
    retry_interval: float = scart.prop(default=0.2)
    info_interval: float = scart.prop(default=0.5)
    ctx: scart.ComponentContext = scart.context()

    # --- lifecycle ---------------------------------------------------------------------

    @scart.init
    def open(self) -> None:
        """Start the supervisor (it connects in the background); returns at once. Raises
        ``ValueError`` naming the component and the property for a bad ``transport``."""
        self._policy = self._subscription_policy()  # before anything starts: @destroy does not run after a failed @init
        self._core_open()
        self._system: System | None = None
        self._proxy: Any = None
        self._subscription: Any = None
        self._subscribe_error = ""  # the last subscription failure logged (each reason once)
        self._info: dict[str, Any] = {"state": None, "period": None, "period_status": "", "connected": False}
        # the property, else the runtime's name service (scart run --ns, SCART_NS, the default)
        dataflow_settings = DataflowSettings.of(self.ctx.settings)  # the data-flow extension's own
        self._address = self.name_service.strip() or dataflow_settings.ns_address
        # the names the driver runs under (scart run --remap renames tasks and ports at launch)
        remap = dataflow_settings.remap
        self._task = remap.component(self.component)
        self._ports = {p: remap.port(self.component, p) for p in ("commands", "period", "jointStatus")}
        self._supervisor = threading.Thread(target=self._supervise, name="scart-youbot-proxy", daemon=True)
        self._supervisor.start()

    def _subscription_policy(self) -> ConnPolicy:
        """``ConnPolicy.data()`` with the ``transport`` property (any name ``ConnPolicy``
        accepts: auto, ipc, shm, grpc); its check's message, naming the accepted names, if not."""
        try:
            policy = ConnPolicy.data().with_(transport=str(self.transport).strip())
        except ValueError as exc:
            raise ValueError(f"component {self.ctx.name}: property transport={self.transport!r}: {exc}") from None
        if self.poll_period > 0 and policy.transport == "ipc":
            log.warning("%s: transport ipc applies to the push subscription only; polling (poll_period %g s) "
                        "reads over gRPC", self.ctx.name, self.poll_period)
        return policy

    @scart.destroy
    def close(self) -> None:
        """Signal every thread, close the subscription and the system, join (idempotent)."""
        self._stop.set()
        with self._sample_cond:
            self._sample_cond.notify_all()
        self._supervisor.join(timeout=10.0)
        with self._lock:
            sub, system = self._subscription, self._system
            self._subscription = self._system = self._proxy = None
        if sub is not None:
            sub.close()
        if system is not None:
            system.close()
        self._core_close()

    # --- DriverProxyCore ---------------------------------------------------------------

    def _write_commands(self, values: list[float]) -> None:
        proxy = self._proxy
        if proxy is None:
            raise ConnectionError(f"not connected to {self._task} at {self._address}")
        status = proxy.write(self._ports["commands"], values)
        if status is not WriteStatus.WRITE_SUCCESS:
            raise ConnectionError(f"writing {self._task}.commands: {status.name}")

    def _driver_info(self) -> dict[str, Any]:
        with self._lock:
            info = dict(self._info)
        info["address"] = self._address
        sub = self._subscription
        info["transport"] = (getattr(sub, "transport", "") or None) if sub is not None else None
        info["transport_policy"] = self._policy.transport
        return info

    # --- SettingPeriod -----------------------------------------------------------------

    def set_period(self, seconds: float) -> dict:
        """Write the driver's ``period`` port, then wait (≤ 2 s) for ``period_status``."""
        proxy = self._proxy
        with self._lock:
            connected = bool(self._info.get("connected"))
        if proxy is None or not connected:
            return self._refused(f"driver offline: not connected to {self._task} at {self._address}")
        try:
            value = float(seconds)
        except (TypeError, ValueError):
            return self._refused(f"not a number: {seconds!r}")
        accepted_text = f"accepted {value:g} s"
        refused_prefix = f"rejected {value!r}"
        try:
            written = proxy.write(self._ports["period"], value)
            if written is not WriteStatus.WRITE_SUCCESS:
                return self._refused(f"driver offline? writing {self._task}.period: {written.name}")
            deadline = time.monotonic() + PERIOD_ANSWER_TIMEOUT
            status = ""
            for _ in range(10_000):  # bounded by the deadline too
                status = str(proxy.get_property("period_status"))
                if status == accepted_text or status.startswith(refused_prefix):
                    break
                if time.monotonic() >= deadline or self._stop.wait(0.01):  # polls a remote property
                    return self._refused(f"no answer from {self._task} within {PERIOD_ANSWER_TIMEOUT:g} s "
                                         f"(state {proxy.state}); last status: {status}")
            period = float(proxy.get_property("accepted_period"))  # type: ignore[arg-type]
        except ValueError as exc:  # the driver's port refused it (its check): the driver's own words
            return self._refused(f"{refused_prefix}: {str(exc).split(': ', 2)[-1]}")
        except Exception as exc:  # noqa: BLE001 - reported, not raised
            log.debug("set_period(%r): %s", seconds, exc)
            if isinstance(exc, _OFFLINE_ERRORS):
                return self._refused(f"driver offline: {self._task} at {self._address} does not answer")
            return self._refused(f"{type(exc).__name__}: {exc}")
        with self._lock:
            self._info.update(period=period, period_status=status)
        self._maybe_adjust_polling(period)
        return {"accepted": status == accepted_text, "period": period, "message": status}

    def _refused(self, message: str) -> dict:
        with self._lock:
            period = self._info.get("period")
        return {"accepted": False, "period": period, "message": message}

    # --- supervisor --------------------------------------------------------------------

    def _supervise(self) -> None:
        """Connect (retrying), subscribe, then keep the driver info fresh until stopped."""
        connected = False
        for _ in range(100_000_000):  # bounded; ends when @destroy sets the stop event
            if self._stop.is_set():
                return
            if self._proxy is None:
                self._try_connect()
            ok = self._proxy is not None and self._poll_info()
            if ok != connected:
                connected = ok
                log.log(logging.INFO if ok else logging.WARNING, "%s at %s: %s", self._task, self._address,
                        "connected" if ok else "disconnected")
                self._core_link(ok)
                self._broadcast("connected" if ok else "disconnected", f"{self._task} at {self._address}")
            if self._stop.wait(self.info_interval if ok else self.retry_interval):
                return

    def _try_connect(self) -> None:
        system = None
        answered = False  # the driver answered: a failure now is the subscription's (e.g. transport ipc)
        try:
            system = connect(self._address, timeout=2.0, security=self.ctx.settings.security)
            proxy = system.component(self._task)
            period = float(proxy.get_property("accepted_period"))  # type: ignore[arg-type]
            answered = True
            sub = proxy.subscribe(self._ports["jointStatus"], self._on_sample, policy=self._policy,
                                  period=self._poll_for(period))
        except Exception as exc:  # noqa: BLE001 - not up yet: retry later
            if answered and str(exc) != self._subscribe_error:  # told once per reason, not each retry
                self._subscribe_error = str(exc)
                log.warning("subscribing to %s.%s (transport %s) failed: %s; retrying", self._task,
                            self._ports["jointStatus"], self._policy.transport, exc)
            else:
                log.debug("connecting to %s at %s failed: %s", self._task, self._address, exc)
            if system is not None:
                system.close()
            return
        self._subscribe_error = ""
        with self._lock:
            stale = self._stop.is_set()
            if not stale:
                self._system, self._proxy, self._subscription = system, proxy, sub
                self._info["period"] = period
        if stale:
            sub.close()
            system.close()

    def _on_sample(self, event: Any) -> None:
        """Observer of ``jointStatus`` (the client library's SampleEvent)."""
        self._on_status(event.value)

    def _poll_for(self, period: float, warn: bool = True) -> float | None:
        """None (push) when ``poll_period`` is 0; else at most half the driver period."""
        if self.poll_period <= 0:
            return None
        if self.poll_period > period / 2:
            if warn:
                log.warning("poll_period %g s is more than half the driver period %g s: polling at %g s",
                            self.poll_period, period, period / 2)
            return period / 2
        return self.poll_period

    def _maybe_adjust_polling(self, period: float) -> None:
        """Re-subscribe at a faster poll when a new period makes the current one too slow."""
        sub, proxy = self._subscription, self._proxy
        if sub is None or proxy is None or sub.period is None:
            return
        wanted = self._poll_for(period, warn=False)
        if wanted is None or math.isclose(wanted, sub.period):
            return
        log.info("driver period %g s: polling every %g s now", period, wanted)
        try:
            fresh = proxy.subscribe(self._ports["jointStatus"], self._on_sample, policy=self._policy, period=wanted)
        except Exception as exc:  # noqa: BLE001 - keep the current subscription; retried on the next change
            log.warning("re-subscribing at %g s failed: %s", wanted, exc)
            return
        with self._lock:
            self._subscription = fresh
        sub.close()

    def _poll_info(self) -> bool:
        proxy = self._proxy
        try:
            state = proxy.state
            period = proxy.get_property("accepted_period")
            status = proxy.get_property("period_status")
        except Exception as exc:  # noqa: BLE001 - the driver went away: report, keep retrying
            log.debug("driver info: %s", exc)
            with self._lock:  # nothing known about a driver we cannot reach
                self._info.update(connected=False, state=None)
            return False
        sub = self._subscription
        live = bool(sub is None or getattr(sub, "connected", True))
        with self._lock:
            changed = self._info.get("period") != period
            self._info.update(state=state, period=period, period_status=status, connected=live)
        if changed and isinstance(period, float):  # changed by someone else (e.g. scart write)
            self._maybe_adjust_polling(period)
        return True
