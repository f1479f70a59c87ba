from scart_wire.proto.scart.dataflow.v1 import value_pb2 as _value_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class ConnType(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    CONN_TYPE_UNSPECIFIED: _ClassVar[ConnType]
    CONN_TYPE_DATA: _ClassVar[ConnType]
    CONN_TYPE_BUFFER: _ClassVar[ConnType]
    CONN_TYPE_CIRCULAR_BUFFER: _ClassVar[ConnType]

class FlowStatus(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    FLOW_STATUS_UNSPECIFIED: _ClassVar[FlowStatus]
    FLOW_STATUS_NO_DATA: _ClassVar[FlowStatus]
    FLOW_STATUS_OLD_DATA: _ClassVar[FlowStatus]
    FLOW_STATUS_NEW_DATA: _ClassVar[FlowStatus]

class WriteStatus(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    WRITE_STATUS_UNSPECIFIED: _ClassVar[WriteStatus]
    WRITE_STATUS_WRITE_SUCCESS: _ClassVar[WriteStatus]
    WRITE_STATUS_WRITE_FAILURE: _ClassVar[WriteStatus]
    WRITE_STATUS_NOT_CONNECTED: _ClassVar[WriteStatus]

class Transition(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    TRANSITION_UNSPECIFIED: _ClassVar[Transition]
    TRANSITION_CONFIGURE: _ClassVar[Transition]
    TRANSITION_START: _ClassVar[Transition]
    TRANSITION_STOP: _ClassVar[Transition]
    TRANSITION_CLEANUP: _ClassVar[Transition]
    TRANSITION_RECOVER: _ClassVar[Transition]
CONN_TYPE_UNSPECIFIED: ConnType
CONN_TYPE_DATA: ConnType
CONN_TYPE_BUFFER: ConnType
CONN_TYPE_CIRCULAR_BUFFER: ConnType
FLOW_STATUS_UNSPECIFIED: FlowStatus
FLOW_STATUS_NO_DATA: FlowStatus
FLOW_STATUS_OLD_DATA: FlowStatus
FLOW_STATUS_NEW_DATA: FlowStatus
WRITE_STATUS_UNSPECIFIED: WriteStatus
WRITE_STATUS_WRITE_SUCCESS: WriteStatus
WRITE_STATUS_WRITE_FAILURE: WriteStatus
WRITE_STATUS_NOT_CONNECTED: WriteStatus
TRANSITION_UNSPECIFIED: Transition
TRANSITION_CONFIGURE: Transition
TRANSITION_START: Transition
TRANSITION_STOP: Transition
TRANSITION_CLEANUP: Transition
TRANSITION_RECOVER: Transition

class OpenIpcWriterRequest(_message.Message):
    __slots__ = ("task", "port", "policy", "host_id", "hello", "shm")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    HOST_ID_FIELD_NUMBER: _ClassVar[int]
    HELLO_FIELD_NUMBER: _ClassVar[int]
    SHM_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    policy: ConnPolicy
    host_id: str
    hello: LinkHello
    shm: bool
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ..., host_id: _Optional[str] = ..., hello: _Optional[_Union[LinkHello, _Mapping]] = ..., shm: _Optional[bool] = ...) -> None: ...

class OpenIpcWriterResponse(_message.Message):
    __slots__ = ("ticket",)
    TICKET_FIELD_NUMBER: _ClassVar[int]
    ticket: IpcTicket
    def __init__(self, ticket: _Optional[_Union[IpcTicket, _Mapping]] = ...) -> None: ...

class LinkHello(_message.Message):
    __slots__ = ("task", "port", "policy", "channel", "after", "boot_id", "source", "type_name", "name", "source_ns")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    CHANNEL_FIELD_NUMBER: _ClassVar[int]
    AFTER_FIELD_NUMBER: _ClassVar[int]
    BOOT_ID_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    TYPE_NAME_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    SOURCE_NS_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    policy: ConnPolicy
    channel: str
    after: int
    boot_id: str
    source: str
    type_name: str
    name: str
    source_ns: str
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ..., channel: _Optional[str] = ..., after: _Optional[int] = ..., boot_id: _Optional[str] = ..., source: _Optional[str] = ..., type_name: _Optional[str] = ..., name: _Optional[str] = ..., source_ns: _Optional[str] = ...) -> None: ...

class LinkRequest(_message.Message):
    __slots__ = ("heartbeat", "samples", "dropped", "boot_id", "hello", "closing", "part", "more", "slots")
    HEARTBEAT_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    DROPPED_FIELD_NUMBER: _ClassVar[int]
    BOOT_ID_FIELD_NUMBER: _ClassVar[int]
    HELLO_FIELD_NUMBER: _ClassVar[int]
    CLOSING_FIELD_NUMBER: _ClassVar[int]
    PART_FIELD_NUMBER: _ClassVar[int]
    MORE_FIELD_NUMBER: _ClassVar[int]
    SLOTS_FIELD_NUMBER: _ClassVar[int]
    heartbeat: bool
    samples: _containers.RepeatedCompositeFieldContainer[Sample]
    dropped: int
    boot_id: str
    hello: LinkHello
    closing: bool
    part: bytes
    more: bool
    slots: _containers.RepeatedCompositeFieldContainer[ShmSlot]
    def __init__(self, heartbeat: _Optional[bool] = ..., samples: _Optional[_Iterable[_Union[Sample, _Mapping]]] = ..., dropped: _Optional[int] = ..., boot_id: _Optional[str] = ..., hello: _Optional[_Union[LinkHello, _Mapping]] = ..., closing: _Optional[bool] = ..., part: _Optional[bytes] = ..., more: _Optional[bool] = ..., slots: _Optional[_Iterable[_Union[ShmSlot, _Mapping]]] = ...) -> None: ...

class LinkResponse(_message.Message):
    __slots__ = ("last", "lost", "known", "final", "refused", "pending", "released")
    LAST_FIELD_NUMBER: _ClassVar[int]
    LOST_FIELD_NUMBER: _ClassVar[int]
    KNOWN_FIELD_NUMBER: _ClassVar[int]
    FINAL_FIELD_NUMBER: _ClassVar[int]
    REFUSED_FIELD_NUMBER: _ClassVar[int]
    PENDING_FIELD_NUMBER: _ClassVar[int]
    RELEASED_FIELD_NUMBER: _ClassVar[int]
    last: int
    lost: int
    known: bool
    final: bool
    refused: str
    pending: int
    released: _containers.RepeatedScalarFieldContainer[int]
    def __init__(self, last: _Optional[int] = ..., lost: _Optional[int] = ..., known: _Optional[bool] = ..., final: _Optional[bool] = ..., refused: _Optional[str] = ..., pending: _Optional[int] = ..., released: _Optional[_Iterable[int]] = ...) -> None: ...

class OpenIpcReaderRequest(_message.Message):
    __slots__ = ("task", "port", "policy", "host_id", "heartbeat_ms", "shm")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    HOST_ID_FIELD_NUMBER: _ClassVar[int]
    HEARTBEAT_MS_FIELD_NUMBER: _ClassVar[int]
    SHM_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    policy: ConnPolicy
    host_id: str
    heartbeat_ms: int
    shm: bool
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ..., host_id: _Optional[str] = ..., heartbeat_ms: _Optional[int] = ..., shm: _Optional[bool] = ...) -> None: ...

class OpenIpcReaderResponse(_message.Message):
    __slots__ = ("ticket",)
    TICKET_FIELD_NUMBER: _ClassVar[int]
    ticket: IpcTicket
    def __init__(self, ticket: _Optional[_Union[IpcTicket, _Mapping]] = ...) -> None: ...

class IpcTicket(_message.Message):
    __slots__ = ("socket", "secret", "boot_id")
    SOCKET_FIELD_NUMBER: _ClassVar[int]
    SECRET_FIELD_NUMBER: _ClassVar[int]
    BOOT_ID_FIELD_NUMBER: _ClassVar[int]
    socket: str
    secret: bytes
    boot_id: str
    def __init__(self, socket: _Optional[str] = ..., secret: _Optional[bytes] = ..., boot_id: _Optional[str] = ...) -> None: ...

class ConnPolicy(_message.Message):
    __slots__ = ("type", "size", "init", "lock_policy", "buffer_policy", "mandatory", "transport", "topic", "wait", "wait_timeout")
    TYPE_FIELD_NUMBER: _ClassVar[int]
    SIZE_FIELD_NUMBER: _ClassVar[int]
    INIT_FIELD_NUMBER: _ClassVar[int]
    LOCK_POLICY_FIELD_NUMBER: _ClassVar[int]
    BUFFER_POLICY_FIELD_NUMBER: _ClassVar[int]
    MANDATORY_FIELD_NUMBER: _ClassVar[int]
    TRANSPORT_FIELD_NUMBER: _ClassVar[int]
    TOPIC_FIELD_NUMBER: _ClassVar[int]
    WAIT_FIELD_NUMBER: _ClassVar[int]
    WAIT_TIMEOUT_FIELD_NUMBER: _ClassVar[int]
    type: ConnType
    size: int
    init: bool
    lock_policy: str
    buffer_policy: str
    mandatory: bool
    transport: str
    topic: str
    wait: str
    wait_timeout: float
    def __init__(self, type: _Optional[_Union[ConnType, str]] = ..., size: _Optional[int] = ..., init: _Optional[bool] = ..., lock_policy: _Optional[str] = ..., buffer_policy: _Optional[str] = ..., mandatory: _Optional[bool] = ..., transport: _Optional[str] = ..., topic: _Optional[str] = ..., wait: _Optional[str] = ..., wait_timeout: _Optional[float] = ...) -> None: ...

class TaskSummary(_message.Message):
    __slots__ = ("name", "state", "activity", "period", "cycles", "overruns", "last_cycle")
    NAME_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    ACTIVITY_FIELD_NUMBER: _ClassVar[int]
    PERIOD_FIELD_NUMBER: _ClassVar[int]
    CYCLES_FIELD_NUMBER: _ClassVar[int]
    OVERRUNS_FIELD_NUMBER: _ClassVar[int]
    LAST_CYCLE_FIELD_NUMBER: _ClassVar[int]
    name: str
    state: str
    activity: str
    period: float
    cycles: int
    overruns: int
    last_cycle: float
    def __init__(self, name: _Optional[str] = ..., state: _Optional[str] = ..., activity: _Optional[str] = ..., period: _Optional[float] = ..., cycles: _Optional[int] = ..., overruns: _Optional[int] = ..., last_cycle: _Optional[float] = ...) -> None: ...

class PortInfo(_message.Message):
    __slots__ = ("name", "direction", "type_name", "doc", "connections", "event", "last_value", "has_last_value", "bounds", "writes", "check", "streams")
    NAME_FIELD_NUMBER: _ClassVar[int]
    DIRECTION_FIELD_NUMBER: _ClassVar[int]
    TYPE_NAME_FIELD_NUMBER: _ClassVar[int]
    DOC_FIELD_NUMBER: _ClassVar[int]
    CONNECTIONS_FIELD_NUMBER: _ClassVar[int]
    EVENT_FIELD_NUMBER: _ClassVar[int]
    LAST_VALUE_FIELD_NUMBER: _ClassVar[int]
    HAS_LAST_VALUE_FIELD_NUMBER: _ClassVar[int]
    BOUNDS_FIELD_NUMBER: _ClassVar[int]
    WRITES_FIELD_NUMBER: _ClassVar[int]
    CHECK_FIELD_NUMBER: _ClassVar[int]
    STREAMS_FIELD_NUMBER: _ClassVar[int]
    name: str
    direction: str
    type_name: str
    doc: str
    connections: int
    event: bool
    last_value: _value_pb2.Value
    has_last_value: bool
    bounds: str
    writes: int
    check: str
    streams: _containers.RepeatedCompositeFieldContainer[PortStreamInfo]
    def __init__(self, name: _Optional[str] = ..., direction: _Optional[str] = ..., type_name: _Optional[str] = ..., doc: _Optional[str] = ..., connections: _Optional[int] = ..., event: _Optional[bool] = ..., last_value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., has_last_value: _Optional[bool] = ..., bounds: _Optional[str] = ..., writes: _Optional[int] = ..., check: _Optional[str] = ..., streams: _Optional[_Iterable[_Union[PortStreamInfo, _Mapping]]] = ...) -> None: ...

class PortStreamInfo(_message.Message):
    __slots__ = ("name", "topic", "type_name", "state", "refused", "refusal", "unauthenticated")
    NAME_FIELD_NUMBER: _ClassVar[int]
    TOPIC_FIELD_NUMBER: _ClassVar[int]
    TYPE_NAME_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    REFUSED_FIELD_NUMBER: _ClassVar[int]
    REFUSAL_FIELD_NUMBER: _ClassVar[int]
    UNAUTHENTICATED_FIELD_NUMBER: _ClassVar[int]
    name: str
    topic: str
    type_name: str
    state: str
    refused: int
    refusal: str
    unauthenticated: bool
    def __init__(self, name: _Optional[str] = ..., topic: _Optional[str] = ..., type_name: _Optional[str] = ..., state: _Optional[str] = ..., refused: _Optional[int] = ..., refusal: _Optional[str] = ..., unauthenticated: _Optional[bool] = ...) -> None: ...

class PropertyInfo(_message.Message):
    __slots__ = ("name", "type_name", "json_value", "doc", "bounds")
    NAME_FIELD_NUMBER: _ClassVar[int]
    TYPE_NAME_FIELD_NUMBER: _ClassVar[int]
    JSON_VALUE_FIELD_NUMBER: _ClassVar[int]
    DOC_FIELD_NUMBER: _ClassVar[int]
    BOUNDS_FIELD_NUMBER: _ClassVar[int]
    name: str
    type_name: str
    json_value: str
    doc: str
    bounds: str
    def __init__(self, name: _Optional[str] = ..., type_name: _Optional[str] = ..., json_value: _Optional[str] = ..., doc: _Optional[str] = ..., bounds: _Optional[str] = ...) -> None: ...

class Parameter(_message.Message):
    __slots__ = ("name", "type_name")
    NAME_FIELD_NUMBER: _ClassVar[int]
    TYPE_NAME_FIELD_NUMBER: _ClassVar[int]
    name: str
    type_name: str
    def __init__(self, name: _Optional[str] = ..., type_name: _Optional[str] = ...) -> None: ...

class OperationInfo(_message.Message):
    __slots__ = ("name", "params", "returns", "doc", "own_thread", "signature")
    NAME_FIELD_NUMBER: _ClassVar[int]
    PARAMS_FIELD_NUMBER: _ClassVar[int]
    RETURNS_FIELD_NUMBER: _ClassVar[int]
    DOC_FIELD_NUMBER: _ClassVar[int]
    OWN_THREAD_FIELD_NUMBER: _ClassVar[int]
    SIGNATURE_FIELD_NUMBER: _ClassVar[int]
    name: str
    params: _containers.RepeatedCompositeFieldContainer[Parameter]
    returns: str
    doc: str
    own_thread: bool
    signature: str
    def __init__(self, name: _Optional[str] = ..., params: _Optional[_Iterable[_Union[Parameter, _Mapping]]] = ..., returns: _Optional[str] = ..., doc: _Optional[str] = ..., own_thread: _Optional[bool] = ..., signature: _Optional[str] = ...) -> None: ...

class TaskInfo(_message.Message):
    __slots__ = ("summary", "ports", "properties", "operations")
    SUMMARY_FIELD_NUMBER: _ClassVar[int]
    PORTS_FIELD_NUMBER: _ClassVar[int]
    PROPERTIES_FIELD_NUMBER: _ClassVar[int]
    OPERATIONS_FIELD_NUMBER: _ClassVar[int]
    summary: TaskSummary
    ports: _containers.RepeatedCompositeFieldContainer[PortInfo]
    properties: _containers.RepeatedCompositeFieldContainer[PropertyInfo]
    operations: _containers.RepeatedCompositeFieldContainer[OperationInfo]
    def __init__(self, summary: _Optional[_Union[TaskSummary, _Mapping]] = ..., ports: _Optional[_Iterable[_Union[PortInfo, _Mapping]]] = ..., properties: _Optional[_Iterable[_Union[PropertyInfo, _Mapping]]] = ..., operations: _Optional[_Iterable[_Union[OperationInfo, _Mapping]]] = ...) -> None: ...

class ListTasksRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class ListTasksResponse(_message.Message):
    __slots__ = ("tasks",)
    TASKS_FIELD_NUMBER: _ClassVar[int]
    tasks: _containers.RepeatedCompositeFieldContainer[TaskSummary]
    def __init__(self, tasks: _Optional[_Iterable[_Union[TaskSummary, _Mapping]]] = ...) -> None: ...

class DescribeTaskRequest(_message.Message):
    __slots__ = ("task",)
    TASK_FIELD_NUMBER: _ClassVar[int]
    task: str
    def __init__(self, task: _Optional[str] = ...) -> None: ...

class DescribeTaskResponse(_message.Message):
    __slots__ = ("task",)
    TASK_FIELD_NUMBER: _ClassVar[int]
    task: TaskInfo
    def __init__(self, task: _Optional[_Union[TaskInfo, _Mapping]] = ...) -> None: ...

class ChangeStateRequest(_message.Message):
    __slots__ = ("task", "transition")
    TASK_FIELD_NUMBER: _ClassVar[int]
    TRANSITION_FIELD_NUMBER: _ClassVar[int]
    task: str
    transition: Transition
    def __init__(self, task: _Optional[str] = ..., transition: _Optional[_Union[Transition, str]] = ...) -> None: ...

class ChangeStateResponse(_message.Message):
    __slots__ = ("accepted", "state")
    ACCEPTED_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    accepted: bool
    state: str
    def __init__(self, accepted: _Optional[bool] = ..., state: _Optional[str] = ...) -> None: ...

class WritePortRequest(_message.Message):
    __slots__ = ("task", "port", "value", "json", "writer")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    JSON_FIELD_NUMBER: _ClassVar[int]
    WRITER_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    value: _value_pb2.Value
    json: str
    writer: str
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., json: _Optional[str] = ..., writer: _Optional[str] = ...) -> None: ...

