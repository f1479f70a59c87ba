"""Conversions between the core's policies and statuses and their proto messages (private).

Values have their own public codec, :mod:`scart_wire.codec`."""

from __future__ import annotations

import json
from collections.abc import Mapping
from types import MappingProxyType
from enum import Enum
from typing import TypeVar

from dataflow.policy import (MAX_BUFFER, MAX_TOPIC, BufferPolicy, ConnPolicy, ConnType, FlowStatus, LockPolicy, WaitMode,
                             WriteStatus)
from dataflow.remote._proto import df as pb
from dataflow.transports import MAX_NAME

E = TypeVar("E", bound=Enum)

_CONN_TO_MSG: Mapping[ConnType, pb.ConnType] = MappingProxyType({
    ConnType.DATA: pb.CONN_TYPE_DATA,
    ConnType.BUFFER: pb.CONN_TYPE_BUFFER,
    ConnType.CIRCULAR_BUFFER: pb.CONN_TYPE_CIRCULAR_BUFFER,
})
_CONN_FROM_MSG = MappingProxyType({v: k for k, v in _CONN_TO_MSG.items()})


def policy_to_msg(policy: ConnPolicy) -> pb.ConnPolicy:
    """ConnPolicy → ``scart.dataflow.v1.ConnPolicy``."""
    waits = policy.wait is not WaitMode.NO_WAIT
    return pb.ConnPolicy(
        type=_CONN_TO_MSG[policy.type],
        size=policy.size,
        init=policy.init,
        lock_policy=policy.lock_policy.name,
        buffer_policy=policy.buffer_policy.name,
        mandatory=policy.mandatory,
        transport=policy.transport,
        topic=policy.topic,
        wait=policy.wait.value if waits else "",
        wait_timeout=policy.wait_timeout if waits else 0.0,
    )


def policy_from_msg(msg: pb.ConnPolicy | None, default: ConnPolicy | None = None) -> ConnPolicy:
    """``scart.dataflow.v1.ConnPolicy`` → ConnPolicy (unset message → ``default`` or DATA).

    Raises ``ValueError`` (→ ``INVALID_ARGUMENT`` on the wire) naming the bad field for an
    unknown connection type, lock or buffer policy name, a size beyond
    :data:`~dataflow.policy.MAX_BUFFER` (the same limit as in one process), or an invalid
    combination (e.g. a buffer of size 0).
    """
    if msg is None or msg.type == 0:
        return default if default is not None else ConnPolicy.data()
    if msg.type not in _CONN_FROM_MSG:
        raise ValueError(f"policy.type {msg.type} is not a known connection type")
    if msg.size > MAX_BUFFER:
        raise ValueError(f"policy.size {msg.size} is over the limit MAX_BUFFER ({MAX_BUFFER} samples)")
    return ConnPolicy(
        type=_CONN_FROM_MSG[msg.type],
        size=msg.size,
        init=msg.init,
        lock_policy=_member(LockPolicy, "lock_policy", msg.lock_policy, LockPolicy.LOCK_FREE),
        buffer_policy=_member(BufferPolicy, "buffer_policy", msg.buffer_policy, BufferPolicy.PER_CONNECTION),
        mandatory=msg.mandatory if msg.HasField("mandatory") else True,
        transport=msg.transport[:MAX_NAME + 1],  # unknown or too long: ValueError naming the known ones
        topic=msg.topic[:MAX_TOPIC + 1],
        wait=_wait(msg.wait),
        wait_timeout=msg.wait_timeout or 1.0,  # NaN or out of range: ValueError naming the field
    )


def _wait(text: str) -> WaitMode:
    try:
        return WaitMode(text) if text else WaitMode.NO_WAIT
    except ValueError:
        raise ValueError(f"policy.wait {text[:40]!r} is not one of {', '.join(m.value for m in WaitMode)}") from None


def _member(enum: type[E], field: str, name: str, default: E) -> E:
    if not name:
        return default
    if name not in enum.__members__:
        raise ValueError(f"policy.{field} {name!r} is not one of {', '.join(enum.__members__)}")
    return enum[name]


# Both directions between the Python enums and the proto enums (``PREFIX_MEMBER``), built
# once, so the per-sample conversions are one dict lookup.
_FLOW_TO: Mapping[FlowStatus, pb.FlowStatus] = MappingProxyType({
    FlowStatus.NO_DATA: pb.FLOW_STATUS_NO_DATA,
    FlowStatus.OLD_DATA: pb.FLOW_STATUS_OLD_DATA,
    FlowStatus.NEW_DATA: pb.FLOW_STATUS_NEW_DATA,
})
_FLOW_FROM: Mapping[int, FlowStatus] = MappingProxyType({number: member for member, number in _FLOW_TO.items()})
_WRITE_TO: Mapping[WriteStatus, pb.WriteStatus] = MappingProxyType({
    WriteStatus.WRITE_SUCCESS: pb.WRITE_STATUS_WRITE_SUCCESS,
    WriteStatus.WRITE_FAILURE: pb.WRITE_STATUS_WRITE_FAILURE,
    WriteStatus.NOT_CONNECTED: pb.WRITE_STATUS_NOT_CONNECTED,
})
_WRITE_FROM: Mapping[int, WriteStatus] = MappingProxyType({number: member for member, number in _WRITE_TO.items()})


def flow_to_msg(status: FlowStatus) -> pb.FlowStatus:
    """FlowStatus → proto enum number."""
    return _FLOW_TO[status]


def flow_from_msg(number: int) -> FlowStatus:
    """Proto enum number → FlowStatus (unspecified → NO_DATA)."""
    return _FLOW_FROM.get(number, FlowStatus.NO_DATA)


def write_to_msg(status: WriteStatus) -> pb.WriteStatus:
    """WriteStatus → proto enum number."""
    return _WRITE_TO[status]


def write_from_msg(number: int) -> WriteStatus:
    """Proto enum number → WriteStatus (unspecified → WRITE_FAILURE)."""
    return _WRITE_FROM.get(number, WriteStatus.WRITE_FAILURE)


def to_json_text(value: object) -> str:
    """What ``echo --json`` prints for a value."""
    from scart_wire.types import registry

    return json.dumps(registry.to_jsonable(value))
