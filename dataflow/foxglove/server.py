"""The Foxglove server: every data-flow output port, live, in the Foxglove app (what ``scart
foxglove`` and ``scart run --foxglove`` serve).

It serves the Foxglove WebSocket protocol (with the ``foxglove-sdk`` package) on loopback
(``--host``/``--port``; default port 8765, 0 for a free one): each output port of every
task the name service lists becomes a channel ``task.port`` (JSON messages, a JSON Schema
generated from the port's type: pydantic models describe themselves), fed by a ``data``
subscription (a type this process does not know gets the schema of its first sample's
shape); tasks that appear later are added every ``--refresh`` s. Task properties
are Foxglove *parameters* named ``task.property``. The address to open in the app
(``ws://HOST:PORT``) is printed on stdout.

Security (the protocol carries no credentials, so the server decides alone):

- **Handshake**: the SDK's server listens on a loopback port of its own, behind a gate
  (:mod:`dataflow.foxglove.gate`) that admits a WebSocket only with a loopback ``Host``
  and either no ``Origin`` (a program) or one of the Foxglove app's
  (:data:`~dataflow.foxglove.gate.FOXGLOVE_ORIGINS`): no other web page can connect.
- **Only the gate reaches the SDK's server**: a socket filter on its listening socket
  drops every connection but the gate's own (:mod:`dataflow.foxglove.inner_guard`, which says
  why: the SDK takes no Unix socket and checks no peer, and every local user can read the
  address it listens on).
- **Tokens**: the printed URL carries a token made for this launch (``ws://HOST:PORT/
  ?token=...``); with an auth file (``--auth-file``, the runtime's), any token of it is
  accepted too, and a connection without one is refused (reading needs ``read``, as at
  every door). Without an auth file, tokenless connections (any local program) are
  admitted read-only but counted apart and bounded, so a token holder always gets in;
  a connection must send its request within 2 s.
- **Read-only by default**, whatever token this process holds: parameters can be read,
  a ``setParameters`` is refused, and no service is offered. ``--foxglove-control``
  (``scart foxglove --control``) makes it writable: parameters can be set and task
  operations are Foxglove *services* named ``task.operation`` (JSON: the request is an
  object of the arguments by name, or a list of them in order; the response is
  ``{"result": ...}``). Writes then act with a token given for that purpose (a file
  holding a token of the ``operate`` role, never this process's own token; its role is
  checked against the auth file where it is known, else asked of the name service, and
  ``admin`` is refused either way), and only on loopback.
- **Refusals** (by the task: a bound, a type; by the deployer: the role; read-only) come
  back as the protocol's failures: a service call's ``serviceCallFailure`` with the
  reason; a parameter's ``status`` message (level error) with the reason, the value
  answered being the one the task kept.
- **Bounds**: at most :data:`MAX_PARAMETER_NAMES` names per ``getParameters`` or
  ``setParameters`` (more: refused whole), :data:`MAX_REQUEST_BYTES` per service request.
- A routable ``--host`` needs ``--insecure`` and is logged as a warning; control is
  never offered there.

:class:`FoxgloveLive` is the server; :func:`control_token` reads and checks the token its
writes act with. Both the ``scart foxglove`` verb and ``scart run --foxglove`` (the
data-flow extension's launch provider) use them; this package imports no command line.
"""

from __future__ import annotations

import json
import logging
import threading
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import foxglove
    from foxglove.websocket import (
        Capability, ChannelView, Client, ClientChannel, PlaybackControlRequest, ServiceRequest, WebSocketServer)
    from pydantic import JsonValue

    from dataflow.foxglove.gate import WebSocketGate
    from dataflow.foxglove.inner_guard import InnerGuard
    from dataflow.introspection import OperationDescription
    from dataflow.remote import SampleEvent, Subscription, System
    from scart_wire.security import Security

from dataflow.threads import OwnedThread
from scart_wire.jsonschema import message_of, message_schema, schema_name, type_schema

__all__ = ["FoxgloveLive", "control_token"]