class WritePortResponse(_message.Message):
    __slots__ = ("status",)
    STATUS_FIELD_NUMBER: _ClassVar[int]
    status: WriteStatus
    def __init__(self, status: _Optional[_Union[WriteStatus, str]] = ...) -> None: ...

class OpenWriterRequest(_message.Message):
    __slots__ = ("task", "port", "policy")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    policy: ConnPolicy
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ...) -> None: ...

class OpenWriterResponse(_message.Message):
    __slots__ = ("writer", "idle_seconds")
    WRITER_FIELD_NUMBER: _ClassVar[int]
    IDLE_SECONDS_FIELD_NUMBER: _ClassVar[int]
    writer: str
    idle_seconds: float
    def __init__(self, writer: _Optional[str] = ..., idle_seconds: _Optional[float] = ...) -> None: ...

class CloseWriterRequest(_message.Message):
    __slots__ = ("writer",)
    WRITER_FIELD_NUMBER: _ClassVar[int]
    writer: str
    def __init__(self, writer: _Optional[str] = ...) -> None: ...

class CloseWriterResponse(_message.Message):
    __slots__ = ("undelivered",)
    UNDELIVERED_FIELD_NUMBER: _ClassVar[int]
    undelivered: int
    def __init__(self, undelivered: _Optional[int] = ...) -> None: ...

