"""The wire format: every .proto compiles, version bounds agree with grpcio-tools, and the
services the servers register are exactly the proto's (names and streaming kinds)."""

from __future__ import annotations

import importlib.metadata as md
import tomllib
from pathlib import Path

import grpc
import pytest
from grpc_reflection.v1alpha import reflection_pb2, reflection_pb2_grpc
from packaging.requirements import Requirement
from packaging.version import Version

from dataflow import Deployer
from dataflow.remote import _proto, serve_nameserver
from test_remote_support import Pinger

ROOT = Path(__file__).resolve().parent.parent


def _pyproject_requirements() -> dict[str, Requirement]:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    reqs = [Requirement(r) for r in data["project"]["dependencies"]]
    return {r.name: r for r in reqs}


def _lower(req: Requirement) -> Version | None:
    bounds = [Version(s.version) for s in req.specifier if s.operator in (">=", "==", "~=")]
    return max(bounds) if bounds else None


@pytest.mark.parametrize("proto", _proto.proto_files())
def test_every_proto_file_compiles(proto: str) -> None:
    fds = _proto.compile_protos([proto])
    assert [f.name for f in fds.file] == [proto]
    package = fds.file[0].package
    assert package.startswith("scart.") and package.endswith(".v1")
    assert proto.startswith(package.replace(".", "/") + "/"), "buf style: directory matches package"


def test_proto_folder_has_both_packages() -> None:
    assert "scart/dataflow/v1/dataflow.proto" in _proto.proto_files()
    assert "scart/naming/v1/naming.proto" in _proto.proto_files()


def test_buf_style_one_request_response_pair_per_rpc() -> None:
    for service in (_proto.DEPLOYER_SERVICE, _proto.NAMING_SERVICE):
        assert service.name.endswith("Service")
        for method in service.methods:
            assert method.input_type.name == f"{method.name}Request"
            assert method.output_type.name == f"{method.name}Response"


def test_version_bounds_consistent_with_grpcio_tools() -> None:
    pyreqs = _pyproject_requirements()
    for name in ("grpcio", "grpcio-tools", "protobuf"):
        assert name in pyreqs, f"pyproject lacks {name}"
        assert Version(md.version(name)) in pyreqs[name].specifier, f"installed {name} outside pyproject bounds"
    # grpcio and grpcio-tools move together
    assert _lower(pyreqs["grpcio"]) == _lower(pyreqs["grpcio-tools"])
    # what the installed grpcio-tools (whose protoc builds our messages) needs is installed,
    # and the pyproject does not forbid it
    for text in md.requires("grpcio-tools") or []:
        req = Requirement(text)
        if req.name in ("protobuf", "grpcio"):
            installed = Version(md.version(req.name))
            assert installed in req.specifier, f"grpcio-tools needs {req}, {installed} installed"
            low = _lower(req)
            assert low is None or low in pyreqs[req.name].specifier or low >= _lower(pyreqs[req.name])


def _reflected_services(address: str) -> set[str]:
    with grpc.insecure_channel(address) as channel:
        stub = reflection_pb2_grpc.ServerReflectionStub(channel)
        replies = stub.ServerReflectionInfo(iter([reflection_pb2.ServerReflectionRequest(list_services="")]), timeout=5)
        return {s.name for r in replies for s in r.list_services_response.service}


def _registered_methods(address: str, service_name: str) -> dict[str, tuple[bool, bool]]:
    """Ask reflection for the served file and read the methods as the server knows them."""
    from google.protobuf import descriptor_pb2

    with grpc.insecure_channel(address) as channel:
        stub = reflection_pb2_grpc.ServerReflectionStub(channel)
        req = reflection_pb2.ServerReflectionRequest(file_containing_symbol=service_name)
        replies = list(stub.ServerReflectionInfo(iter([req]), timeout=5))
    out = {}
    for raw in replies[0].file_descriptor_response.file_descriptor_proto:
        fdp = descriptor_pb2.FileDescriptorProto.FromString(raw)
        for svc in fdp.service:
            if f"{fdp.package}.{svc.name}" == service_name:
                out = {m.name: (m.client_streaming, m.server_streaming) for m in svc.method}
    return out


def test_registered_services_match_proto_descriptors() -> None:
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0")
    standalone = serve_nameserver("127.0.0.1:0")
    try:
        services = _reflected_services(server.address)
        assert {_proto.DEPLOYER_SERVICE_NAME, _proto.NAMING_SERVICE_NAME, "grpc.health.v1.Health"} <= services
        assert _registered_methods(server.address, _proto.DEPLOYER_SERVICE_NAME) == _proto.method_kinds(
            _proto.DEPLOYER_SERVICE
        )
        assert _proto.NAMING_SERVICE_NAME in _reflected_services(standalone.address)
        assert _proto.DEPLOYER_SERVICE_NAME not in _reflected_services(standalone.address)
        # and every method answers (not UNIMPLEMENTED) at the path the descriptor gives
        with grpc.insecure_channel(server.address) as channel:
            for name, path in _proto.method_paths(_proto.NAMING_SERVICE).items():
                cls = getattr(_proto.ns, f"{name}Request")
                fn = channel.unary_unary(path, request_serializer=cls.SerializeToString, response_deserializer=lambda b: b)
                try:
                    fn(cls(), timeout=5)
                except grpc.RpcError as exc:
                    assert exc.code() != grpc.StatusCode.UNIMPLEMENTED, path
    finally:
        server.stop()
        standalone.stop()