log = logging.getLogger("scart.foxglove")
MAX_CHANNELS = 512
MAX_SERVICES = 1024
MAX_REQUEST_BYTES = 64 * 1024  # a service call's JSON payload
MAX_PARAMETER_NAMES = 64  #: names in one getParameters / setParameters message, at most
CALL_TIMEOUT = 10.0  # s, a service call's operation
READ_ONLY = ("this Foxglove server is read-only: start it with --foxglove-control (scart run) or --control "
             "(scart foxglove) and an operate token for it")


class _Bridge:
    """Channels and subscriptions of the ports seen so far; the server's listener (every
    method of the SDK's ``ServerListener``). ``control``: the system writes go through
    (None: read-only)."""

    def __init__(self, system: System, context: foxglove.Context, control: System | None = None) -> None:
        self.system = system
        self.control = control
        self.context = context
        self.server: WebSocketServer | None = None  # set once listening: refusals are published through it
        self.channels: dict[str, foxglove.Channel | None] = {}
        self.services: dict[str, foxglove.Service] = {}  # name → foxglove.Service, once made
        self.subs: list[Subscription] = []
        self._lock = threading.Condition()  # notified when a channel is made from its first sample

    def refresh(self) -> list[foxglove.Service]:
        """A channel and a subscription for every output port not bridged yet; the services
        of operations not seen before (returned, for a running server to add)."""
        from dataflow import ConnPolicy, registry

        new_services: list[foxglove.Service] = []
        for task in self.system.component_names():
            try:
                proxy = self.system.component(task)
                description = proxy.describe()
            except Exception as exc:  # noqa: BLE001 - a task gone meanwhile: the next refresh
                log.info("task %s: %s", task, exc)
                continue
            for op in description.operations if self.control is not None else ():
                name = f"{task}.{op.name}"
                if name not in self.services and len(self.services) < MAX_SERVICES:
                    self.services[name] = self._service(name, task, op)
                    new_services.append(self.services[name])
            for port in (p for p in description.ports if p.direction == "out"):
                topic = f"{task}.{port.name}"
                with self._lock:
                    if topic in self.channels or len(self.channels) >= MAX_CHANNELS:
                        continue
                    self.channels[topic] = None  # made with its schema: now if the type is known here,
                    if registry.python_type(port.type_name) is not None:  # else from the first sample
                        self.channels[topic] = self._channel(topic, port.type_name, message_schema(port.type_name))

                def observer(event: SampleEvent, topic: str = topic, type_name: str = port.type_name) -> None:
                    data = message_of(event.value)
                    channel = self.channels.get(topic)
                    if channel is None:
                        with self._lock:
                            channel = self.channels.get(topic)
                            if channel is None:
                                channel = self.channels[topic] = self._channel(
                                    topic, type_name, {"title": type_name, **schema_of_sample(data)})
                                self._lock.notify_all()
                    channel.log(json.dumps(data).encode(), log_time=int(event.source_time * 1e9))

                self.subs.append(proxy.subscribe(port.name, observer, policy=ConnPolicy.data()))
        return new_services

    def wait_for_channels(self, timeout: float) -> None:
        """Until every port has its channel (types unknown here get theirs with their first sample)."""
        with self._lock:
            self._lock.wait_for(lambda: None not in self.channels.values(), timeout)

    def _channel(self, topic: str, type_name: str, schema: dict[str, JsonValue]) -> foxglove.Channel:
        import foxglove

        return foxglove.Channel(topic, schema=foxglove.Schema(name=schema_name(type_name), encoding="jsonschema",
                                                              data=json.dumps(schema).encode()),
                                message_encoding="json", context=self.context)

    def _service(self, name: str, task: str, op: OperationDescription) -> foxglove.Service:
        """The Foxglove service calling operation ``op`` of ``task``."""
        import foxglove
        from foxglove.websocket import MessageSchema, Service, ServiceSchema

        from dataflow import registry

        control = self.control
        assert control is not None  # services are made for a writable server only
        params = [p for p, _ in op.params]
        request: dict[str, JsonValue] = {"title": f"{name} request", "type": "object", "required": [*params],
                   "properties": {p: type_schema(t) for p, t in op.params}}
        response: dict[str, JsonValue] = {"title": f"{name} response", "type": "object",
                                          "properties": {"result": type_schema(op.returns)}}

        def schema(title: str, body: dict[str, JsonValue]) -> MessageSchema:
            return MessageSchema(encoding="json", schema=foxglove.Schema(
                name=title, encoding="jsonschema", data=json.dumps(body).encode()))

        def handler(call: ServiceRequest) -> bytes:
            args = _call_arguments(name, params, call.payload)
            result = control.component(task).call_json(op.name, args, timeout=CALL_TIMEOUT)
            return json.dumps({"result": registry.to_jsonable(result)}).encode()

        return Service(name, schema=ServiceSchema(name, request=schema(f"{name} request", request),
                                                  response=schema(f"{name} response", response)), handler=handler)

    # --- foxglove.ServerListener ------------------------------------------------------------

    def on_get_parameters(self, client: Client | None, param_names: list[str],
                          request_id: str | None = None) -> list[foxglove.Parameter]:
        """Task properties as parameters (all of them when none are named; more than
        :data:`MAX_PARAMETER_NAMES` names: refused, none answered)."""
        import foxglove

        from dataflow import registry

        if len(param_names) > MAX_PARAMETER_NAMES:
            self._refused(f"getParameters with {len(param_names)} names refused: at most {MAX_PARAMETER_NAMES}")
            return []
        out = []
        wanted = set(param_names)
        tasks = {name.rpartition(".")[0] for name in wanted}  # only the tasks asked about
        for task in self.system.component_names():
            if wanted and task not in tasks:
                continue
            try:
                props = self.system.component(task).properties()
            except Exception:  # noqa: BLE001 - a task gone meanwhile
                continue
            for name, prop in props.items():
                full = f"{task}.{name}"
                if not wanted or full in wanted:
                    out.append(foxglove.Parameter(full, value=_parameter_value(registry.to_jsonable(prop.value))))
        return out

    def on_set_parameters(self, client: Client, parameters: list[foxglove.Parameter],
                          request_id: str | None = None) -> list[foxglove.Parameter]:
        """Set task properties through ``control``; each refusal (read-only, the role, the
        task's bounds or type) is published as an error status with its reason, and the
        answer carries the values the tasks kept."""
        names = [p.name for p in parameters]
        if len(parameters) > MAX_PARAMETER_NAMES:
            self._refused(f"setParameters with {len(parameters)} names refused: at most {MAX_PARAMETER_NAMES}")
            return []
        if self.control is None:
            self._refused(f"set {', '.join(names)[:200]} refused: {READ_ONLY}")
            return self.on_get_parameters(client, names, request_id)
        refusals = []
        for parameter in parameters:
            task, dot, name = parameter.name.rpartition(".")
            try:
                if not dot:
                    raise ValueError("a parameter is named TASK.PROPERTY")
                self.control.component(task).set_property_json(name, parameter.get_value())
            except Exception as exc:  # noqa: BLE001 - refused (role, bounds, type): said to the client
                refusals.append(f"set {parameter.name[:120]} refused: {exc}")
        if refusals:
            self._refused("; ".join(refusals[:8]) + (f"; and {len(refusals) - 8} more" if len(refusals) > 8 else ""))
        return self.on_get_parameters(client, names, request_id)

    def _refused(self, message: str) -> None:
        """Tell the clients (the protocol's ``status``, level error) and log it once."""
        import foxglove

        log.warning("foxglove: %s", message)
        if self.server is not None:
            self.server.publish_status(message[:1000], foxglove.StatusLevel.Error)

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        """Nothing to do: every port is subscribed already."""

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        """Nothing to do (the port's subscription serves the other clients too)."""

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        """Clients may not publish (the capability is not offered)."""

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        """Clients may not publish."""

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        """Clients may not publish: ignored."""

    def on_parameters_subscribe(self, param_names: list[str]) -> None:
        """Parameter updates are not pushed: the app asks again."""

    def on_parameters_unsubscribe(self, param_names: list[str]) -> None:
        """Parameter updates are not pushed."""

    def on_connection_graph_subscribe(self) -> None:
        """No connection graph (the capability is not offered)."""

    def on_connection_graph_unsubscribe(self) -> None:
        """No connection graph."""

    def on_playback_control_request(self, playback_control_request: PlaybackControlRequest) -> None:
        """No playback (a live view)."""

    def close(self) -> None:
        for sub in self.subs:
            sub.close()
        for channel in self.channels.values():
            if channel is not None:
                channel.close()


