"""The dummy youBot driver's dynamics, deterministic with a seed and a SlaveActivity."""

from __future__ import annotations

import pytest
from support import wait_until

from driver import ERROR_BITS, N_JOINTS, YouBotDriver, YouBotStatus, error_names
from youbot_model import JOINT_LIMITS
from dataflow import (
    ConnPolicy, FlowStatus, InputPort, OutputPort, PeriodicActivity, PropertyValueError, SlaveActivity, registry,
)

BIT = {name: 1 << bit for bit, name in ERROR_BITS.items()}


def rig(seed: int = 1, **props):
    d = YouBotDriver("youBotDriver")
    d.set_activity(SlaveActivity())
    d.seed = seed
    for k, v in props.items():
        setattr(d, k, v)
    cmd, per = OutputPort(list[float], "cmd"), OutputPort(float, "per")
    status = InputPort(YouBotStatus, "status")
    cmd.connect_to(d.commands, ConnPolicy.data())
    per.connect_to(d.port("period"), ConnPolicy.data())
    d.port("jointStatus").connect_to(status, ConnPolicy.buffer(1000))
    assert d.configure() and d.start()
    return d, cmd, per, status


def run(d, n):
    for _ in range(n):
        assert d.update()


def last(status):
    flow, s = status.read_newest()
    assert flow is FlowStatus.NEW_DATA
    return s


def test_declaration():
    d = YouBotDriver()
    assert set(d.ports()) == {"commands", "period", "jointStatus"}
    assert d.activity.kind == "periodic" and d.activity.period == 0.01
    assert len(ERROR_BITS) == 10 and registry.python_type("YouBotStatus") is YouBotStatus


def test_commanded_positions_reached_at_bounded_velocity():
    d, cmd, _, status = rig(max_velocity=1.0)
    target = [0.5, -0.5, 1.0, 0.2, -1.0]
    cmd.write(target)
    run(d, 50)  # 0.5 s at 1 rad/s: joints with |target| > 0.5 are still moving
    s = last(status)
    assert s.sequence == 50 and len(s.joints) == N_JOINTS
    assert s.joints[2].position == pytest.approx(0.5, abs=1e-9)
    assert s.joints[2].current > s.joints[3].current  # moving draws more current than holding
    run(d, 60)
    s = last(status)
    assert [j.position for j in s.joints] == pytest.approx(target, abs=1e-9)
    assert all(abs(j.velocity) < 0.05 for j in s.joints)
    assert all(j.error_flags == 0 for j in s.joints)
    d.stop()


def test_joint_limit_bit():
    d, cmd, _, status = rig()
    cmd.write([10.0, 0.0, 0.0, 0.0, 0.0])
    run(d, 400)
    s = last(status)
    assert s.joints[0].position == pytest.approx(JOINT_LIMITS[0][1])
    assert s.joints[0].error_flags & BIT["POSITION_LIMIT"]
    assert "POSITION_LIMIT" in error_names(s.joints[0].error_flags)
    assert not s.joints[1].error_flags & BIT["POSITION_LIMIT"]
    assert "POSITION_LIMIT" in d.call("error_names", 0)


def test_over_temperature_halts_motor():
    d, cmd, _, status = rig(max_temperature=20.0)  # ambient is 25 °C
    cmd.write([1.0] * 5)
    run(d, 10)
    s = last(status)
    assert all(j.error_flags & BIT["OVER_TEMPERATURE"] for j in s.joints)
    assert all(j.error_flags & BIT["MOTOR_HALTED"] for j in s.joints)
    assert all(j.position == 0.0 for j in s.joints)


def test_temperature_drifts_with_current_and_over_current():
    d, cmd, _, status = rig(max_current=0.5)
    cmd.write([2.5, 0.0, 0.0, 0.0, 0.0])
    run(d, 100)
    s = last(status)
    assert s.joints[0].temperature > s.joints[1].temperature
    assert s.joints[0].error_flags & BIT["OVER_CURRENT"]
    assert not s.joints[1].error_flags & BIT["OVER_CURRENT"]


def test_random_bits_and_seed_determinism():
    def samples(seed):
        d, cmd, _, status = rig(seed=seed, random_error_rate=0.2)
        cmd.write([0.3] * 5)
        run(d, 30)
        out = []
        while (r := status.read())[0] is FlowStatus.NEW_DATA:
            out.append([(j.velocity, j.current, j.error_flags) for j in r[1].joints])
        return out

    a, b, c = samples(7), samples(7), samples(8)
    assert a == b and a != c
    assert any(flags for row in a for (_, _, flags) in row)


