"""scart's own extensions, each a package found through the ``scart.extensions`` entry
points exactly as a third-party one would be (see :mod:`scart.extensions`):

* :mod:`scart.bindings.grpc` — ``binding.grpc``: SCA services and references over gRPC;
* :mod:`scart.bindings.dataflow` — ``implementation.task``, ``<scart:connect>`` and
  ``binding.dataflow``: data-flow tasks inside a composite, and SCA wired to ports.

They talk to the runtime only through :mod:`scart.spi`; the core never imports them.
"""