def _call_arguments(name: str, params: list[str], payload: bytes) -> list[object]:
    """A service request's arguments in order: a JSON object by parameter name, or a list
    (an empty payload: no arguments). Bounded in bytes; refusals name the service."""
    if len(payload) > MAX_REQUEST_BYTES:
        raise ValueError(f"{name}: request of {len(payload)} bytes; at most {MAX_REQUEST_BYTES}")
    try:
        body = json.loads(payload) if payload.strip() else {}
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{name}: the request is not JSON: {exc}") from None
    if isinstance(body, list):
        return body
    if not isinstance(body, dict):
        raise ValueError(f"{name}: the request must be a JSON object of the arguments {params} (or a list)")
    unknown = sorted(set(body) - set(params))
    missing = [p for p in params if p not in body]
    if unknown or missing:
        raise ValueError(f"{name} takes {params}" + (f"; unknown {unknown}" if unknown else "")
                         + (f"; missing {missing}" if missing else ""))
    return [body[p] for p in params]


def schema_of_sample(data: object, depth: int = 0) -> dict[str, JsonValue]:
    """A JSON Schema describing a JSON value (for a type this process does not know: the
    first sample shows its shape), bounded in depth."""
    if depth > 16:
        return {}
    if isinstance(data, bool):
        return {"type": "boolean"}
    if isinstance(data, int):
        return {"type": "integer"}
    if isinstance(data, float):
        return {"type": "number"}
    if isinstance(data, str):
        return {"type": "string"}
    if isinstance(data, list):
        return {"type": "array", "items": schema_of_sample(data[0], depth + 1) if data else {}}
    if isinstance(data, dict):
        return {"type": "object", "properties": {str(k): schema_of_sample(v, depth + 1) for k, v in data.items()}}
    return {}


