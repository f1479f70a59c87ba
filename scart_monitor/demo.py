"""A synthetic arm that feeds a `MonitorServer`: to look at the page without a robot, and
for the monitor's own tests (it stands in for the driver + proxy + Locomotor host).

    python -m scart_monitor.demo [--port 8765]

`SyntheticArm` is both the `MonitorBackend` and the status source: one feeder thread
(created in `start`, joined in `stop`) publishes a status every period; positions move
toward the commanded pose at a bounded velocity, current follows velocity, temperature
drifts with current, and error bits follow those conditions.
"""

from __future__ import annotations

import argparse
import math
import random
import threading
import time

from .server import MonitorServer

JOINTS = 5
MAX_VELOCITY = 1.5  # rad/s
TOLERANCE = 1e-3  # rad
LIMIT = 2.9  # rad, |position| at or past it sets POSITION_LIMIT
OVER_TEMPERATURE = 45.0  # °C
AMBIENT = [28.0, 30.0, 32.0, 34.0, 43.0]  # °C per joint at rest (joint 5 runs hot: a visible flag)
TAU_S = 20.0  # s, thermal time constant

# The same bit names as the dummy driver's (composites/youbot/youbot_model.py), not imported: the
# monitor package stands alone.
DEMO_FLAG_NAMES: dict[int, str] = {
    0: "OVER_CURRENT",
    1: "UNDER_VOLTAGE",
    2: "OVER_VOLTAGE",
    3: "OVER_TEMPERATURE",
    4: "MOTOR_HALTED",
    5: "HALL_SENSOR_ERROR",
    6: "ENCODER_ERROR",
    7: "POSITION_LIMIT",
    8: "TIMEOUT",
    9: "I2T_EXCEEDED",
}
_FLAG_BIT: dict[str, int] = {name: 1 << bit for bit, name in DEMO_FLAG_NAMES.items()}

POSES: dict[str, list[float]] = {
    "home": [0.0, 0.0, 0.0, 0.0, 0.0],
    "candle": [0.0, 1.1, -1.0, 1.4, 0.0],
    "folded": [0.5, -1.0, 1.2, -0.8, 0.3],
    "reach": [-1.2, 0.8, 0.6, 0.4, -0.9],
}


