"""The data-flow verbs of the ``scart`` command line, one module each (ros2cli's
``ros2topic/verb/``): each has ``HELP``, ``add_arguments(parser)`` and ``main(args)``,
is named by a ``scart.verbs`` entry point and imported only when its verb runs (see
:mod:`scart.cli`). They belong to the data-flow side and never import ``scart``; what
they share is :mod:`scart_wire.console` (with the SCA verbs) and
:mod:`dataflow.cli.connected`."""