def _parameter_value(value: object) -> Any:  # Any: a list may hold None, which the SDK's alias leaves out
    """What a Foxglove parameter holds: bool, float, str, list, dict (ints become floats)."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, list):
        return [_parameter_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _parameter_value(v) for k, v in value.items()}
    return str(value)


class FoxgloveLive:
    """A Foxglove WebSocket server showing the data-flow ``system`` (a name-service client):
    channels, parameters and services as the module says, looked for again every
    ``refresh`` s on a thread of its own. ``start()`` then ``stop()``; ``url`` once started.

    ``control``: a system connected with the token writes act with (see
    :func:`control_token`); None: read-only. A routable ``host`` needs ``insecure_host``
    (the protocol has no authentication; logged as a warning) and is never writable.
    ``stop()`` closes ``control``, and ``system`` too with ``owns_system``. Raises
    ``ValueError`` for a routable host refused."""

    def __init__(self, system: System, host: str = "127.0.0.1", port: int = 8765, refresh: float = 2.0,
                 insecure_host: bool = False, owns_system: bool = False, control: System | None = None,
                 auth_file: str | None = None) -> None:
        from scart_wire.security import is_loopback

        if not is_loopback(host):
            if not insecure_host:
                raise ValueError(f"host {host} is routable and the Foxglove protocol has no authentication "
                                 "(allow it with --insecure; it is then read-only)")
            if control is not None:
                raise ValueError(f"host {host} is routable: a writable Foxglove server (--foxglove-control) is for "
                                 "loopback only, the protocol carries no credentials")
            log.warning("foxglove: serving on %s (--insecure): anyone who reaches it sees every port and property "
                        "(the Foxglove protocol has no authentication)", host)
        import secrets

        from scart_wire.security import AuthTable

        self.host, self.port, self.refresh_period = host, port, refresh
        self._system, self._owns_system, self._control = system, owns_system, control
        self._table = AuthTable.load(auth_file) if auth_file else None  # raises naming the file
        self._seat = secrets.token_urlsafe(24)  # this launch's own token: the printed URL carries it
        self._bridge: _Bridge | None = None
        self._server: WebSocketServer | None = None
        self._gate: WebSocketGate | None = None
        self._guard: InnerGuard | None = None
        self._thread = OwnedThread(self._refreshing, "scart-foxglove-refresh")

    @property
    def address(self) -> str:
        """``ws://HOST:PORT`` once started (no token)."""
        return f"ws://{self.host}:{self._gate.port}" if self._gate is not None else ""

    @property
    def url(self) -> str:
        """What to open in the Foxglove app: the address with this launch's token."""
        return f"{self.address}/?token={self._seat}" if self._gate is not None else ""

    def accepts(self, token: str) -> bool:
        """Whether a connection presenting ``token`` is a token holder: this launch's own,
        or one of the auth file (any role). Constant time."""
        import hmac

        own = hmac.compare_digest(token.encode(), self._seat.encode())
        return own or (self._table is not None and self._table.role_of(token) is not None)

    @property
    def channels(self) -> int:
        return len(self._bridge.channels) if self._bridge is not None else 0

    @property
    def writable(self) -> bool:
        """True when parameters can be set and services called (``control`` given)."""
        return self._control is not None

    def start(self) -> None:
        """Bridge what runs now (types unknown here wait up to 5 s for a first sample), listen,
        and keep looking for new tasks. Nothing is left running when it raises."""
        import foxglove

        from dataflow.foxglove.gate import WebSocketGate

        self._bridge = bridge = _Bridge(self._system, foxglove.Context(), self._control)
        try:
            services = bridge.refresh()
            bridge.wait_for_channels(5.0)
            capabilities = [foxglove.Capability.Parameters]
            if self._control is not None:
                capabilities.append(foxglove.Capability.Services)
            self._server, self._guard = self._inner_server(bridge, capabilities, services)
            bridge.server = self._server
            self._gate = WebSocketGate(self.host, self.port, self._guard.address, tokens=self.accepts,
                                       tokens_required=self._table is not None, guard=self._guard)
            self._gate.start()
            self._thread.start()
        except BaseException:
            self.stop()
            raise

    @staticmethod
    def _inner_server(bridge: _Bridge, capabilities: list[Capability],
                      services: list[foxglove.Service]) -> tuple[WebSocketServer, InnerGuard]:
        """The SDK's server, behind the gate, and the guard that lets only the gate reach it
        (:mod:`dataflow.foxglove.inner_guard`): on a random address of 127.0.0.0/8 (a web page
        cannot guess it), else 127.0.0.1; a free port. A connection that came before the
        guard: started again elsewhere (3 tries). Raises ``GuardError`` when it cannot be
        kept private."""
        import secrets

        import foxglove

        from dataflow.foxglove.inner_guard import GuardError, InnerGuard

        for attempt in range(3):
            server, host = None, ""
            for host in (f"127.{secrets.randbelow(254) + 1}.{secrets.randbelow(256)}.{secrets.randbelow(254) + 1}",
                         "127.0.0.1"):
                try:
                    server = foxglove.start_server(
                        name="scart", host=host, port=0, context=bridge.context, server_listener=bridge,
                        capabilities=capabilities, supported_encodings=["json"], services=services)
                    break
                except Exception as exc:  # noqa: BLE001 - that address not routed to loopback here: the next one
                    if host == "127.0.0.1":
                        raise
                    log.debug("foxglove: cannot listen on %s (%s); 127.0.0.1 then", host, exc)
            assert server is not None
            guard = InnerGuard((host, server.port))
            try:
                guard.start()
                return server, guard
            except GuardError as exc:
                guard.close()
                server.stop()
                if attempt == 2 or "before its guard" not in str(exc):
                    raise
                log.warning("foxglove: %s; starting it again elsewhere", exc)
        raise AssertionError("unreachable")

    def _refreshing(self, stopping: threading.Event) -> None:
        while not stopping.wait(self.refresh_period):
            try:
                assert self._bridge is not None
                services = self._bridge.refresh()
                if services and self._server is not None:
                    self._server.add_services(services)
            except Exception as exc:  # noqa: BLE001 - the name service away for a while: the next round
                log.warning("foxglove: looking for new tasks failed: %s", exc)

    def stop(self) -> None:
        """Stop looking, stop the gate and the server, end the subscriptions (idempotent)."""
        self._thread.stop(timeout=30)
        if self._gate is not None:
            self._gate.stop()
            self._gate = None
        if self._server is not None:
            self._server.stop()
            self._server = None
        if self._guard is not None:
            self._guard.close()
            self._guard = None
        if self._bridge is not None:
            self._bridge.close()  # subscriptions end even when the server could not start
            self._bridge = None
        if self._control is not None:
            control, self._control = self._control, None
            control.close()
        if self._owns_system:
            self._owns_system = False
            self._system.close()


