"""The SCA verbs of the ``scart`` command line, one module each: ``run``, ``validate``,
``graph`` (composites) and ``services``, ``call`` (SCA services, found through the name
service or ``--at``). The data-flow verbs are :mod:`dataflow.cli.verbs`; every verb is
found through the ``scart.verbs`` entry points (see :mod:`scart.cli`). The verbs of both
worlds share one output module, :mod:`scart_wire.console`; none of these imports
:mod:`dataflow.cli`."""
