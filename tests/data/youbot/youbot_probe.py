"""A test client of the youBot driver proxy: records every ``notify`` it receives."""

from __future__ import annotations

import threading
from typing import Protocol

import scart
from interfaces import RetrievingStatus, SendingCommands, SettingPeriod


@scart.interface
class Probing(Protocol):
    """What the tests drive."""

    def register(self) -> list[float]: ...
    def command(self, values: list[float]) -> None: ...
    def events(self) -> list[list[str]]: ...
    def refreshes(self) -> int: ...
    def status(self) -> dict | None: ...
    def info(self) -> dict: ...
    def set_period(self, seconds: float) -> dict: ...


@scart.component(services=[Probing])
class Probe:
    """Calls the proxy through wired references and keeps what comes back."""

    status_ref: RetrievingStatus = scart.reference()
    driver: SendingCommands = scart.reference()
    period: SettingPeriod = scart.reference()

    @scart.init
    def open(self) -> None:
        self._lock = threading.Lock()
        self._events: list[list[str]] = []
        self._refreshes = 0

    def register(self) -> list[float]:
        return self.status_ref.get_joints_positions()

    def command(self, values: list[float]) -> None:
        self.driver.set_joints_positions(values)

    def events(self) -> list[list[str]]:
        with self._lock:
            return [list(e) for e in self._events]

    def refreshes(self) -> int:
        return self._refreshes

    def status(self) -> dict | None:
        return self.status_ref.get_joints_status()

    def info(self) -> dict:
        return self.status_ref.get_driver_info()

    def set_period(self, seconds: float) -> dict:
        return self.period.set_period(seconds)

    def notify(self, event: str, detail: str = "") -> None:
        if event == "refresh":
            self._refreshes += 1
            return
        with self._lock:
            self._events.append([event, detail])
