"""The remote layer's wire modules (private): the code protoc made of ``dataflow/proto``.

Nothing is compiled at import: the ``_pb2``/``_pb2_grpc`` modules are committed next to
their ``.proto`` files (see :mod:`scart_wire.proto`). Public names: :data:`df`
(``scart.dataflow.v1`` messages and enums), :data:`df_grpc` (its stub and servicer
registration), :data:`ns` / :data:`ns_grpc` (``scart.naming.v1``), the service
descriptors :data:`DEPLOYER_SERVICE` and :data:`NAMING_SERVICE`, and their full names.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from google.protobuf.descriptor import ServiceDescriptor

from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as df
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2_grpc as df_grpc
from scart_wire.proto.scart.naming.v1 import naming_pb2 as ns
from scart_wire.proto.scart.naming.v1 import naming_pb2_grpc as ns_grpc
from scart_wire.security import Role, roles_of_service

DEPLOYER_SERVICE: ServiceDescriptor = df.DESCRIPTOR.services_by_name["DeployerService"]
NAMING_SERVICE: ServiceDescriptor = ns.DESCRIPTOR.services_by_name["NamingService"]
DEPLOYER_SERVICE_NAME = DEPLOYER_SERVICE.full_name
NAMING_SERVICE_NAME = NAMING_SERVICE.full_name

#: The role each method needs (see :mod:`scart_wire.security`): reading and
#: subscribing need ``read``; the rest of the DeployerService ``operate``; registering
#: names with a name service ``admin``.
DEPLOYER_ROLES: Mapping[str, Role] = MappingProxyType(roles_of_service(
    DEPLOYER_SERVICE_NAME, reads={"ListTasks", "DescribeTask", "ReadPort", "Subscribe", "GetProperty", "ListLinks",
                                     "OpenIpcReader"}))
NAMING_ROLES: Mapping[str, Role] = MappingProxyType(roles_of_service(
    NAMING_SERVICE_NAME, reads={"Resolve", "ListEntries"}, default=Role.ADMIN))

__all__ = ["DEPLOYER_ROLES", "DEPLOYER_SERVICE", "DEPLOYER_SERVICE_NAME", "NAMING_ROLES", "NAMING_SERVICE",
           "NAMING_SERVICE_NAME", "df", "df_grpc",
           "method_kinds", "method_paths", "ns", "ns_grpc"]


def method_paths(service: ServiceDescriptor) -> dict[str, str]:
    """``{method name: "/package.Service/Method"}`` for a service descriptor."""
    return {m.name: f"/{service.full_name}/{m.name}" for m in service.methods}


def method_kinds(service: ServiceDescriptor) -> dict[str, tuple[bool, bool]]:
    """``{method name: (client_streaming, server_streaming)}``."""
    return {m.name: (m.client_streaming, m.server_streaming) for m in service.methods}