class ReadPortRequest(_message.Message):
    __slots__ = ("task", "port")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ...) -> None: ...

class ReadPortResponse(_message.Message):
    __slots__ = ("flow_status", "value", "sequence", "source_time_ns", "boot_id")
    FLOW_STATUS_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    SEQUENCE_FIELD_NUMBER: _ClassVar[int]
    SOURCE_TIME_NS_FIELD_NUMBER: _ClassVar[int]
    BOOT_ID_FIELD_NUMBER: _ClassVar[int]
    flow_status: FlowStatus
    value: _value_pb2.Value
    sequence: int
    source_time_ns: int
    boot_id: str
    def __init__(self, flow_status: _Optional[_Union[FlowStatus, str]] = ..., value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., sequence: _Optional[int] = ..., source_time_ns: _Optional[int] = ..., boot_id: _Optional[str] = ...) -> None: ...

class SubscribeRequest(_message.Message):
    __slots__ = ("task", "port", "policy", "heartbeat_ms")
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    HEARTBEAT_MS_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    policy: ConnPolicy
    heartbeat_ms: int
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ..., heartbeat_ms: _Optional[int] = ...) -> None: ...

class SubscribeResponse(_message.Message):
    __slots__ = ("heartbeat", "samples", "dropped", "boot_id", "written", "sent_last", "part", "more", "slots")
    HEARTBEAT_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    DROPPED_FIELD_NUMBER: _ClassVar[int]
    BOOT_ID_FIELD_NUMBER: _ClassVar[int]
    WRITTEN_FIELD_NUMBER: _ClassVar[int]
    SENT_LAST_FIELD_NUMBER: _ClassVar[int]
    PART_FIELD_NUMBER: _ClassVar[int]
    MORE_FIELD_NUMBER: _ClassVar[int]
    SLOTS_FIELD_NUMBER: _ClassVar[int]
    heartbeat: bool
    samples: _containers.RepeatedCompositeFieldContainer[Sample]
    dropped: int
    boot_id: str
    written: int
    sent_last: int
    part: bytes
    more: bool
    slots: _containers.RepeatedCompositeFieldContainer[ShmSlot]
    def __init__(self, heartbeat: _Optional[bool] = ..., samples: _Optional[_Iterable[_Union[Sample, _Mapping]]] = ..., dropped: _Optional[int] = ..., boot_id: _Optional[str] = ..., written: _Optional[int] = ..., sent_last: _Optional[int] = ..., part: _Optional[bytes] = ..., more: _Optional[bool] = ..., slots: _Optional[_Iterable[_Union[ShmSlot, _Mapping]]] = ...) -> None: ...

