"""What a process holding ports is told about the middlewares it speaks, on its command
line or a composite's launch: the ROS options and launch-time parameters of its ROS node
(:mod:`dataflow.launch.ros`), its YARP name server (:mod:`dataflow.launch.yarp`) and its
Zenoh session (:mod:`dataflow.launch.zenoh`), each applied to the process's transports;
and the one-shot calls made with the same settings (a ROS service, a YARP RPC port).

``scart deploy`` and ``scart call`` (the command line) and ``scart run``'s data-flow launch
provider (:mod:`scart.bindings.dataflow.launch`) use it; nothing here imports the command
line, and no transport is loaded until an option names it."""
