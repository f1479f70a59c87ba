"""The dummy youBot driver: a periodic data-flow task simulating the 5 arm joints.

Every cycle it publishes a :class:`YouBotStatus` on ``jointStatus``. It is a dummy, but
a plausible one:

* positions move toward the last commanded set-point (``commands``, clipped to the joint
  limits) at most ``max_velocity`` rad/s; velocity follows from that motion, plus noise;
* current follows motion (a holding current plus a term in |velocity|), plus noise;
* temperature drifts with current (I²-heating against cooling to ambient; time constant
  ~100 s);
* error bits (:data:`ERROR_BITS`) follow real conditions — ``POSITION_LIMIT`` (at a limit
  or a command clipped), ``OVER_TEMPERATURE`` (above ``max_temperature``) which also
  halts the motor (``MOTOR_HALTED``) until it cooled 5 °C below, ``OVER_CURRENT`` (above
  ``max_current``), ``I2T_EXCEEDED`` (integrated overload), ``TIMEOUT`` (no command for
  ``command_timeout`` s while a set-point is pending) — plus rare random ones (rate
  ``random_error_rate`` per joint per cycle) that last one sample.

Each cycle it also publishes the arm's frames, ``base_link → arm_link_0 … arm_link_5``
(:mod:`youbot_arm`: the youBot's link lengths and joint axes), in its process's frame
tree (``self.frames``), stamped with the sample's time; ``<scart:frames ros1="true"/>``
puts them on ``/tf``.

``period`` (input port) changes the task's own activity period: a value in
[``MIN_PERIOD``, ``MAX_PERIOD``] = [0.001, 1] s is accepted, anything else is refused;
``accepted_period`` and ``period_status`` (read-only properties: an outside set is refused)
say what was accepted, or why not. A malformed command (not 5 finite numbers) is refused
with a warning and ``command_status`` says why. Both ports also check a value written
from another process as it arrives (``InputPort(check=...)``), so ``scart write`` gets the
driver's verdict at once: a refused value never reaches the task. Settings are sanitised where they are
used: a negative ``max_velocity`` counts as 0, positions never leave ``JOINT_LIMITS``. The random source is seeded with the ``seed``
property at configure time and by ``reset()``: with a :class:`SlaveActivity` the whole
simulation is deterministic (the time step is the nominal period, never wall time).
"""

from __future__ import annotations

import logging
import math
import random
import time
from typing import Annotated

from pydantic import Field

from dataflow import (
    FlowStatus,
    InputPort,
    OutputPort,
    PeriodicActivity,
    Property,
    TaskContext,
    TaskState,
    operation,
)

from youbot_arm import arm_frames, mount
from youbot_model import (
    ERROR_BITS,
    JOINT_LIMITS,
    MAX_PERIOD,
    MIN_PERIOD,
    N_JOINTS,
    JointStatus,
    YouBotStatus,
    error_names,
)

__all__ = ["YouBotDriver", "MIN_PERIOD", "MAX_PERIOD", "ERROR_BITS", "JointStatus", "YouBotStatus", "error_names", "N_JOINTS"]

log = logging.getLogger("youbot.driver")

BIT = {name: 1 << bit for bit, name in ERROR_BITS.items()}
AMBIENT = 25.0
HOLD_CURRENT = 0.15  # A, holding a pose
CURRENT_PER_VELOCITY = 1.2  # A per rad/s
HEATING = 0.165  # °C/s per A²
COOLING = 0.01  # 1/s towards ambient
I2T_LIMIT = 20.0  # A²·s above the nominal current before I2T_EXCEEDED
NOMINAL_CURRENT = 1.5
RANDOM_BITS = ("UNDER_VOLTAGE", "OVER_VOLTAGE", "HALL_SENSOR_ERROR", "ENCODER_ERROR")


def _read_only(value: object) -> None:
    raise ValueError("read-only: set by the driver itself")


#: What ``set_period`` takes: declared, so a call from outside is refused as a write is.
_Period = Annotated[float, Field(ge=MIN_PERIOD, le=MAX_PERIOD, allow_inf_nan=False)]


def _valid_period(seconds: float) -> None:
    """a period in [0.001, 1] s"""
    if not MIN_PERIOD <= seconds <= MAX_PERIOD:
        raise ValueError(f"the period must be in [{MIN_PERIOD:g}, {MAX_PERIOD:g}] s")


def _valid_command(values: list[float]) -> None:
    """5 finite joint set-points"""
    problem = command_problem(values)
    if problem is not None:
        raise ValueError(problem)