class Sample(_message.Message):
    __slots__ = ("value", "sequence", "source_time_ns", "slot", "slot_size")
    VALUE_FIELD_NUMBER: _ClassVar[int]
    SEQUENCE_FIELD_NUMBER: _ClassVar[int]
    SOURCE_TIME_NS_FIELD_NUMBER: _ClassVar[int]
    SLOT_FIELD_NUMBER: _ClassVar[int]
    SLOT_SIZE_FIELD_NUMBER: _ClassVar[int]
    value: _value_pb2.Value
    sequence: int
    source_time_ns: int
    slot: int
    slot_size: int
    def __init__(self, value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., sequence: _Optional[int] = ..., source_time_ns: _Optional[int] = ..., slot: _Optional[int] = ..., slot_size: _Optional[int] = ...) -> None: ...

class ShmSlot(_message.Message):
    __slots__ = ("id", "size")
    ID_FIELD_NUMBER: _ClassVar[int]
    SIZE_FIELD_NUMBER: _ClassVar[int]
    id: int
    size: int
    def __init__(self, id: _Optional[int] = ..., size: _Optional[int] = ...) -> None: ...

class CallOperationRequest(_message.Message):
    __slots__ = ("task", "operation", "args", "json_args", "use_json")
    TASK_FIELD_NUMBER: _ClassVar[int]
    OPERATION_FIELD_NUMBER: _ClassVar[int]
    ARGS_FIELD_NUMBER: _ClassVar[int]
    JSON_ARGS_FIELD_NUMBER: _ClassVar[int]
    USE_JSON_FIELD_NUMBER: _ClassVar[int]
    task: str
    operation: str
    args: _containers.RepeatedCompositeFieldContainer[_value_pb2.Value]
    json_args: _containers.RepeatedScalarFieldContainer[str]
    use_json: bool
    def __init__(self, task: _Optional[str] = ..., operation: _Optional[str] = ..., args: _Optional[_Iterable[_Union[_value_pb2.Value, _Mapping]]] = ..., json_args: _Optional[_Iterable[str]] = ..., use_json: _Optional[bool] = ...) -> None: ...

