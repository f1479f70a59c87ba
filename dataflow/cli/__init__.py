"""The data-flow side of the ``scart`` command line: its verbs, one module each in
:mod:`dataflow.cli.verbs` (found through the ``scart.verbs`` entry points, as ros2cli
finds its verbs; see :mod:`scart.cli`), and running a verb connected
(:mod:`dataflow.cli.connected`). Their output, options and typed values are the ones every
verb shares, the SCA verbs too (:mod:`scart_wire.console`); the servers, files and
options some of them use are libraries of their own (:mod:`dataflow.foxglove`,
:mod:`dataflow.recording`, :mod:`dataflow.launch`), which never import this package.
Nothing here imports ``scart``."""
