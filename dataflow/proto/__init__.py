"""Every wire format of scart: the ``.proto`` files, and the Python code protoc makes of them.

The ``.proto`` files under this folder are the single source of truth, laid out buf style
(the folder is the proto package)::

    scart/dataflow/v1/value.proto     Value: one value of any registered type
    scart/dataflow/v1/dataflow.proto  DeployerService: remote access to data-flow tasks
    scart/naming/v1/naming.proto      NamingService: component name -> deployer
    scart/sca/v1/sca.proto            ScaService: binding.grpc

Next to each file lie its ``_pb2.py``, ``_pb2.pyi`` and ``_pb2_grpc.py`` modules, made by
grpcio-tools' protoc and committed, so that installing scart needs no protoc and no
import runs one. Never edit them: change the ``.proto`` and run
``python -m dataflow.proto._generate``. A test regenerates them and fails when they
differ from what is committed.

Import the modules by their full name, for example
``from dataflow.proto.scart.dataflow.v1 import dataflow_pb2``. Importing this package
itself imports nothing (no protobuf, no grpc).
"""
