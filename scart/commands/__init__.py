"""The verbs of the ``scart`` command line, one module per group (see ``scart.cli``)."""
