"""The data-flow side of the bridge scenario: a thermostat task.

Each set-point arriving on ``setpoint`` (an event port: a cycle runs per arrival) moves
the temperature a fraction ``gain`` of the way towards it; the new temperature is
written on ``temperature`` and whether it is still below the target on ``heating``.
"""

from __future__ import annotations

from dataflow import FlowStatus, InputPort, OutputPort, Property, TaskContext, operation


def _fraction(value: float) -> None:
    if not 0.0 < value <= 1.0:
        raise ValueError("gain must be in (0, 1]")


class Thermostat(TaskContext):
    """A first-order thermostat: one temperature sample per set-point."""

    setpoint = InputPort(float, event=True, doc="target temperature (degC)")
    temperature = OutputPort(float, doc="temperature reached (degC)")
    heating = OutputPort(bool, doc="True while below the target")
    gain = Property(float, 0.5, doc="fraction of the error closed per set-point", check=_fraction)
    initial = Property(float, 20.0, doc="temperature at configure time (degC)")

    def __init__(self, name: str = "thermostat") -> None:
        super().__init__(name)
        self.current = 20.0

    def configure_hook(self) -> bool:
        self.current = self.initial
        return True

    @operation
    def reset(self, value: float) -> None:
        """Set the current temperature."""
        self.current = value

    @operation
    def current_temperature(self) -> float:
        """The current temperature."""
        return self.current

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, target = self.setpoint.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.current += self.gain * (target - self.current)
            self.temperature.write(self.current)
            self.heating.write(self.current < target - 1e-9)