class SyntheticArm:
    """Fake driver host: `MonitorBackend` methods plus a feeder thread.

    Thread-safe: the backend methods are called from HTTP handler threads while the
    feeder runs. `start`/`stop` as in the runtime: one thread, created in `start`,
    joined in `stop` (idempotent).
    """

    def __init__(self, period: float = 0.02, seed: int = 0, max_runtime: float = 3600.0) -> None:
        self.server: MonitorServer | None = None
        self.sent: list[str | list[float]] = []
        self._period = period
        self._max_runtime = max_runtime
        self._rng = random.Random(seed)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pos = [0.2, -0.4, 0.6, -0.2, 0.1]
        self._target = list(self._pos)
        self._target_name = ""
        self._busy = False
        self._temp = [a + 3.0 for a in AMBIENT]
        self._seq = 0

    # -- MonitorBackend ---------------------------------------------------------------

    def set_period(self, seconds: float) -> tuple[bool, str]:
        """Accept 2 ms … 1 s, as a driver would; otherwise say why not."""
        if not 0.002 <= seconds <= 1.0:
            return False, f"refused {seconds * 1000:g} ms: the period must be between 2 ms and 1 s"
        with self._lock:
            self._period = seconds
        if self.server is not None:
            self.server.set_driver_info("RUNNING", seconds, True)
        return True, f"driver period set to {seconds * 1000:g} ms"

    def send_pose(self, pose: str | list[float]) -> tuple[bool, str]:
        """Move toward a named pose or 5 joint positions; emits busy now, idle/reached later."""
        if isinstance(pose, str):
            if pose not in POSES:
                return False, f"unknown pose {pose!r}; known: {', '.join(POSES)}"
            target, name = POSES[pose], pose
        else:
            if len(pose) != JOINTS:
                return False, f"expected {JOINTS} joint positions, got {len(pose)}"
            target, name = list(pose), "[" + ", ".join(f"{v:.2f}" for v in pose) + "]"
        with self._lock:
            self._target, self._target_name, self._busy = list(target), name, True
            self.sent.append(pose)
        if self.server is not None:
            self.server.publish_event("busy", f"moving to {name}")
        return True, f"moving to {name}"

    def poses(self) -> list[str]:
        """The named poses."""
        return list(POSES)

    # -- lifecycle --------------------------------------------------------------------

    def start(self, server: MonitorServer) -> None:
        """Feed ``server``: sets its flag names and driver info, starts the feeder thread."""
        self.server = server
        server.error_flag_names = DEMO_FLAG_NAMES
        server.joint_limits = [(-LIMIT, LIMIT)] * JOINTS
        server.set_driver_info("RUNNING", self._period, True)
        self._thread = threading.Thread(target=self._run, name="scart-monitor-demo-feeder", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop and join the feeder. Idempotent."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    # -- feeder -----------------------------------------------------------------------

    def _run(self) -> None:
        started = time.monotonic()
        deadline = started
        while time.monotonic() - started < self._max_runtime:
            with self._lock:
                period = self._period
            deadline += period
            now = time.monotonic()
            if deadline < now - period:  # fell behind (a slow machine): do not burst
                deadline = now
            if self._stop.wait(max(0.0, deadline - now)):  # pacing, woken early by stop()
                return
            self._step(period)

    def _step(self, dt: float) -> None:
        server = self.server
        assert server is not None  # set by start()
        with self._lock:
            sample, reached = self._advance(dt)
            name = self._target_name
        server.publish_status(sample)
        server.publish_event("refresh")
        if reached:
            server.publish_event("idle", f"at {name}")
            server.publish_event("reached", name)

    def _advance(self, dt: float) -> tuple[dict[str, object], bool]:
        joints = []
        for i in range(JOINTS):
            error = self._target[i] - self._pos[i]
            step = max(-MAX_VELOCITY * dt, min(MAX_VELOCITY * dt, error))
            self._pos[i] += step
            velocity = step / dt + self._rng.gauss(0.0, 0.002)
            current = 0.35 + 0.9 * abs(velocity) + 0.05 * math.sin(self._seq / 25 + i) + self._rng.gauss(0, 0.01)
            # first-order drift toward a current-dependent equilibrium (time constant TAU_S)
            equilibrium = AMBIENT[i] + 8.0 * current
            self._temp[i] += (equilibrium - self._temp[i]) * min(1.0, dt / TAU_S)
            flags = 0
            if abs(self._pos[i]) >= LIMIT:
                flags |= _FLAG_BIT["POSITION_LIMIT"]
            if self._temp[i] > OVER_TEMPERATURE:
                flags |= _FLAG_BIT["OVER_TEMPERATURE"]
            if current > 2.5:
                flags |= _FLAG_BIT["OVER_CURRENT"]
            joints.append(
                {
                    "position": self._pos[i],
                    "velocity": velocity,
                    "current": current,
                    "temperature": self._temp[i],
                    "error_flags": flags,
                    "setpoint": self._target[i],
                }
            )
        self._seq += 1
        reached = self._busy and all(abs(t - p) < TOLERANCE for t, p in zip(self._target, self._pos))
        if reached:
            self._busy = False
        return {"sequence": self._seq, "timestamp": time.time(), "joints": joints}, reached


def main(argv: list[str] | None = None) -> int:
    """Serve the monitor with a synthetic arm until Ctrl-C."""
    parser = argparse.ArgumentParser(description="youBot Monitor with a synthetic arm")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--period", type=float, default=0.01, help="feeder period in seconds")
    args = parser.parse_args(argv)
    arm = SyntheticArm(period=args.period)
    server = MonitorServer(arm, host=args.host, port=args.port)
    server.start()
    arm.start(server)
    print(f"youBot Monitor (synthetic arm): {server.url}", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        arm.stop()
        server.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
