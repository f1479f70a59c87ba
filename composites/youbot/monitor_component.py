"""``YouBotMonitor``: the SCA component hosting the youBot Monitor web page.

It owns a :class:`monitor.MonitorServer` (started in ``@init``, stopped in ``@destroy``)
and is its backend: period requests go to ``period: SettingPeriod``, poses to
``locomotor: Moving``. It registers with the driver proxy for ``refresh`` callbacks by
calling ``status.get_joints_status()`` at init; on each ``notify("refresh")`` it fetches
the newest sample and publishes it; ``busy``/``idle`` and connection events are shown
in the page's event log. Moves are followed whoever ordered them (the page, ``scart
call Locomotor.move_to_pose``, another component): each new one the Locomotor reports
(``last_move``) shows ``busy``, then ``idle`` and ``reached`` (or why not). A small owned thread (~2 Hz) keeps the driver info (state,
period, connection) up to date. Where its ``bridge`` reference is wired (``youbot.composite``:
a ``binding.dataflow`` to the ``armSummary`` bridge), each refresh also reads the newest
``ArmSummary`` and shows it; where its ``gripper`` reference is wired (a ``binding.dataflow``
to the ``gripper`` task of :mod:`youbot_arm`, which reads the frame tree), where the gripper
is in ``base_link``.

At start it prints ``youBot Monitor: http://HOST:PORT/`` on stdout (flushed). With
``control_token`` true, a fresh random token is made at each start and the printed URL
is ``http://HOST:PORT/?token=...``: only a page opened from that URL can send commands
(see the Security section of :mod:`monitor.server`); the token is printed, never logged.
Unset, ``control_token`` follows the runtime: on when it checks tokens (``--auth-file``),
so the control API is never more open than the gRPC surfaces; ``false`` turns it off
(then a warning says that anyone on this host can command the arm).
"""

from __future__ import annotations

import logging
import secrets
import threading
import time
from collections import deque
from typing import Any, Protocol

import scart
from arm_summary import ArmSummaryReader
from interfaces import Moving, RetrievingStatus, SettingPeriod
from scart_monitor import MonitorServer
from youbot_arm import GripperPosition
from youbot_model import ERROR_BITS, JOINT_LIMITS

__all__ = ["GripperReader", "YouBotMonitor", "MonitorStatistics"]

log = logging.getLogger("youbot.monitor")


@scart.interface
class MonitorStatistics(Protocol):
    """What the monitor received (for benchmarks and tests)."""

    def statistics(self) -> dict:
        """{"url", "published", "refreshes", "latencies": [s, ...] (newest ≤ 20000),
        "first_sequence", "last_sequence", "events": [[name, detail], ...]}."""
        ...


@scart.interface
class GripperReader(Protocol):
    """The newest sample of the gripper task's ``position`` port (binding.dataflow reference)."""

    def position(self) -> GripperPosition | None: ...


