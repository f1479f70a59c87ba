"""What a ROS 2 node serves to be seen as rclpy's nodes are (the client side of
``ros2 param`` and ``ros2 service call .../set_logger_levels``): the names and
``rcl_interfaces`` types of the parameter and logger services, Python values as
``rcl_interfaces/msg/ParameterValue`` and back, the ``/rosout`` topic's QoS and
rcutils' numbers of Python's log levels. What a node's parameters are, and whose logs it
publishes, is the caller's.
"""

from __future__ import annotations

import logging
from types import MappingProxyType
from typing import Any

from .qos import Durability, QoS, Reliability

__all__ = ["LOGGER_SERVICES", "MAX_NAMES", "ROSOUT", "ROSOUT_QOS", "ROSOUT_TYPE", "SERVICES", "SIM_TIME",
           "from_value", "log_level", "service_type", "to_value"]

#: The parameter services (``<node>/<name>``), by name: their ``rcl_interfaces/srv`` type.
SERVICES = MappingProxyType({"get_parameters": "GetParameters", "set_parameters": "SetParameters",
                             "list_parameters": "ListParameters", "describe_parameters": "DescribeParameters",
                             "get_parameter_types": "GetParameterTypes"})
#: The logger services of rclpy since Iron, likewise.
LOGGER_SERVICES = MappingProxyType({"get_logger_levels": "GetLoggerLevels", "set_logger_levels": "SetLoggerLevels"})
#: rcl_interfaces/msg/ParameterType, and the ParameterValue field of each
_FIELDS = MappingProxyType({1: "bool_value", 2: "integer_value", 3: "double_value", 4: "string_value",
                            5: "byte_array_value", 6: "bool_array_value", 7: "integer_array_value",
                            8: "double_array_value", 9: "string_array_value"})
_LEVELS = ((logging.CRITICAL, 50), (logging.ERROR, 40), (logging.WARNING, 30), (logging.INFO, 20))
ROSOUT, ROSOUT_TYPE = "/rosout", "rcl_interfaces/msg/Log"  #: where a node's log goes, and its type
ROSOUT_QOS = QoS(100, Reliability.RELIABLE, Durability.TRANSIENT_LOCAL, lifespan=10.0)  # rcl's, a smaller depth
SIM_TIME = "use_sim_time"  #: the parameter that makes a node follow ``/clock``
_INT64 = range(-(2**63), 2**63)
MAX_NAMES = 10_000  #: names one request may ask about


def service_type(name: str) -> str:
    """The ROS 2 type of the parameter or logger service ``name`` (``get_parameters``...)."""
    return f"rcl_interfaces/srv/{SERVICES.get(name) or LOGGER_SERVICES[name]}"


def log_level(levelno: int) -> int:
    """rcutils' level (``rcl_interfaces/msg/Log``'s ``level``) of a Python record's level."""
    return next((b for lvl, b in _LEVELS if levelno >= lvl), 10)


def _kind(items: list[object]) -> int | None:
    if all(isinstance(i, bool) for i in items):
        return 6
    if all(isinstance(i, int) and not isinstance(i, bool) and i in _INT64 for i in items):
        return 7
    if all(isinstance(i, (int, float)) and not isinstance(i, bool) for i in items):
        return 8
    if all(isinstance(i, str) for i in items):
        return 9
    return None


def to_value(value: Any) -> dict[str, Any] | None:
    """``value`` as an ``rcl_interfaces/msg/ParameterValue`` (fields), or None when it
    cannot be one (an empty list, whose item type is unknown, included)."""
    if isinstance(value, bool):
        kind: int | None = 1
    elif isinstance(value, int):
        kind = 2 if value in _INT64 else None
    elif isinstance(value, float):
        kind = 3
    elif isinstance(value, str):
        kind = 4
    elif isinstance(value, (bytes, bytearray)):
        return {"type": 5, "byte_array_value": list(value)}
    elif isinstance(value, (list, tuple)) and value:
        kind = _kind(list(value))
        if kind == 8:
            value = [float(v) for v in value]
    else:
        kind = None
    return None if kind is None else {"type": kind, _FIELDS[kind]: list(value) if kind > 5 else value}


def from_value(value: Any) -> Any:
    """The Python value of an ``rcl_interfaces/msg/ParameterValue``; ``ValueError`` when
    it is not set."""
    field = _FIELDS.get(int(value.type))
    if field is None:
        raise ValueError("the value is not set (type 0)")
    got = getattr(value, field)
    if int(value.type) == 5:  # octets (rosbags holds them as int8): the bytes :func:`to_value` took
        return bytes(int(v) & 0xFF for v in got)
    return [v.item() if hasattr(v, "item") else v for v in got] if int(value.type) > 4 else got
