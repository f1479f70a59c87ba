"""The SCA verbs of the ``scart`` command line (:mod:`scart.commands.run`); other groups
come from the ``scart.commands`` entry points (see :mod:`scart.cli`)."""
