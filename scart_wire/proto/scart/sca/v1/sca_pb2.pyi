from scart_wire.proto.scart.dataflow.v1 import value_pb2 as _value_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Invocation(_message.Message):
    __slots__ = ("service", "operation", "args", "kwargs", "session_id", "target_id")
    class KwargsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: _value_pb2.Value
        def __init__(self, key: _Optional[str] = ..., value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ...) -> None: ...
    SERVICE_FIELD_NUMBER: _ClassVar[int]
    OPERATION_FIELD_NUMBER: _ClassVar[int]
    ARGS_FIELD_NUMBER: _ClassVar[int]
    KWARGS_FIELD_NUMBER: _ClassVar[int]
    SESSION_ID_FIELD_NUMBER: _ClassVar[int]
    TARGET_ID_FIELD_NUMBER: _ClassVar[int]
    service: str
    operation: str
    args: _containers.RepeatedCompositeFieldContainer[_value_pb2.Value]
    kwargs: _containers.MessageMap[str, _value_pb2.Value]
    session_id: str
    target_id: int
    def __init__(self, service: _Optional[str] = ..., operation: _Optional[str] = ..., args: _Optional[_Iterable[_Union[_value_pb2.Value, _Mapping]]] = ..., kwargs: _Optional[_Mapping[str, _value_pb2.Value]] = ..., session_id: _Optional[str] = ..., target_id: _Optional[int] = ...) -> None: ...

class Fault(_message.Message):
    __slots__ = ("type", "message", "traceback", "code", "reference")
    TYPE_FIELD_NUMBER: _ClassVar[int]
    MESSAGE_FIELD_NUMBER: _ClassVar[int]
    TRACEBACK_FIELD_NUMBER: _ClassVar[int]
    CODE_FIELD_NUMBER: _ClassVar[int]
    REFERENCE_FIELD_NUMBER: _ClassVar[int]
    type: str
    message: str
    traceback: str
    code: str
    reference: str
    def __init__(self, type: _Optional[str] = ..., message: _Optional[str] = ..., traceback: _Optional[str] = ..., code: _Optional[str] = ..., reference: _Optional[str] = ...) -> None: ...

class Outcome(_message.Message):
    __slots__ = ("value", "fault")
    VALUE_FIELD_NUMBER: _ClassVar[int]
    FAULT_FIELD_NUMBER: _ClassVar[int]
    value: _value_pb2.Value
    fault: Fault
    def __init__(self, value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ..., fault: _Optional[_Union[Fault, _Mapping]] = ...) -> None: ...

class CallbackCall(_message.Message):
    __slots__ = ("id", "operation", "args", "kwargs", "oneway", "target_id")
    class KwargsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: _value_pb2.Value
        def __init__(self, key: _Optional[str] = ..., value: _Optional[_Union[_value_pb2.Value, _Mapping]] = ...) -> None: ...
    ID_FIELD_NUMBER: _ClassVar[int]
    OPERATION_FIELD_NUMBER: _ClassVar[int]
    ARGS_FIELD_NUMBER: _ClassVar[int]
    KWARGS_FIELD_NUMBER: _ClassVar[int]
    ONEWAY_FIELD_NUMBER: _ClassVar[int]
    TARGET_ID_FIELD_NUMBER: _ClassVar[int]
    id: int
    operation: str
    args: _containers.RepeatedCompositeFieldContainer[_value_pb2.Value]
    kwargs: _containers.MessageMap[str, _value_pb2.Value]
    oneway: bool
    target_id: int
    def __init__(self, id: _Optional[int] = ..., operation: _Optional[str] = ..., args: _Optional[_Iterable[_Union[_value_pb2.Value, _Mapping]]] = ..., kwargs: _Optional[_Mapping[str, _value_pb2.Value]] = ..., oneway: _Optional[bool] = ..., target_id: _Optional[int] = ...) -> None: ...

class CallbackReply(_message.Message):
    __slots__ = ("id", "outcome")
    ID_FIELD_NUMBER: _ClassVar[int]
    OUTCOME_FIELD_NUMBER: _ClassVar[int]
    id: int
    outcome: Outcome
    def __init__(self, id: _Optional[int] = ..., outcome: _Optional[_Union[Outcome, _Mapping]] = ...) -> None: ...

class CallRequest(_message.Message):
    __slots__ = ("invocation",)
    INVOCATION_FIELD_NUMBER: _ClassVar[int]
    invocation: Invocation
    def __init__(self, invocation: _Optional[_Union[Invocation, _Mapping]] = ...) -> None: ...

class CallResponse(_message.Message):
    __slots__ = ("outcome",)
    OUTCOME_FIELD_NUMBER: _ClassVar[int]
    outcome: Outcome
    def __init__(self, outcome: _Optional[_Union[Outcome, _Mapping]] = ...) -> None: ...

class SendRequest(_message.Message):
    __slots__ = ("invocation",)
    INVOCATION_FIELD_NUMBER: _ClassVar[int]
    invocation: Invocation
    def __init__(self, invocation: _Optional[_Union[Invocation, _Mapping]] = ...) -> None: ...

