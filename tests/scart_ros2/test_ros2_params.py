"""The vocabulary of a ROS 2 node's parameter and logger services (:mod:`scart_ros2.params`):
Python values as ``rcl_interfaces/msg/ParameterValue`` through rmw's CDR bytes and back,
the services' types as the distro's store knows them, and rcutils' log levels."""

from __future__ import annotations

import logging
from typing import Any

import pytest

pytest.importorskip("cyclonedds.idl", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from scart_ros2 import MessageTypes  # noqa: E402
from scart_ros2.params import (  # noqa: E402
    LOGGER_SERVICES, ROSOUT_TYPE, SERVICES, from_value, log_level, service_type, to_value)

VALUE = "rcl_interfaces/msg/ParameterValue"


@pytest.mark.parametrize("value", [True, -(2**63), 2.5, "ü", b"\x00\x7f", b"\x80\xc8\xff", [True, False], [1, 2],
                                   [1, 2.5], ["a", ""]])
def test_a_value_crosses_as_a_parameter_value_and_comes_back(value: Any) -> None:
    types = MessageTypes()
    fields = to_value(value)
    assert fields is not None
    back = from_value(types.deserialize(VALUE, types.serialize(VALUE, fields)))
    expected = [float(v) for v in value] if value == [1, 2.5] else value
    assert back == expected and type(back) is type(expected)


def test_octets_over_127_cross_cyclone_as_rosbags_has_them() -> None:
    """A ``byte[]`` (octets, 0..255 on the wire) from Cyclone's own types: int8 as rosbags
    deserialises it, and the same bytes again as a parameter value."""
    types = MessageTypes()
    idl = types.to_idl(VALUE, to_value(b"\x01\xc8\xff"))
    msg = types.from_idl(VALUE, type(idl).deserialize(idl.serialize()))
    assert msg.byte_array_value.tolist() == [1, -56, -1]
    assert from_value(msg) == b"\x01\xc8\xff"


@pytest.mark.parametrize("value", [2**63, [], [1, "a"], {"a": 1}, None])
def test_what_a_parameter_value_cannot_hold_is_none(value: Any) -> None:
    assert to_value(value) is None


def test_an_unset_value_is_refused() -> None:
    types = MessageTypes()
    with pytest.raises(ValueError, match="not set"):
        from_value(types.deserialize(VALUE, types.serialize(VALUE, {"type": 0})))


def test_the_services_and_rosout_have_the_distros_types() -> None:
    types = MessageTypes()
    for name in [*SERVICES, *LOGGER_SERVICES]:
        kind = service_type(name)
        assert kind.startswith("rcl_interfaces/srv/")
        request, response = types.service(kind)
        types.zero(request), types.zero(response)
    types.zero(ROSOUT_TYPE)
    with pytest.raises(KeyError):
        service_type("get_everything")


def test_python_levels_map_onto_rcutils_numbers() -> None:
    assert [log_level(lvl) for lvl in (logging.DEBUG, logging.INFO, logging.WARNING, logging.ERROR,
                                       logging.CRITICAL, 5)] == [10, 20, 30, 40, 50, 10]
