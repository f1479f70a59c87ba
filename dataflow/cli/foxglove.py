"""``scart foxglove``: every data-flow output port, live, in the Foxglove app.

It serves the Foxglove WebSocket protocol (with the ``foxglove-sdk`` package) on loopback
(``--host``/``--port``; default port 8765, 0 for a free one): each output port of every
task the name service lists becomes a channel ``task.port`` (JSON messages, a JSON Schema
generated from the port's type: pydantic models describe themselves), fed by a ``data``
subscription (a type this process does not know gets the schema of its first sample's
shape); tasks that appear later are added every ``--refresh`` s. Task properties
are Foxglove *parameters* named ``task.property``: read, and set — the set goes through
this command's token, so it needs the ``operate`` role where the deployer checks tokens.
The address to open in the app (``ws://HOST:PORT``) is printed on stdout.
"""

from __future__ import annotations

import argparse
import json
import logging
import threading
from typing import Any

from dataflow.cli.record import _schema_of

__all__ = ["cmd_foxglove"]

log = logging.getLogger("scart.foxglove")
MAX_CHANNELS = 512


class _Bridge:
    """Channels and subscriptions of the ports seen so far; the server's listener."""

    def __init__(self, system: Any, context: Any) -> None:
        self.system = system
        self.context = context
        self.channels: dict[str, Any] = {}
        self.subs: list[Any] = []
        self._lock = threading.Condition()  # notified when a channel is made from its first sample

    def refresh(self) -> None:
        """A channel and a subscription for every output port not bridged yet."""
        from dataflow import ConnPolicy, registry

        for task in self.system.component_names():
            try:
                proxy = self.system.component(task)
                ports = [p for p in proxy.describe().ports if p.direction == "out"]
            except Exception as exc:  # noqa: BLE001 - a task gone meanwhile: the next refresh
                log.info("task %s: %s", task, exc)
                continue
            for port in ports:
                topic = f"{task}.{port.name}"
                with self._lock:
                    if topic in self.channels or len(self.channels) >= MAX_CHANNELS:
                        continue
                    self.channels[topic] = None  # made with its schema: now if the type is known here,
                    if registry.python_type(port.type_name) is not None:  # else from the first sample
                        self.channels[topic] = self._channel(topic, port.type_name, _schema_of(port.type_name))

                def observer(event: Any, topic: str = topic, type_name: str = port.type_name) -> None:
                    data = registry.to_jsonable(event.value)
                    data = data if isinstance(data, dict) else {"value": data}
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

    def wait_for_channels(self, timeout: float) -> None:
        """Until every port has its channel (types unknown here get theirs with their first sample)."""
        with self._lock:
            self._lock.wait_for(lambda: None not in self.channels.values(), timeout)

    def _channel(self, topic: str, type_name: str, schema: dict[str, Any]) -> Any:
        import foxglove

        return foxglove.Channel(topic, schema=foxglove.Schema(name=type_name, encoding="jsonschema",
                                                              data=json.dumps(schema).encode()),
                                message_encoding="json", context=self.context)

    # --- foxglove.ServerListener ------------------------------------------------------------

    def on_get_parameters(self, client: Any, param_names: list[str], request_id: str | None = None) -> list[Any]:
        """Task properties as parameters (all of them when none are named)."""
        import foxglove

        from dataflow import registry

        out = []
        wanted = set(param_names)
        for task in self.system.component_names():
            try:
                props = self.system.component(task).properties()
            except Exception:  # noqa: BLE001 - a task gone meanwhile
                continue
            for name, prop in props.items():
                full = f"{task}.{name}"
                if not wanted or full in wanted:
                    out.append(foxglove.Parameter(full, value=_parameter_value(registry.to_jsonable(prop.value))))
        return out

    def on_set_parameters(self, client: Any, parameters: list[Any], request_id: str | None = None) -> list[Any]:
        """Set task properties (refusals are logged; the answer carries the values as they are)."""
        for parameter in parameters:
            task, dot, name = parameter.name.rpartition(".")
            if not dot:
                continue
            try:
                self.system.component(task).set_property_json(name, parameter.get_value())
            except Exception as exc:  # noqa: BLE001 - refused (role, bounds, type): said in the log
                log.warning("set %s refused: %s", parameter.name, exc)
        return self.on_get_parameters(client, [p.name for p in parameters], request_id)

    def close(self) -> None:
        for sub in self.subs:
            sub.close()
        for channel in self.channels.values():
            if channel is not None:
                channel.close()


def schema_of_sample(data: Any, depth: int = 0) -> dict[str, Any]:
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


def _parameter_value(value: Any) -> Any:
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


def cmd_foxglove(args: argparse.Namespace) -> int:
    """``scart foxglove [--host H] [--port P]``: see the module docstring."""
    import foxglove

    from dataflow.cli.inspect import _err, _wait_until_stopped

    if args.host not in ("127.0.0.1", "localhost", "::1") and not args.insecure_host:
        raise ValueError(f"--host {args.host}: the Foxglove protocol has no authentication; serving a routable "
                         "address needs --insecure-host")
    context = foxglove.Context()
    bridge = _Bridge(args.system, context)
    try:
        bridge.refresh()
        bridge.wait_for_channels(5.0)
        server = foxglove.start_server(name="scart", host=args.host, port=args.port, context=context,
                                       capabilities=[foxglove.Capability.Parameters], server_listener=bridge)
        try:
            print(f"scart: Foxglove at ws://{args.host}:{server.port} ({len(bridge.channels)} channel(s))", flush=True)
            _err(f"foxglove: open ws://{args.host}:{server.port} in the Foxglove app; Ctrl-C to stop")
            stop = threading.Event()
            _wait_until_stopped(stop, args.duration, tick=args.refresh, on_tick=bridge.refresh)
        finally:
            server.stop()
    finally:
        bridge.close()  # subscriptions end even when the server could not start
    return 0
