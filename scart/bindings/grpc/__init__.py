"""``binding.grpc``: SCA services and references across processes, over gRPC (an extension).

XML (namespace ``urn:scart:1.0``)::

    <service name="Calculator">
      <scart:binding.grpc address="127.0.0.1:50051" timeout="30"/>     <!-- address default 127.0.0.1:0 -->
    </service>
    <reference name="calculator">
      <scart:binding.grpc address="127.0.0.1:50051" service="CalculatorComponent/Calculator" timeout="5"/>
    </reference>

* **Service side** (:class:`~scart.bindings.grpc._binding.GrpcServiceBinding`): exports a component service (or a
  promoted composite service) on ``address``; services of one runtime naming the same
  address share one server (all default ``127.0.0.1:0`` services share one port).
  ``.address`` is the real "host:port". A service answers to "Component/Service",
  "Component" (when it is the component's only service) and its promoted names; a
  server exporting a single service also answers to an empty name. ``timeout`` (s,
  default 30) bounds each wait for a caller's reply to a synchronous callback.
* **Reference side** (:class:`~scart.bindings.grpc._binding.GrpcReferenceBinding`): ``address`` (required),
  ``service`` (optional when the server exports one service), ``timeout`` (s, default
  5): the per-call deadline. Calls use ``wait_for_ready``: a provider that is down when
  called is waited for until the deadline, then :class:`scart.ServiceUnavailableError` names
  the address; the channel (created at start, connecting lazily) reconnects by itself,
  so a provider that comes back later is reached again without restarting the client.
* **Errors** raised by the provider arrive as :class:`scart.RemoteError` (``remote_type``,
  ``remote_message``), a ``scart.InvocationError``.

Callbacks — the client never listens on a port; the calls' own streams carry them back:

* A synchronous call made by a component whose reference has a callback interface uses
  the server-streaming ``Invoke`` RPC: the server streams ``CallbackCall`` s on the
  call's own response stream while the operation runs, the client runs each in the
  calling thread (exactly where a local call would run it) and answers each synchronous
  one, in order, with a unary ``ReplyCallback`` naming the call; then the server sends
  the outcome. (Server streaming plus a unary reply is about 2x cheaper in grpcio than a
  bidirectional stream, whose request iterator costs a thread per call.) Without a
  callback (e.g. ``Runtime.service(...)``), a plain unary ``Call``.
* One-way calls (unary ``Send``) return once the provider has *queued* the work on its
  one-way pool. When the caller has a callback, the reference binding first opens a
  **callback session**: one long-lived ``OpenCallbackSession`` stream per reference
  binding (opened at the first such call, reopened after the provider restarts), over
  which the provider calls back during and after the one-way call. The client runs
  session callbacks in order on the session's reader thread (one-way callback operations
  are queued on the caller's own pool); synchronous ones are answered on the stream.
  ``Invoke`` calls name the session too, so a callback made after a synchronous call
  returned still arrives when a session is open.
* One-way failures on the provider are logged and counted: the runtime's
  ``oneway_failures`` and :attr:`~scart.bindings.grpc._binding.GrpcServiceBinding.oneway_failures`; a one-way call
  the provider refuses (unknown operation, undecodable argument) or cannot be reached
  raises at the caller.
"""

from __future__ import annotations

import re

from scart.spi import (
    Binding, BindingProvider, CheckContext, Host, InterfaceInfo, Problem, ReferenceBinding, ServiceBinding,
    ServiceEndpoint, Side, parse_host_port, port_in_range,
)

__all__ = ["BAD_ATTRIBUTE", "GrpcBinding", "check_attributes"]

BAD_ATTRIBUTE = "SCART-B101"  # a binding.grpc attribute is missing or malformed
_SERVICE = re.compile(r"^[^\s/]+(/[^\s/]+)*$")


class GrpcBinding(BindingProvider):
    """The ``binding.grpc`` provider. Its static check needs no gRPC; the transport
    (grpcio) is imported only when a service or reference side is made."""

    name = "binding.grpc"

    def check(self, model: Binding, interface: InterfaceInfo | None, side: Side,
              context: CheckContext) -> list[Problem]:
        """See :func:`check_attributes`."""
        return check_attributes(model, side)

    def names_endpoint(self, model: Binding) -> bool:
        """A reference's ``address`` (and ``service``) name its endpoint."""
        return "address" in model.attributes or "service" in model.attributes

    def service(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> ServiceBinding:
        """A :class:`~scart.bindings.grpc._binding.GrpcServiceBinding` (listens at start)."""
        from scart.bindings.grpc._binding import GrpcServiceBinding

        return GrpcServiceBinding(model, endpoint, host)

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        """A :class:`~scart.bindings.grpc._binding.GrpcReferenceBinding` (connects lazily)."""
        from scart.bindings.grpc._binding import GrpcReferenceBinding

        return GrpcReferenceBinding(model, interface, host)


def check_attributes(model: Binding, side: Side) -> list[Problem]:
    """Static problems of a ``binding.grpc`` element: ``address`` ("host:port"; required on
    references, where port 0 is refused), ``service`` ("Component/Service", references
    only) and a positive ``timeout``."""
    reference = side == "reference"
    attrs, loc = model.attributes, model.loc
    out: list[str] = []
    address = attrs.get("address")
    if address is None:
        if reference:
            out.append('binding.grpc on a reference needs address="host:port"')
    else:
        parsed = parse_host_port(address)
        if parsed is None:
            out.append(f'binding.grpc: address {address!r} is not "host:port"')
        elif not port_in_range(parsed[1], zero_ok=not reference):
            out.append(f"binding.grpc: address {address!r}: port must be 1..65535" + ("" if reference else " or 0"))
    timeout = attrs.get("timeout")
    if timeout is not None:
        try:
            if not 0 < float(timeout) < 1e6:
                raise ValueError
        except ValueError:
            out.append(f"binding.grpc: timeout {timeout!r} must be a positive number of seconds")
    service = attrs.get("service")
    if service is not None:
        if not reference:
            out.append("binding.grpc: 'service' is an attribute of references only")
        elif not _SERVICE.match(service):
            out.append(f'binding.grpc: service {service!r} is not "Component/Service"')
    return [Problem(BAD_ATTRIBUTE, text, loc.path, loc.line) for text in out]
