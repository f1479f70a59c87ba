"""Recording and playing back port samples, a library feature of the data-flow world: MCAP
files read with bounds and written as ``scart record`` writes them
(:mod:`dataflow.recording.mcap`), and the link that plays large samples (images, clouds)
back into an input port beside the control plane (:mod:`dataflow.recording.playlink`).

The ``record``, ``play`` and ``info`` verbs use it; nothing here imports the command line."""