def control_token(token_file: str | None, security: Security, flag: str, ns: str | None = None) -> str | None:
    """The token a writable Foxglove server acts with: the first line of ``token_file``
    (None without one). Where ``security`` names the auth file (the runtime checks tokens),
    a token is needed and must be of the ``operate`` role. Where it does not, the name
    service at ``ns`` is asked whether the token holds the ``admin`` role (a call only
    ``admin`` may make, harmless: a lease nobody holds): an ``admin`` token is refused
    either way, and one the name service does not accept too. It may never be
    ``security``'s own token (the runtime's, perhaps admin). Raises ``ValueError`` saying,
    with ``flag``, what to give (never the token)."""
    import hmac

    from scart_wire.security import Role, read_token_file

    token = read_token_file(token_file) if token_file else None
    table = security.auth_table() if security.auth_file else None
    if table is not None:
        if token is None:
            raise ValueError(f"{flag} needs TOKEN_FILE, a file holding a token of the 'operate' role: the "
                             "deployer checks tokens (--auth-file)")
        role = table.role_of(token)
        if role is None:
            raise ValueError(f"{flag} {token_file}: that token is not in the auth file {security.auth_file}")
        if role is not Role.OPERATE:
            raise ValueError(f"{flag} {token_file}: that token has the '{role.label}' role; give one of the "
                             "'operate' role made for Foxglove")
    if token is not None and security.token and hmac.compare_digest(token.encode(), security.token.encode()):
        raise ValueError(f"{flag} {token_file}: that is this process's own token; give one made for Foxglove "
                         "(of the 'operate' role)")
    if token is not None and table is None and ns is not None:
        _refuse_admin(ns, token, token_file or "", security, flag)
    return token


