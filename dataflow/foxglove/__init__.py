"""The Foxglove server, a library feature of the data-flow world: every output port live in
the Foxglove app over the Foxglove WebSocket protocol (:mod:`dataflow.foxglove.server`),
behind a gate that checks each handshake (:mod:`dataflow.foxglove.gate`) and a socket
filter that lets only the gate reach the SDK's server (:mod:`dataflow.foxglove.inner_guard`).

The ``scart foxglove`` verb (:mod:`dataflow.cli.verbs.foxglove`) and ``scart run
--foxglove`` both use it; nothing here imports the command line."""