class CallOperationResponse(_message.Message):
    __slots__ = ("result",)
    RESULT_FIELD_NUMBER: _ClassVar[int]
    result: _value_pb2.Value
    def __init__(self, result: _Optional[_Union[_value_pb2.Value, _Mapping]] = ...) -> None: ...

class GetPropertyRequest(_message.Message):
    __slots__ = ("task", "name")
    TASK_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    task: str
    name: str
    def __init__(self, task: _Optional[str] = ..., name: _Optional[str] = ...) -> None: ...

class GetPropertyResponse(_message.Message):
    __slots__ = ("value", "json_value")
    VALUE_FIELD_NUMBER: _ClassVar[int]
    JSON_VALUE_FIELD_NUMBER: _ClassVar[int]
    value: _value_pb2.Value
    json_value: str
    def __init__(self, value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., json_value: _Optional[str] = ...) -> None: ...

class SetPropertyRequest(_message.Message):
    __slots__ = ("task", "name", "value", "json")
    TASK_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    JSON_FIELD_NUMBER: _ClassVar[int]
    task: str
    name: str
    value: _value_pb2.Value
    json: str
    def __init__(self, task: _Optional[str] = ..., name: _Optional[str] = ..., value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., json: _Optional[str] = ...) -> None: ...

class SetPropertyResponse(_message.Message):
    __slots__ = ("json_value",)
    JSON_VALUE_FIELD_NUMBER: _ClassVar[int]
    json_value: str
    def __init__(self, json_value: _Optional[str] = ...) -> None: ...

