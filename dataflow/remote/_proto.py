"""Message classes and service descriptors built from ``proto/`` at import time.

Nothing generated is committed: grpcio-tools' own protoc compiles ``proto/**/*.proto``
into a descriptor set when this module is imported (the data-flow and naming files; other
files are compiled by their users with :func:`compile_protos`), the descriptors go into
the default pool (so server reflection serves them), and the message classes are made
from them, so they can never drift from ``proto/``.

Why not ``grpc.protos_and_services``: it imports the generated code under a module
name derived from the proto path (``scart.dataflow.v1.dataflow_pb2``), which collides
with the real ``scart`` package and would make ``dataflow`` import ``scart``. The
descriptor-set route uses the same protoc and the public protobuf API instead, and the
server/client build their method tables from the service descriptors (see
:func:`method_paths`), so the names on the wire are the proto's by construction.

Public names: :data:`df` (``scart.dataflow.v1`` messages as attributes), :data:`ns`
(``scart.naming.v1``), :data:`DEPLOYER_SERVICE`, :data:`NAMING_SERVICE` (service
descriptors), :func:`proto_root`, :func:`proto_files`, :func:`compile_protos`.
"""

from __future__ import annotations

import tempfile
import threading
from pathlib import Path
from types import SimpleNamespace

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.descriptor import ServiceDescriptor

DATAFLOW_PACKAGE = "scart.dataflow.v1"
NAMING_PACKAGE = "scart.naming.v1"
DEPLOYER_SERVICE_NAME = f"{DATAFLOW_PACKAGE}.DeployerService"
NAMING_SERVICE_NAME = f"{NAMING_PACKAGE}.NamingService"

_lock = threading.Lock()


def proto_root() -> Path:
    """The ``proto/`` folder (repository root in the editable install)."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        candidate = parent / "proto"
        if (candidate / "scart").is_dir():
            return candidate
    raise FileNotFoundError(f"no proto/ folder above {here.parent}")


def proto_files() -> list[str]:
    """Every ``.proto`` file under :func:`proto_root`, relative to it, sorted."""
    root = proto_root()
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*.proto"))


def compile_protos(files: list[str] | None = None) -> descriptor_pb2.FileDescriptorSet:
    """Compile ``files`` (default: all) with grpcio-tools' protoc; raises ``RuntimeError``.

    Blocks for the compile (tens of ms). Thread-safe.
    """
    from grpc_tools import protoc  # local: only needed at import / in tests

    files = proto_files() if files is None else files
    with tempfile.TemporaryDirectory(prefix="scart-proto-") as tmp:
        out = Path(tmp) / "set.pb"
        args = ["protoc", f"-I{proto_root()}", f"--descriptor_set_out={out}", *files]
        with _lock:
            code = protoc.main(args)
        if code != 0 or not out.exists():
            raise RuntimeError(f"protoc failed ({code}) compiling {files} under {proto_root()}")
        fds = descriptor_pb2.FileDescriptorSet()
        fds.ParseFromString(out.read_bytes())
    return fds


#: The files this module loads (other streams compile theirs with :func:`compile_protos`).
OWN_PROTOS = ["scart/dataflow/v1/dataflow.proto", "scart/naming/v1/naming.proto"]


def _load() -> tuple[SimpleNamespace, SimpleNamespace, ServiceDescriptor, ServiceDescriptor]:
    fds = compile_protos(OWN_PROTOS)
    pool = descriptor_pool.Default()
    for file_proto in fds.file:
        try:
            pool.FindFileByName(file_proto.name)
        except KeyError:
            pool.Add(file_proto)
    classes = message_factory.GetMessages(list(fds.file), pool=pool)
    spaces: dict[str, SimpleNamespace] = {DATAFLOW_PACKAGE: SimpleNamespace(), NAMING_PACKAGE: SimpleNamespace()}
    for full_name, cls in classes.items():
        package, _, short = full_name.rpartition(".")
        if package in spaces:
            setattr(spaces[package], short, cls)
    for package, space in spaces.items():
        for file_proto in fds.file:
            if file_proto.package != package:
                continue
            file_desc = pool.FindFileByName(file_proto.name)
            for enum_name, enum_desc in file_desc.enum_types_by_name.items():
                setattr(space, enum_name, {v.name: v.number for v in enum_desc.values})
    return (
        spaces[DATAFLOW_PACKAGE],
        spaces[NAMING_PACKAGE],
        pool.FindServiceByName(DEPLOYER_SERVICE_NAME),
        pool.FindServiceByName(NAMING_SERVICE_NAME),
    )


df, ns, DEPLOYER_SERVICE, NAMING_SERVICE = _load()


def method_paths(service: ServiceDescriptor) -> dict[str, str]:
    """``{method name: "/package.Service/Method"}`` for a service descriptor."""
    return {m.name: f"/{service.full_name}/{m.name}" for m in service.methods}


def method_kinds(service: ServiceDescriptor) -> dict[str, tuple[bool, bool]]:
    """``{method name: (client_streaming, server_streaming)}``."""
    return {m.name: (m.client_streaming, m.server_streaming) for m in service.methods}
