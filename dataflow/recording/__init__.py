"""Recording and playing back port samples, a library feature of the data-flow world: MCAP
files read with bounds and the output file (:mod:`dataflow.recording.mcap`), a recording
written from samples by a thread of its own (:mod:`dataflow.recording.recorder`), and the
link that plays large samples (images, clouds) back into an input port beside the control
plane (:mod:`dataflow.recording.playlink`).

The ``record``, ``play`` and ``info`` verbs use it; nothing here imports the command line."""