@scart.component(services=[MonitorStatistics])
class YouBotMonitor:
    """Hosts the monitor page; implements ``monitor.MonitorBackend`` by delegation."""

    host: str = scart.prop(default="127.0.0.1")
    port: int = scart.prop(default=0)
    info_interval: float = scart.prop(default=0.5)
    control_token: bool | None = scart.prop(default=None)  # None: on when the runtime checks tokens
    insecure: bool = scart.prop(default=False)  # serve a routable host without a control token
    status: RetrievingStatus = scart.reference()
    period: SettingPeriod = scart.reference()
    locomotor: Moving = scart.reference()
    bridge: ArmSummaryReader | None = scart.reference(required=False)
    gripper: GripperReader | None = scart.reference(required=False)
    context: scart.ComponentContext = scart.context()

    @scart.init
    def open(self) -> None:
        """Start the web server (with a fresh control token if ``control_token``), print
        its page URL, register for refresh, start the info thread."""
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self.published = 0
        self.refreshes = 0
        self._last_sequence: int | None = None
        self._moving = ""
        self._move_seen = 0
        self._watching = threading.Lock()  # one thread at a time follows the moves: events in order
        self._first_sequence: int | None = None
        self._latencies: deque[float] = deque(maxlen=20_000)
        self._events: deque[tuple[str, str]] = deque(maxlen=200)
        token = secrets.token_urlsafe(16) if self._wants_token() else None
        self.server = MonitorServer(self, host=self.host, port=int(self.port), token=token, insecure=self.insecure)
        self.server.error_flag_names = dict(ERROR_BITS)
        self.server.joint_limits = list(JOINT_LIMITS)
        self.server.start()
        self.url = self.server.url  # the base (statistics); never the token
        self._thread = threading.Thread(target=self._info_loop, name="scart-youbot-monitor-info", daemon=True)
        try:
            self._publish_newest(self.status.get_joints_status())  # registers us for refresh
            self._move_seen = int(self.locomotor.last_move()["number"])  # moves before this page: not its news
            if not self.locomotor.is_busy():
                self._show("idle", "arm ready")
            self._thread.start()
        except BaseException:
            self.server.stop()  # @destroy does not run after a failed @init
            raise
        print(f"youBot Monitor: {self.server.page_url}", flush=True)

    def _wants_token(self) -> bool:
        """``control_token`` as set, else whether the runtime checks tokens (an auth file)."""
        checks_tokens = bool(self.context.settings.security.auth_file)
        if self.control_token is None:
            return checks_tokens
        if checks_tokens and not self.control_token:
            log.warning("youBot Monitor: control_token=false while the runtime checks tokens: any local user "
                        "can command the arm through the monitor")
        return bool(self.control_token)

    @scart.destroy
    def close(self) -> None:
        """Stop the info thread, then the web server (idempotent)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self.server.stop()

    # --- monitor.MonitorBackend --------------------------------------------------------

    def set_period(self, seconds: float) -> tuple[bool, str]:
        """Ask the driver (through the proxy) for a new period; the driver's answer."""
        answer = self.period.set_period(float(seconds))
        ok = bool(answer.get("accepted"))
        period = answer.get("period")
        message = str(answer.get("message", ""))
        if ok and isinstance(period, (int, float)):
            message = f"driver period {float(period) * 1000:g} ms ({message})"
            self._refresh_info()
        return ok, message

    def send_pose(self, pose: str | list[float]) -> tuple[bool, str]:
        """Named pose or 5 joint positions through the Locomotor; (accepted?, message)."""
        try:
            if isinstance(pose, str):
                message = self.locomotor.move_to_pose(pose)
            else:
                message = self.locomotor.move_to([float(v) for v in pose])
        except ValueError as exc:
            return False, str(exc)
        self._watch_moves()  # busy, as for a move ordered by anyone
        return True, message

    def poses(self) -> list[str]:
        """The Locomotor's named poses."""
        return list(self.locomotor.poses())

    # --- Notifying (callback from the driver proxy) ------------------------------------

    def notify(self, event: str, detail: str = "") -> None:
        """``refresh``: fetch and publish the newest sample; other events are shown."""
        if event == "refresh":
            self.refreshes += 1
            self._read_summary()
            self._read_gripper()
            self._publish_newest(self.status.get_joints_status())
            self.server.publish_event("refresh")
            self._watch_moves()
            return
        if event in ("connected", "disconnected"):  # the page logs changes of the driver info itself
            self._events.append((event, detail))
            self._refresh_info()
            if event == "disconnected" and self._moving:
                self._check_move(offline=True)
            return
        self._show(event, detail)

    def _show(self, event: str, detail: str) -> None:
        self._events.append((event, detail))
        self.server.publish_event(event, detail)

    def _watch_moves(self) -> None:
        """Show ``busy`` for each move the Locomotor started since the last look (whoever
        ordered it; a move it replaced unfinished: ``idle ... superseded``), then follow the
        one in progress (:meth:`_check_move`). Thread-safe; never blocks for long."""
        with self._watching:
            try:
                move = self.locomotor.last_move()
            except Exception as exc:  # noqa: BLE001 - the Locomotor stopping: the next look
                log.debug("last move: %s", exc)
                return
            number = int(move.get("number", 0))
            if number != self._move_seen:
                with self._lock:
                    previous, self._moving, self._move_seen = self._moving, f"moving to {move.get('target')}", number
                if previous:  # the previous move never finished: say so
                    self._show("idle", f"{previous.removeprefix('moving to ')} superseded")
                self._show("busy", self._moving)
            if self._moving:
                self._check_move()

    def _check_move(self, offline: bool = False) -> None:
        """While a move runs: show ``idle`` (and ``reached``) when the Locomotor is no longer
        busy (or the driver went offline), with why it ended."""
        if not offline and self.locomotor.is_busy():
            return
        with self._lock:
            message, self._moving = self._moving, ""
        if not message:
            return
        target = message.removeprefix("moving to ")
        if self.locomotor.target_reached():
            self._show("idle", f"at {target}")
            self._show("reached", target)
        else:
            why = "driver offline" if offline else ""
            if not why:
                try:
                    report = str(self.locomotor.outcome())
                except Exception:  # noqa: BLE001 - an older Locomotor: no reason known
                    report = ""
                why = report.partition("not reached: ")[2]
            self._show("idle", f"{target} not reached" + (f": {why}" if why else ""))

    # --- MonitorStatistics -------------------------------------------------------------

    def statistics(self) -> dict:
        """See :class:`MonitorStatistics`."""
        with self._lock:
            return {
                "url": self.url,
                "published": self.published,
                "refreshes": self.refreshes,
                "latencies": list(self._latencies),
                "first_sequence": self._first_sequence,
                "last_sequence": self._last_sequence,
                "events": [list(e) for e in self._events],
            }

    # --- internals ---------------------------------------------------------------------

    def _publish_newest(self, sample: dict[str, Any] | None) -> None:
        if sample is None:
            return
        received = time.time()
        sequence = sample.get("sequence")
        with self._lock:
            if sequence is not None and sequence == self._last_sequence:
                return  # already shown
            self._last_sequence = sequence
            if self._first_sequence is None:
                self._first_sequence = sequence
            self.published += 1
            stamp = sample.get("timestamp")
            if isinstance(stamp, (int, float)):
                self._latencies.append(received - float(stamp))
        self.server.publish_status(sample)

    def _read_summary(self) -> None:
        """The bridge's newest ArmSummary to the page (carried with the next status)."""
        if self.bridge is None:
            return
        try:
            value = self.bridge.summary()
        except Exception as exc:  # noqa: BLE001 - the bridge not there (yet): nothing to show
            log.debug("arm summary: %s", exc)
            return
        if value is not None:
            self.server.set_summary(value.model_dump())

    def _read_gripper(self) -> None:
        """Where the gripper is in base_link, to the page (carried with the next status)."""
        if self.gripper is None:
            return
        try:
            value = self.gripper.position()
        except Exception as exc:  # noqa: BLE001 - the task not there (yet): nothing to show
            log.debug("gripper: %s", exc)
            return
        if value is not None:
            self.server.set_gripper(value.model_dump())

    def _refresh_info(self) -> None:
        try:
            info = self.status.get_driver_info()
        except Exception as exc:  # noqa: BLE001 - shown as disconnected
            log.debug("driver info: %s", exc)
            self.server.set_driver_info("OFFLINE", 0.0, False)
            return
        period = info.get("period")
        connected = bool(info.get("connected"))
        self.server.set_driver_info(
            str(info.get("state") or "UNKNOWN") if connected else "OFFLINE",  # never a stale RUNNING
            float(period) if isinstance(period, (int, float)) else 0.0,
            connected,
        )

    def _info_loop(self) -> None:
        for _ in range(100_000_000):  # bounded; ends when @destroy sets the stop event
            self._refresh_info()
            self._watch_moves()
            if self._stop.wait(self.info_interval):
                return