class SendResponse(_message.Message):
    __slots__ = ("fault",)
    FAULT_FIELD_NUMBER: _ClassVar[int]
    fault: Fault
    def __init__(self, fault: _Optional[_Union[Fault, _Mapping]] = ...) -> None: ...

class InvokeRequest(_message.Message):
    __slots__ = ("invocation", "call_id")
    INVOCATION_FIELD_NUMBER: _ClassVar[int]
    CALL_ID_FIELD_NUMBER: _ClassVar[int]
    invocation: Invocation
    call_id: str
    def __init__(self, invocation: _Optional[_Union[Invocation, _Mapping]] = ..., call_id: _Optional[str] = ...) -> None: ...

class InvokeResponse(_message.Message):
    __slots__ = ("callback_call", "outcome")
    CALLBACK_CALL_FIELD_NUMBER: _ClassVar[int]
    OUTCOME_FIELD_NUMBER: _ClassVar[int]
    callback_call: CallbackCall
    outcome: Outcome
    def __init__(self, callback_call: _Optional[_Union[CallbackCall, _Mapping]] = ..., outcome: _Optional[_Union[Outcome, _Mapping]] = ...) -> None: ...

class ReplyCallbackRequest(_message.Message):
    __slots__ = ("call_id", "reply")
    CALL_ID_FIELD_NUMBER: _ClassVar[int]
    REPLY_FIELD_NUMBER: _ClassVar[int]
    call_id: str
    reply: CallbackReply
    def __init__(self, call_id: _Optional[str] = ..., reply: _Optional[_Union[CallbackReply, _Mapping]] = ...) -> None: ...

class ReplyCallbackResponse(_message.Message):
    __slots__ = ("delivered",)
    DELIVERED_FIELD_NUMBER: _ClassVar[int]
    delivered: bool
    def __init__(self, delivered: _Optional[bool] = ...) -> None: ...

class OpenCallbackSessionRequest(_message.Message):
    __slots__ = ("session_id", "callback_reply")
    SESSION_ID_FIELD_NUMBER: _ClassVar[int]
    CALLBACK_REPLY_FIELD_NUMBER: _ClassVar[int]
    session_id: str
    callback_reply: CallbackReply
    def __init__(self, session_id: _Optional[str] = ..., callback_reply: _Optional[_Union[CallbackReply, _Mapping]] = ...) -> None: ...

class OpenCallbackSessionResponse(_message.Message):
    __slots__ = ("opened", "callback_call")
    OPENED_FIELD_NUMBER: _ClassVar[int]
    CALLBACK_CALL_FIELD_NUMBER: _ClassVar[int]
    opened: bool
    callback_call: CallbackCall
    def __init__(self, opened: _Optional[bool] = ..., callback_call: _Optional[_Union[CallbackCall, _Mapping]] = ...) -> None: ...

class ListServicesRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class OperationInfo(_message.Message):
    __slots__ = ("name", "oneway", "returns_value", "params")
    NAME_FIELD_NUMBER: _ClassVar[int]
    ONEWAY_FIELD_NUMBER: _ClassVar[int]
    RETURNS_VALUE_FIELD_NUMBER: _ClassVar[int]
    PARAMS_FIELD_NUMBER: _ClassVar[int]
    name: str
    oneway: bool
    returns_value: bool
    params: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, name: _Optional[str] = ..., oneway: _Optional[bool] = ..., returns_value: _Optional[bool] = ..., params: _Optional[_Iterable[str]] = ...) -> None: ...

class ServiceInfo(_message.Message):
    __slots__ = ("names", "interface", "operations", "callback_interface", "callback_operations")
    NAMES_FIELD_NUMBER: _ClassVar[int]
    INTERFACE_FIELD_NUMBER: _ClassVar[int]
    OPERATIONS_FIELD_NUMBER: _ClassVar[int]
    CALLBACK_INTERFACE_FIELD_NUMBER: _ClassVar[int]
    CALLBACK_OPERATIONS_FIELD_NUMBER: _ClassVar[int]
    names: _containers.RepeatedScalarFieldContainer[str]
    interface: str
    operations: _containers.RepeatedCompositeFieldContainer[OperationInfo]
    callback_interface: str
    callback_operations: _containers.RepeatedCompositeFieldContainer[OperationInfo]
    def __init__(self, names: _Optional[_Iterable[str]] = ..., interface: _Optional[str] = ..., operations: _Optional[_Iterable[_Union[OperationInfo, _Mapping]]] = ..., callback_interface: _Optional[str] = ..., callback_operations: _Optional[_Iterable[_Union[OperationInfo, _Mapping]]] = ...) -> None: ...

class ListServicesResponse(_message.Message):
    __slots__ = ("services",)
    SERVICES_FIELD_NUMBER: _ClassVar[int]
    services: _containers.RepeatedCompositeFieldContainer[ServiceInfo]
    def __init__(self, services: _Optional[_Iterable[_Union[ServiceInfo, _Mapping]]] = ...) -> None: ...
