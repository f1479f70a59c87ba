"""scart_wire: what the SCA world (:mod:`scart`) and the data-flow world (:mod:`dataflow`)
share on the wire. Both build on it; it imports neither.

=====================================  ====================================================
module                                 what it holds
=====================================  ====================================================
:mod:`scart_wire.errors`               the error tree both worlds raise and catch
:mod:`scart_wire.types`                the type registry (a type name <-> a Python type)
:mod:`scart_wire.codec`                the one codec between values and ``Value`` messages
:mod:`scart_wire.bounds`               declared bounds of ports, properties and arguments
:mod:`scart_wire.proto`                the code protoc makes of the top-level ``proto/``
:mod:`scart_wire.security`             tokens, roles, TLS settings (:class:`Security`)
:mod:`scart_wire.rpc`                  gRPC plumbing: options, servers, status mapping
:mod:`scart_wire.defaults`             the name service's default address, lease...
=====================================  ====================================================

Importing this package imports nothing else (no protobuf, no gRPC): ``import scart``
reads its settings from :mod:`scart_wire.security` and :mod:`scart_wire.defaults` alone.
"""
