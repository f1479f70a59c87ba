"""``Locomotor``: moves the youBot arm to named poses or joint positions.

It commands the driver proxy through ``SendingCommands`` (one-way) and hears back through
the ``Notifying`` callback: its :meth:`Locomotor.notify` receives ``busy`` / ``idle`` /
``refresh``. When ``busy_out`` is wired (``youbot.composite``: a ``binding.dataflow`` to the
``locomotorState`` task), every change of its busy flag is written there too, for the
``armSummary`` bridge. It reports (log and :attr:`Locomotor.reports`) when the target is reached —
the newest positions within ``tolerance`` of the target.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque

import scart
from arm_summary import BusyFeed
from interfaces import Moving, RetrievingStatus, SendingCommands
from youbot_model import JOINT_LIMITS, N_JOINTS

__all__ = ["Locomotor", "POSES"]

log = logging.getLogger("youbot.locomotor")

POSES: dict[str, list[float]] = {
    "home": [0.0, 0.0, 0.0, 0.0, 0.0],
    "candle": [0.0, 1.1, -1.0, 1.4, 0.0],
    "folded": [0.5, -1.0, 1.2, -0.8, 0.3],
    "reach": [-1.2, 0.8, 0.6, 0.4, -0.9],
    "wave": [1.0, 0.3, -0.5, 1.0, 1.5],
}
"""Named poses [rad] (all inside :data:`youbot_model.JOINT_LIMITS`)."""


@scart.component(services=[Moving])
class Locomotor:
    """Moves the arm; thread-safe (callbacks arrive on the proxy's notifier thread)."""

    tolerance: float = scart.prop(default=0.02)
    poses_table: dict = scart.prop(default=POSES)
    driver: SendingCommands = scart.reference()
    status: RetrievingStatus = scart.reference()
    busy_out: BusyFeed | None = scart.reference(required=False)

    @scart.init
    def open(self) -> None:
        """Prepare the state (nothing is commanded at start)."""
        self._lock = threading.Lock()
        self._publish_lock = threading.Lock()
        self._busy = False
        self._target: list[float] | None = None
        self._target_name = ""
        self._moves = 0
        self.reports: deque[str] = deque(maxlen=100)
        self.refreshes = 0
        self._table = {str(k): [float(x) for x in v] for k, v in dict(self.poses_table or POSES).items()}

    # --- Moving ------------------------------------------------------------------------

    def poses(self) -> list[str]:
        """The pose names, in table order."""
        return list(self._table)

    def move_to_pose(self, name: str) -> str:
        """Start moving to pose ``name``; raises ``ValueError`` listing the known poses."""
        if name not in self._table:
            raise ValueError(f"unknown pose {name!r}; known: {', '.join(self._table)}")
        return self._move(self._table[name], name)

    def move_to(self, positions: list[float]) -> str:
        """Start moving to 5 joint positions; raises ``ValueError`` if malformed or out of limits."""
        values = [float(v) for v in positions]
        if len(values) != N_JOINTS or not all(math.isfinite(v) for v in values):
            raise ValueError(f"expected {N_JOINTS} finite joint positions, got {positions!r}")
        for j, (v, (lo, hi)) in enumerate(zip(values, JOINT_LIMITS)):
            if not lo <= v <= hi:
                raise ValueError(f"joint {j + 1}: {v:g} rad is outside [{lo:g}, {hi:g}]")
        return self._move(values, "[" + ", ".join(f"{v:.2f}" for v in values) + "]")

    def is_busy(self) -> bool:
        """True from a command until the proxy's ``idle`` for it."""
        with self._lock:
            return self._busy

    def target_reached(self) -> bool:
        """True when the newest positions are within ``tolerance`` of the last target."""
        with self._lock:
            target = self._target
        if target is None:
            return False
        positions = self.status.get_joints_positions()
        return len(positions) == len(target) and all(
            abs(p - t) <= self.tolerance for p, t in zip(positions, target)
        )

    def _move(self, target: list[float], name: str) -> str:
        with self._lock:
            self._target, self._target_name, self._busy = list(target), name, True
            self._moves += 1
        self._publish_busy()
        self.driver.set_joints_positions(list(target))  # one-way: returns at once
        log.info("moving to %s", name)
        return f"moving to {name}"

    # --- Notifying (callback from the driver proxy) ------------------------------------

    def notify(self, event: str, detail: str = "") -> None:
        """``busy`` / ``idle`` / ``refresh`` from the driver proxy (never blocks)."""
        if event == "refresh":
            self.refreshes += 1
            return
        if event == "busy":
            with self._lock:
                self._busy = True
            self._publish_busy()
        elif event == "idle" and detail != "superseded":
            with self._lock:
                self._busy = False
                name = self._target_name
            self._publish_busy()
            if detail == "":
                report = f"target {name} reached"
                log.info(report)
            else:
                report = f"target {name} not reached: {detail}"
                log.warning(report)
            self.reports.append(report)

    def _publish_busy(self) -> None:
        """The flag as it is now to ``busy_out`` when wired, one writer at a time (so the last
        value written is the current one); a task not there yet: logged, not raised."""
        if self.busy_out is None:
            return
        with self._publish_lock:
            with self._lock:
                busy = self._busy
            try:
                self.busy_out.set_busy(busy)
            except Exception as exc:  # noqa: BLE001 - the flag is informative: never fail a move for it
                log.debug("busy flag not written: %s", exc)

    def outcome(self) -> str:
        """The newest report (``Moving.outcome``)."""
        return self.last_report

    def last_move(self) -> dict:
        """``Moving.last_move``: the newest move, from any caller (the monitor's page, ``scart
        call``, another component)."""
        with self._lock:
            return {"number": self._moves, "target": self._target_name, "busy": self._busy}

    @property
    def last_report(self) -> str:
        """The newest report ("" before any)."""
        return self.reports[-1] if self.reports else ""
