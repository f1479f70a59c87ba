"""ROS 2 services as rmw_cyclonedds carries them: two topics and a request header.

A client writes ``rq/<service>Request`` samples of ``pkg::srv::dds_::Name_Request_``: rmw's
request header (``guid``: the instance handle of the client's request writer, uint64;
``seq``: int64, counting from 1) and then the request's fields, in plain CDR. (The IDL
members are named ``guid_`` and ``seq_``: ROS field names never end with ``_``, so they
cannot clash with the request's; rmw announces no XTypes type, so names never reach it.) The server answers on ``rr/<service>Reply`` with ``..._Response_`` carrying
the same header, so that each client keeps the replies whose ``guid`` is its own
and pairs them by sequence number. Both endpoints of a client carry
``clientid=<16 bytes>;`` in their user data (``serviceid=`` for a server); before
replying, a server waits up to 100 ms for the client's reply reader to be matched, as
rmw_cyclonedds does, so the first reply of a new client is not lost.

The QoS is rmw's default for services: reliable, volatile, keep-last 10.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from cyclonedds.core import DDSException, InstanceState, ReadCondition, SampleState, ViewState
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy
from cyclonedds.sub import DataReader

from .errors import ConversionError, Ros2Error
from .qos import QoS
from .msgs import MessageTypes

if TYPE_CHECKING:
    from .endpoints import Dispatcher

__all__ = ["ServiceServer", "ServiceClient", "SERVICE_QOS"]

LOG = logging.getLogger("scart_ros2")
SERVICE_QOS = QoS.buffer(10)  # rmw_qos_profile_services_default
_ANY = SampleState.Any | ViewState.Any | InstanceState.Any
_REPLY_WAIT = 0.1  # s, as rmw_cyclonedds' rmw_send_response
_BATCH = 256


def _user_data_value(endpoint: Any, key: str) -> str | None:
    """``value`` of ``key=value;`` in a discovered endpoint's user data, if any."""
    policy = endpoint.qos[Policy.Userdata] if endpoint is not None and endpoint.qos is not None else None
    if policy is None:
        return None
    for item in bytes(policy.data).decode("utf-8", "replace").split(";"):
        name, _, value = item.partition("=")
        if name == key:
            return value
    return None


class _Endpoint:
    """A reader and writer pair drained on the dispatcher thread."""

    def __init__(self, reader: DataReader, writer: DataWriter, types: MessageTypes, srv_type: str,
                 dispatcher: Dispatcher) -> None:
        self.srv_type = srv_type
        self.request_type, self.response_type = types.service(srv_type)
        self._reader, self._writer, self._types = reader, writer, types
        self._dispatcher = dispatcher
        self._condition = ReadCondition(reader, _ANY)
        self._closed = False
        self.closed_hook: Callable[[], None] | None = None  # the participant's (node graph)
        self.refused = 0
        self.last_refusal: str | None = None

    def _take(self) -> list[Any]:  # instances of the request's or reply's IDL class, made at run time
        """Valid samples taken now (a malformed one is counted and skipped)."""
        out: list[object] = []
        for _ in range(_BATCH):
            try:
                taken = self._reader.take(N=1, condition=self._condition)
            except DDSException:
                break
            except Exception as exc:  # bytes cyclonedds cannot deserialise
                self._refuse(f"malformed sample: {exc}")
                continue
            if not taken:
                break
            if taken[0].sample_info.valid_data:
                out.append(taken[0])
        return out

    def _refuse(self, why: str) -> None:
        self.refused += 1
        self.last_refusal = why

    def _body(self, sample: object, name: str) -> object:
        return self._types.from_idl(name, sample)

    def close(self) -> None:
        """Stop and delete both endpoints. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._dispatcher.retire(self._condition, self.closed_hook, self._reader, self._writer)


class ServiceServer(_Endpoint):
    """Answers one ROS 2 service with ``handler(request) -> response`` (made by
    ``Participant.service``); the handler runs on the participant's thread. A handler
    that raises, or a response that cannot be converted, sends no reply (ROS 2 has no
    error reply) and is counted in ``refused``."""

    def __init__(self, reader: DataReader, writer: DataWriter, types: MessageTypes, srv_type: str,
                 handler: Callable[[Any], object], dispatcher: Dispatcher, raw: bool = False) -> None:
        super().__init__(reader, writer, types, srv_type, dispatcher)
        self._handler = handler
        self._raw = raw
        self._reply_type = types.service_idl_type(self.response_type)
        self.answered = 0
        dispatcher.add(self._condition, self._drain)

    def _drain(self) -> None:
        for sample in self._take():
            if self._closed:
                return
            try:
                response = self._handler(sample if self._raw else self._body(sample, self.request_type))
                fields = self._types.to_fields(self.response_type, response)
            except Exception as exc:  # the handler's or the conversion's: no reply
                self._refuse(f"{self.srv_type}: {exc}")
                continue
            if self._client_ready(sample.sample_info.publication_handle):
                # the struct's fields are made at run time: IdlStruct's own __init__ knows none
                reply = self._reply_type(guid_=sample.guid_, seq_=sample.seq_, **fields)  # type: ignore[call-arg]  # ^
                self._writer.write(reply)
                self.answered += 1

    def _client_ready(self, request_writer: int) -> bool:
        """Whether the requesting client's reply reader is matched (waits up to 100 ms)."""
        deadline = time.monotonic() + _REPLY_WAIT
        while True:
            try:
                client = self._reader.get_matched_publication_data(request_writer)
                clientid = _user_data_value(client, "clientid") if client is not None else None
                if client is None:
                    return False  # the client is gone
                if clientid is None:
                    return True  # a client without an id: assume all is well (as rmw)
                for handle in self._writer.get_matched_subscriptions():
                    if _user_data_value(self._writer.get_matched_subscription_data(handle), "clientid") == clientid:
                        return True
            except DDSException:
                return False
            if time.monotonic() >= deadline:
                self._refuse(f"{self.srv_type}: the client's reply reader was not matched within 100 ms")
                return False
            time.sleep(0.01)


