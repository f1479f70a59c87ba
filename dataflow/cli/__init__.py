"""The data-flow side of the ``scart`` command line: its verbs, one module each in
:mod:`dataflow.cli.verbs` (found through the ``scart.verbs`` entry points, as ros2cli
finds its verbs; see :mod:`scart.cli`), what they share (:mod:`dataflow.cli.output`:
options, printing, errors, typed values, the name service), and the servers and files
some of them use (:mod:`dataflow.cli.foxglove`, :mod:`dataflow.cli._mcap`). Nothing here
imports ``scart``."""