def _refuse_admin(ns: str, token: str, token_file: str, security: Security, flag: str) -> None:
    """Raise ``ValueError`` when the name service at ``ns`` grants ``token`` the ``admin``
    role, or does not accept it; nothing when it refuses it ``admin`` (or checks no
    token at all: then no token has a role)."""
    import dataclasses

    from dataflow.remote.naming import NameClient
    from scart_wire.errors import AuthenticationError, PermissionDeniedError, RemoteError, RemoteNotFoundError

    def admitted(with_token: str | None) -> bool:
        names = NameClient(ns, timeout=3.0, security=dataclasses.replace(security, token=with_token))
        try:
            names.heartbeat("scart-foxglove-role-probe")  # admin only; a lease nobody holds: changes nothing
            return True
        except RemoteNotFoundError:
            return True  # let in, and told the lease is unknown
        except (PermissionDeniedError, AuthenticationError):
            return False
        except RemoteError as exc:
            raise ValueError(f"{flag}: cannot ask the name service at {ns} the role of {token_file}: {exc}") from None
        finally:
            names.close()

    if not admitted(token):
        names = NameClient(ns, timeout=3.0, security=dataclasses.replace(security, token=token))
        try:
            names.entries()  # read: does it accept the token at all?
        except AuthenticationError:
            raise ValueError(f"{flag} {token_file}: the name service at {ns} does not accept that token") from None
        except RemoteError:
            pass  # it accepts it (a role below admin), whatever else it says
        finally:
            names.close()
        return
    if not admitted("scart-no-such-token"):  # it checks tokens, and this one is admin
        raise ValueError(f"{flag} {token_file}: that token has the 'admin' role (the name service at {ns} says); "
                         "give one of the 'operate' role made for Foxglove (--auth-file AUTH lets scart check it "
                         "itself)")