class YouBotDriver(TaskContext):
    """Dummy KUKA youBot arm driver (5 joints), periodic (default 10 ms)."""

    commands = InputPort(list[float], doc="joint position set-points [rad], 5 values", ge=-2 * math.pi, le=2 * math.pi,
                         check=_valid_command)
    new_period = InputPort(float, name="period", check=_valid_period,
                           doc=f"new period of the driver [s], in [{MIN_PERIOD:g}, {MAX_PERIOD:g}]")
    status = OutputPort(YouBotStatus, name="jointStatus", doc="joint status, every period")

    # safety limits: finite and within a plausible range (a NaN or -inf limit is refused)
    seed = Property(int, 0, doc="seed of the random source (applied on configure and reset)", ge=0, le=2**32 - 1)
    max_velocity = Property(float, 1.0, doc="joint velocity limit [rad/s]", ge=0.0, le=10.0)
    max_current = Property(float, 2.0, doc="OVER_CURRENT threshold [A]", gt=0.0, le=50.0)
    max_temperature = Property(float, 70.0, doc="OVER_TEMPERATURE threshold [°C]", gt=0.0, le=200.0)
    command_timeout = Property(float, 10.0, doc="TIMEOUT when a set-point is pending this long [s]", gt=0.0, le=3600.0)
    noise = Property(float, 1.0, doc="noise scale (0 = noiseless)", ge=0.0, le=100.0)
    random_error_rate = Property(float, 1e-5, doc="probability of a random error bit per joint per cycle", ge=0.0, le=1.0)
    accepted_period = Property(float, 0.01, doc="the period currently in use [s] (read-only)", check=_read_only)
    period_status = Property(str, "", doc="outcome of the last period request (read-only)", check=_read_only)
    command_status = Property(str, "", doc="outcome of the last command (read-only)", check=_read_only)

    def __init__(self, name: str = "youBotDriver", period: float = 0.01) -> None:
        super().__init__(name)
        self.set_activity(PeriodicActivity(period))
        self._set_status(accepted_period=period, period_status=f"accepted {period:g} s")
        self._reset_state()

    # -- operations -------------------------------------------------------------
    @operation(own_thread=True)
    def reset(self) -> None:
        """Back to the candle pose at ambient temperature, errors cleared, RNG reseeded."""
        self._reset_state()

    @operation
    def set_period(self, seconds: _Period) -> bool:
        """Request a new period (same as writing the ``period`` port); True if accepted.
        Its bounds are declared, so a call from outside is refused as a write is."""
        return self._apply_period(seconds)

    @operation
    def error_names(self, joint: int) -> list[str]:
        """Names of the error bits set on ``joint`` (0..4) in the last sample."""
        if isinstance(joint, bool) or not isinstance(joint, int) or not 0 <= joint < N_JOINTS:
            raise ValueError(f"joint must be an integer in 0..{N_JOINTS - 1}, got {joint!r}")
        return error_names(self._flags[joint])

    # -- lifecycle --------------------------------------------------------------
    def configure_hook(self) -> bool:
        # The activity may have been replaced after __init__ (a composite's period="..."):
        # what is in use is what the properties report.
        act = self.activity
        if isinstance(act, PeriodicActivity) and act.period != self.accepted_period:
            self._set_status(accepted_period=act.period, period_status=f"accepted {act.period:g} s")
        self._reset_state()
        self.frames.publish(mount(), static=True, authority=self.name)
        return True

    def update_hook(self) -> None:
        flow, period = self.new_period.read()
        if flow is FlowStatus.NEW_DATA:
            self._apply_period(period)
        flow, cmd = self.commands.read()
        if flow is FlowStatus.NEW_DATA:
            self._apply_command(cmd)
        self._step(self.accepted_period)
        self._sequence += 1
        now = time.time_ns()
        self.status.write(self._sample(now / 1e9))
        self.frames.publish(arm_frames(self._pos, now), authority=self.name)

    # -- simulation -------------------------------------------------------------
    def _set_status(self, **values: object) -> None:
        """Update read-only properties (their ``check`` refuses every outside set)."""
        for name, value in values.items():
            self._prop_values[name] = getattr(type(self), name)._adapter.validate_python(value)

    def _reset_state(self) -> None:
        self._rng = random.Random(self.seed)
        self._pos = [0.0] * N_JOINTS
        self._vel = [0.0] * N_JOINTS
        self._cur = [HOLD_CURRENT] * N_JOINTS
        self._temp = [AMBIENT] * N_JOINTS
        self._target = [0.0] * N_JOINTS
        self._flags = [0] * N_JOINTS
        self._clipped = [False] * N_JOINTS
        self._halted = [False] * N_JOINTS
        self._i2t = [0.0] * N_JOINTS
        self._since_command = 0.0
        self._sequence = 0

    def _apply_period(self, seconds: object) -> bool:
        try:
            value = float(seconds)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            value = math.nan
        if not (MIN_PERIOD <= value <= MAX_PERIOD):
            self._set_status(period_status=f"rejected {seconds!r}: the period must be in "
                                           f"[{MIN_PERIOD:g}, {MAX_PERIOD:g}] s")
            return False
        act = self.activity
        if isinstance(act, PeriodicActivity):
            act.period = value
        self._set_status(accepted_period=value, period_status=f"accepted {value:g} s")
        return True

    def _apply_command(self, cmd: list[float] | None) -> None:
        problem = command_problem(cmd)
        if problem is not None:  # refused: the previous set-point stays
            log.warning("%s: command %.80r rejected: %s", self.name, cmd, problem)
            self._set_status(command_status=f"rejected: {problem}")
            return
        self._set_status(command_status=f"accepted {[round(float(x), 4) for x in cmd]}")
        for j, (lo, hi) in enumerate(JOINT_LIMITS):
            self._target[j] = min(max(cmd[j], lo), hi)
            self._clipped[j] = not lo <= cmd[j] <= hi
        self._since_command = 0.0

    def _step(self, dt: float) -> None:
        rng, noise = self._rng, self.noise
        self._since_command += dt
        for j in range(N_JOINTS):
            flags = 0
            if self._temp[j] > self.max_temperature:
                self._halted[j] = True
            elif self._temp[j] < max(self.max_temperature - 5.0, (AMBIENT + self.max_temperature) / 2):  # reachable
                self._halted[j] = False
            max_step = 0.0 if self._halted[j] else max(0.0, self.max_velocity) * dt
            err = self._target[j] - self._pos[j]
            step = min(max(err, -max_step), max_step)
            lo, hi = JOINT_LIMITS[j]
            self._pos[j] = min(max(self._pos[j] + step, lo), hi)
            self._vel[j] = step / dt + rng.gauss(0.0, 0.002) * noise
            accel_free = HOLD_CURRENT + CURRENT_PER_VELOCITY * abs(step / dt)
            self._cur[j] = max(0.0, accel_free + rng.gauss(0.0, 0.01) * noise)
            cur = self._cur[j]
            self._temp[j] += (HEATING * cur * cur - COOLING * (self._temp[j] - AMBIENT)) * dt
            self._i2t[j] = max(0.0, self._i2t[j] + (cur * cur - NOMINAL_CURRENT**2) * dt)
            if self._clipped[j] or self._pos[j] <= lo or self._pos[j] >= hi:
                flags |= BIT["POSITION_LIMIT"]
            if self._temp[j] > self.max_temperature:
                flags |= BIT["OVER_TEMPERATURE"]
            if self._halted[j]:
                flags |= BIT["MOTOR_HALTED"]
            if cur > self.max_current:
                flags |= BIT["OVER_CURRENT"]
            if self._i2t[j] > I2T_LIMIT:
                flags |= BIT["I2T_EXCEEDED"]
            if abs(err) > 1e-6 and self._since_command > self.command_timeout:
                flags |= BIT["TIMEOUT"]
            if rng.random() < self.random_error_rate:
                flags |= BIT[rng.choice(RANDOM_BITS)]
            self._flags[j] = flags

    def _sample(self, timestamp: float) -> YouBotStatus:
        joints = [
            JointStatus.model_construct(
                position=self._pos[j],
                velocity=self._vel[j],
                current=self._cur[j],
                temperature=self._temp[j],
                error_flags=self._flags[j],
                setpoint=self._target[j],
            )
            for j in range(N_JOINTS)
        ]
        return YouBotStatus.model_construct(
            joints=joints, timestamp=timestamp, sequence=self._sequence
        )

    @property
    def positions(self) -> list[float]:
        """Current joint positions [rad] (a copy)."""
        return list(self._pos)

    def is_halted(self) -> bool:
        """True when any joint motor is halted (over-temperature)."""
        return any(self._halted) and self.state >= TaskState.RUNNING


def command_problem(cmd: object) -> str | None:
    """Why ``cmd`` is not a valid command (5 finite numbers), or None."""
    try:
        values = [float(x) for x in cmd]  # type: ignore[union-attr]
    except (TypeError, ValueError):
        return f"expected {N_JOINTS} finite values, got {cmd!r:.60}"
    bad = sum(1 for v in values if not math.isfinite(v))
    if len(values) != N_JOINTS or bad:
        extra = f" ({bad} not finite)" if bad else ""
        return f"expected {N_JOINTS} finite values, got {len(values)}{extra}"
    return None