def test_period_port_accepts_and_rejects():
    d, _, per, _ = rig()
    per.write(0.05)
    run(d, 1)
    assert d.accepted_period == 0.05 and "accepted" in d.period_status
    for bad in (0.0, -1.0, 2.0):
        per.write(bad)
        run(d, 1)
        assert d.accepted_period == 0.05 and "rejected" in d.period_status
    assert d.call("set_period", 0.02) is True and d.accepted_period == 0.02
    assert d.call("set_period", 5.0) is False


def test_period_change_takes_effect_on_periodic_activity():
    d = YouBotDriver("yb")
    per = OutputPort(float, "per")
    per.connect_to(d.port("period"))
    d.start()
    per.write(0.002)
    wait_until(lambda: d.activity.period == 0.002)
    assert isinstance(d.activity, PeriodicActivity) and d.accepted_period == 0.002
    cycles = d.activity.cycles
    wait_until(lambda: d.activity.cycles > cycles + 5)
    d.stop()


def test_reset_operation():
    d, cmd, _, status = rig()
    cmd.write([0.5] * 5)
    run(d, 20)
    d.call("reset")
    run(d, 1)
    assert last(status).sequence == 1
    assert d.positions == [0.0] * 5  # back to the candle pose, set-point cleared


def test_period_lower_bound_and_read_only_status():
    from dataflow.errors import PropertyValueError
    from driver import MIN_PERIOD

    d, _, per, _ = rig()
    per.write(1e-12)
    run(d, 1)
    assert d.accepted_period == 0.01 and d.period_status.startswith("rejected 1e-12")
    assert f"[{MIN_PERIOD:g}, 1] s" in d.period_status
    per.write(MIN_PERIOD)
    run(d, 1)
    assert d.accepted_period == MIN_PERIOD and d.period_status == "accepted 0.001 s"
    for name, value in (("accepted_period", 0.5), ("period_status", "x"), ("command_status", "x")):
        with pytest.raises(PropertyValueError, match="read-only"):
            d.properties()[name].set(value)
    assert d.accepted_period == MIN_PERIOD


def test_malformed_command_reported(caplog):
    d, cmd, _, status = rig()
    for bad, why in (([1, 2, 3, 4], "got 4"), ([0.1, float("nan"), 0, 0, 0], "1 not finite")):
        with caplog.at_level("WARNING", logger="youbot.driver"):
            cmd.write(bad)
            run(d, 2)
        assert d.command_status.startswith("rejected: expected 5 finite values") and why in d.command_status
        assert "rejected" in caplog.text
        assert [j.position for j in last(status).joints] == [0.0] * N_JOINTS
    cmd.write([0.1, 0, 0, 0, 0])
    run(d, 2)
    assert d.command_status.startswith("accepted")


@pytest.mark.parametrize(("prop", "bad"), [
    ("max_velocity", -5.0), ("max_velocity", 1000.0), ("max_velocity", float("nan")), ("max_current", float("-inf")),
    ("max_temperature", 0.0), ("noise", -1.0), ("random_error_rate", 2.0), ("command_timeout", float("inf")),
])
def test_safety_limits_refuse_values_out_of_range(prop: str, bad: float):
    d, _, _, _ = rig()
    before = getattr(d, prop)
    with pytest.raises(PropertyValueError, match=f"youBotDriver.{prop}"):
        setattr(d, prop, bad)
    assert getattr(d, prop) == before
    assert d.describe().properties[[p.name for p in d.describe().properties].index(prop)].bounds


def test_positions_hold_the_joint_limits_at_the_highest_velocity():
    d, cmd, _, status = rig(max_velocity=10.0)
    cmd.write([100.0] * N_JOINTS)  # a local connection: the driver clips, and says so
    run(d, 50)
    for j, (lo, hi) in zip(last(status).joints, JOINT_LIMITS):
        assert lo <= j.position <= hi


def test_error_names_range():
    d, _, _, _ = rig()
    assert d.error_names(0) == []
    with pytest.raises(ValueError, match=r"0\.\.4, got 7"):
        d.error_names(7)


def test_motor_halted_clears_with_threshold_near_ambient():
    d, cmd, _, status = rig(noise=0.0, max_temperature=26.0, max_velocity=5.0)
    for i in range(3000):  # bounded: fast back-and-forth moves heat joint 0 over 26 °C: halted
        cmd.write([0.5 if i % 2 else -0.5, 0, 0, 0, 0])
        run(d, 20)
        flags = last(status).joints[0].error_flags
        if flags & BIT["MOTOR_HALTED"]:
            break
    assert flags & BIT["MOTOR_HALTED"]
    for _ in range(3000):  # bounded: cools at holding current and the halt clears
        run(d, 50)
        flags = last(status).joints[0].error_flags
        if not flags & BIT["MOTOR_HALTED"]:
            break
    assert not flags & BIT["MOTOR_HALTED"]
