"""The youBot case study's SCA interfaces (the paper's, plus the Locomotor's ``Moving``).

``RetrievingStatus`` and ``SendingCommands`` are bidirectional: their callback interface
is :class:`Notifying`, so whoever calls them receives ``notify(event, detail)`` calls on
its own method of that name. Events: ``busy`` / ``idle`` around a command (``idle`` with
detail ``"timeout"`` when the target was not reached in time) and ``refresh`` when a new
sample of the driver's ``jointStatus`` arrived.

Values crossing these interfaces are plain JSON-able data (lists, dicts, strings), so
the same interfaces work in-process and over ``binding.grpc``.
"""

from __future__ import annotations

from typing import Protocol

import scart

__all__ = ["Notifying", "RetrievingStatus", "SendingCommands", "SettingPeriod", "Moving"]


@scart.interface
class Notifying(Protocol):
    """Callback interface of the driver proxy: implemented by its clients."""

    def notify(self, event: str, detail: str = "") -> None:
        """``busy`` / ``idle`` / ``refresh`` (and ``connected`` / ``disconnected``).

        Called on a thread of the proxy, never on the driver's; must return quickly."""
        ...


@scart.interface(callback=Notifying)
class RetrievingStatus(Protocol):
    """Read the driver's newest data. Calling any operation registers the caller for
    ``refresh`` callbacks (at most one pending per caller: refreshes coalesce)."""

    def get_joints_positions(self) -> list[float]:
        """Joint positions [rad] of the newest sample (empty before the first one). Never blocks."""
        ...

    def get_joints_status(self) -> dict | None:
        """The newest full sample as a JSON-able dict (``sequence``, ``timestamp``,
        ``joints``: list of {position, velocity, current, temperature, error_flags, setpoint}), or
        None before any. Never blocks."""
        ...

    def get_driver_info(self) -> dict:
        """{"state", "period", "period_status", "measured_rate", "connected", "sample_age"}:
        state and period as last read from the driver (None while not connected), measured
        rate in samples/s over the last second, age of the newest sample in s (None before any).
        A proxy of a remote driver adds "address" (the name service it uses), "transport"
        (how its samples come: ipc or grpc; None while not subscribed) and "transport_policy"
        (the one asked for)."""
        ...


@scart.interface(callback=Notifying)
class SendingCommands(Protocol):
    """Command the arm; the caller hears ``busy`` then ``idle`` through ``notify``."""

    @scart.oneway
    def set_joints_positions(self, values: list[float]) -> None:
        """Send 5 joint set-points [rad] (one-way: returns at once)."""
        ...


@scart.interface
class SettingPeriod(Protocol):
    """Change the driver's period."""

    def set_period(self, seconds: float) -> dict:
        """Request a new period; returns {"accepted": bool, "period": float, "message": str}
        — what the driver accepted or why it refused. Blocks (bounded, ~2 s) until the
        driver's ``period_status`` reflects the request."""
        ...


@scart.interface
class Moving(Protocol):
    """The Locomotor's service: move the arm and say when it got there."""

    def poses(self) -> list[str]:
        """Names of the known poses."""
        ...

    def move_to_pose(self, name: str) -> str:
        """Start moving to a named pose; returns a message. Raises ``ValueError`` for an unknown name."""
        ...

    def move_to(self, positions: list[float]) -> str:
        """Start moving to 5 joint positions [rad]; returns a message. Raises ``ValueError``."""
        ...

    def is_busy(self) -> bool:
        """True from a command until the driver proxy reported ``idle``."""
        ...

    def target_reached(self) -> bool:
        """True when the newest positions are within tolerance of the last target."""
        ...

    def outcome(self) -> str:
        """The newest move's report ("target X reached" / "target X not reached: why"; "" before any)."""
        ...

    def last_move(self) -> dict:
        """The newest move, whoever asked for it: {"number": moves so far, "target": its
        name ("" before any), "busy": still moving}. Never blocks."""
        ...