class ConnectPortsRequest(_message.Message):
    __slots__ = ("source_task", "source_port", "sink_task", "sink_port", "policy", "name", "resume")
    SOURCE_TASK_FIELD_NUMBER: _ClassVar[int]
    SOURCE_PORT_FIELD_NUMBER: _ClassVar[int]
    SINK_TASK_FIELD_NUMBER: _ClassVar[int]
    SINK_PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    RESUME_FIELD_NUMBER: _ClassVar[int]
    source_task: str
    source_port: str
    sink_task: str
    sink_port: str
    policy: ConnPolicy
    name: str
    resume: bool
    def __init__(self, source_task: _Optional[str] = ..., source_port: _Optional[str] = ..., sink_task: _Optional[str] = ..., sink_port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ..., name: _Optional[str] = ..., resume: _Optional[bool] = ...) -> None: ...

class ConnectPortsResponse(_message.Message):
    __slots__ = ("local", "sink_address", "note", "link")
    LOCAL_FIELD_NUMBER: _ClassVar[int]
    SINK_ADDRESS_FIELD_NUMBER: _ClassVar[int]
    NOTE_FIELD_NUMBER: _ClassVar[int]
    LINK_FIELD_NUMBER: _ClassVar[int]
    local: bool
    sink_address: str
    note: str
    link: LinkInfo
    def __init__(self, local: _Optional[bool] = ..., sink_address: _Optional[str] = ..., note: _Optional[str] = ..., link: _Optional[_Union[LinkInfo, _Mapping]] = ...) -> None: ...