class ServiceClient(_Endpoint):
    """Calls one ROS 2 service (made by ``Participant.client``). Thread-safe."""

    def __init__(self, reader: DataReader, writer: DataWriter, types: MessageTypes, srv_type: str,
                 dispatcher: Dispatcher) -> None:
        super().__init__(reader, writer, types, srv_type, dispatcher)
        self._request_type = types.service_idl_type(self.request_type)
        self._guid = writer.get_instance_handle() & 0xFFFF_FFFF_FFFF_FFFF  # ctypes gives it signed
        self._numbers = itertools.count(1)
        self._pending: dict[int, Future] = {}
        self._lock = threading.Lock()
        dispatcher.add(self._condition, self._drain)

    def service_ready(self) -> bool:
        """Whether a server is matched both ways (request reader and reply writer)."""
        try:
            return bool(self._writer.get_matched_subscriptions()) and bool(self._reader.get_matched_publications())
        except DDSException:
            return False

    def wait_for_service(self, timeout: float) -> bool:
        """Block until :meth:`service_ready` or ``timeout`` s; returns which."""
        deadline = time.monotonic() + timeout
        while not self.service_ready():
            if self._closed or time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    def call_async(self, request: object) -> Future:
        """Send ``request`` (rosbags message or mapping); the future gets the response
        (a rosbags message). Raises :class:`ConversionError` for a bad request and
        :class:`Ros2Error` once closed."""
        fields = self._types.to_fields(self.request_type, request)
        future: Future = Future()
        with self._lock:
            if self._closed:
                raise Ros2Error(f"the client of {self.srv_type} is closed")
            number = next(self._numbers)
            self._pending[number] = future
        try:
            # the struct's fields are made at run time: IdlStruct's own __init__ knows none
            request = self._request_type(guid_=self._guid, seq_=number, **fields)  # type: ignore[call-arg]  # ^
            self._writer.write(request)
        except Exception as exc:
            with self._lock:
                self._pending.pop(number, None)
            raise ConversionError(f"{self.srv_type}: {exc}") from None
        return future

    def call(self, request: object, timeout: float = 5.0) -> object:
        """Send ``request`` and block for the response up to ``timeout`` s; raises
        ``TimeoutError`` (the late reply is then dropped) or as :meth:`call_async`."""
        future = self.call_async(request)
        try:
            return future.result(timeout)
        except FutureTimeout:
            with self._lock:
                for number, pending in list(self._pending.items()):
                    if pending is future:
                        del self._pending[number]
            raise TimeoutError(f"no reply from {self.srv_type} within {timeout} s") from None

    def _drain(self) -> None:
        for sample in self._take():
            if sample.guid_ != self._guid:
                continue  # another client's reply (every client reads every reply)
            with self._lock:
                future = self._pending.pop(sample.seq_, None)
            if future is None:
                continue  # timed out already
            try:
                future.set_result(self._body(sample, self.response_type))
            except ConversionError as exc:
                self._refuse(str(exc))
                future.set_exception(exc)

    def close(self) -> None:
        """Fail pending calls with :class:`Ros2Error`, delete both endpoints. Idempotent."""
        with self._lock:
            pending, self._pending = self._pending, {}
        super().close()
        for future in pending.values():
            future.set_exception(Ros2Error(f"the client of {self.srv_type} was closed"))

