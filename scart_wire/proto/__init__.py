"""Every wire format of scart: the Python code protoc makes of the ``.proto`` files.

The ``.proto`` files under the checkout's top-level ``proto/`` folder are the single
source of truth, laid out buf style (the folder is the proto package)::

    scart/dataflow/v1/value.proto     Value: one value of any registered type
    scart/dataflow/v1/dataflow.proto  DeployerService: remote access to data-flow tasks
    scart/naming/v1/naming.proto      NamingService: component name -> deployer
    scart/sca/v1/sca.proto            ScaService: binding.grpc

Under this package, at the same relative path, lie each file's ``_pb2.py``, ``_pb2.pyi``
and ``_pb2_grpc.py`` modules, made by grpcio-tools' protoc and committed, so that
installing scart needs no protoc and no import runs one. Never edit them: change the
``.proto`` and run ``python -m scart_wire.proto._generate``. A test regenerates them and
fails when they differ from what is committed.

Import the modules by their full name, for example
``from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2``. Importing this package
itself imports nothing (no protobuf, no grpc).
"""