class DisconnectPortsRequest(_message.Message):
    __slots__ = ("source_task", "source_port", "sink_task", "sink_port", "name")
    SOURCE_TASK_FIELD_NUMBER: _ClassVar[int]
    SOURCE_PORT_FIELD_NUMBER: _ClassVar[int]
    SINK_TASK_FIELD_NUMBER: _ClassVar[int]
    SINK_PORT_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    source_task: str
    source_port: str
    sink_task: str
    sink_port: str
    name: str
    def __init__(self, source_task: _Optional[str] = ..., source_port: _Optional[str] = ..., sink_task: _Optional[str] = ..., sink_port: _Optional[str] = ..., name: _Optional[str] = ...) -> None: ...

class LinkInfo(_message.Message):
    __slots__ = ("name", "source", "sink", "policy", "transport", "samples", "dropped", "kind", "state", "detail", "pending")
    NAME_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    SINK_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    TRANSPORT_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    DROPPED_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    DETAIL_FIELD_NUMBER: _ClassVar[int]
    PENDING_FIELD_NUMBER: _ClassVar[int]
    name: str
    source: str
    sink: str
    policy: str
    transport: str
    samples: int
    dropped: int
    kind: str
    state: str
    detail: str
    pending: int
    def __init__(self, name: _Optional[str] = ..., source: _Optional[str] = ..., sink: _Optional[str] = ..., policy: _Optional[str] = ..., transport: _Optional[str] = ..., samples: _Optional[int] = ..., dropped: _Optional[int] = ..., kind: _Optional[str] = ..., state: _Optional[str] = ..., detail: _Optional[str] = ..., pending: _Optional[int] = ...) -> None: ...

class StreamPortRequest(_message.Message):
    __slots__ = ("task", "port", "policy", "options", "name")
    class OptionsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: str
        def __init__(self, key: _Optional[str] = ..., value: _Optional[str] = ...) -> None: ...
    TASK_FIELD_NUMBER: _ClassVar[int]
    PORT_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    OPTIONS_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    task: str
    port: str
    policy: ConnPolicy
    options: _containers.ScalarMap[str, str]
    name: str
    def __init__(self, task: _Optional[str] = ..., port: _Optional[str] = ..., policy: _Optional[_Union[ConnPolicy, _Mapping]] = ..., options: _Optional[_Mapping[str, str]] = ..., name: _Optional[str] = ...) -> None: ...

class StreamPortResponse(_message.Message):
    __slots__ = ("link",)
    LINK_FIELD_NUMBER: _ClassVar[int]
    link: LinkInfo
    def __init__(self, link: _Optional[_Union[LinkInfo, _Mapping]] = ...) -> None: ...

class UnstreamPortRequest(_message.Message):
    __slots__ = ("name",)
    NAME_FIELD_NUMBER: _ClassVar[int]
    name: str
    def __init__(self, name: _Optional[str] = ...) -> None: ...

class UnstreamPortResponse(_message.Message):
    __slots__ = ("removed",)
    REMOVED_FIELD_NUMBER: _ClassVar[int]
    removed: bool
    def __init__(self, removed: _Optional[bool] = ...) -> None: ...

class ListLinksRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class SubscriptionInfo(_message.Message):
    __slots__ = ("id", "source", "subscriber", "policy", "transport", "samples", "dropped")
    ID_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    SUBSCRIBER_FIELD_NUMBER: _ClassVar[int]
    POLICY_FIELD_NUMBER: _ClassVar[int]
    TRANSPORT_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    DROPPED_FIELD_NUMBER: _ClassVar[int]
    id: int
    source: str
    subscriber: str
    policy: str
    transport: str
    samples: int
    dropped: int
    def __init__(self, id: _Optional[int] = ..., source: _Optional[str] = ..., subscriber: _Optional[str] = ..., policy: _Optional[str] = ..., transport: _Optional[str] = ..., samples: _Optional[int] = ..., dropped: _Optional[int] = ...) -> None: ...

class ListLinksResponse(_message.Message):
    __slots__ = ("links", "subscriptions")
    LINKS_FIELD_NUMBER: _ClassVar[int]
    SUBSCRIPTIONS_FIELD_NUMBER: _ClassVar[int]
    links: _containers.RepeatedCompositeFieldContainer[LinkInfo]
    subscriptions: _containers.RepeatedCompositeFieldContainer[SubscriptionInfo]
    def __init__(self, links: _Optional[_Iterable[_Union[LinkInfo, _Mapping]]] = ..., subscriptions: _Optional[_Iterable[_Union[SubscriptionInfo, _Mapping]]] = ...) -> None: ...

class RerouteLinkRequest(_message.Message):
    __slots__ = ("name", "sink_task", "sink_port")
    NAME_FIELD_NUMBER: _ClassVar[int]
    SINK_TASK_FIELD_NUMBER: _ClassVar[int]
    SINK_PORT_FIELD_NUMBER: _ClassVar[int]
    name: str
    sink_task: str
    sink_port: str
    def __init__(self, name: _Optional[str] = ..., sink_task: _Optional[str] = ..., sink_port: _Optional[str] = ...) -> None: ...

class RerouteLinkResponse(_message.Message):
    __slots__ = ("link",)
    LINK_FIELD_NUMBER: _ClassVar[int]
    link: LinkInfo
    def __init__(self, link: _Optional[_Union[LinkInfo, _Mapping]] = ...) -> None: ...

class DisconnectPortsResponse(_message.Message):
    __slots__ = ("disconnected", "undelivered")
    DISCONNECTED_FIELD_NUMBER: _ClassVar[int]
    UNDELIVERED_FIELD_NUMBER: _ClassVar[int]
    disconnected: bool
    undelivered: int
    def __init__(self, disconnected: _Optional[bool] = ..., undelivered: _Optional[int] = ...) -> None: ...
