"""The wire format: the committed code is what protoc makes of the .proto files, buf
style, its version stamps agree with pyproject's bounds, and the services the servers
register are exactly the proto's (names and streaming kinds)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import grpc
import pytest
from grpc_reflection.v1alpha import reflection_pb2, reflection_pb2_grpc
from packaging.requirements import Requirement
from packaging.version import Version

from dataflow import Deployer
from scart_wire.proto import _generate
from dataflow.remote import _proto, serve_nameserver
from support import ROOT
from support.remote import Pinger




def _pyproject_requirements(table: list[str]) -> dict[str, Requirement]:
    return {r.name: r for r in map(Requirement, table)}


def _lower(req: Requirement) -> Version | None:
    bounds = [Version(s.version) for s in req.specifier if s.operator in (">=", "==", "~=")]
    return max(bounds) if bounds else None


def test_committed_wire_code_is_what_protoc_makes() -> None:
    stale = _generate.stale()
    assert not stale, f"regenerate with `python -m scart_wire.proto._generate`: {stale}"


def test_freshness_check_sees_an_edit(tmp_path: Path) -> None:
    """The check above can fail: a changed .proto makes the committed code stale."""
    import shutil

    copy = tmp_path / "proto"
    shutil.copytree(_generate.SOURCE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert _generate.stale(copy) == []
    value = copy / "scart/dataflow/v1/value.proto"
    value.write_text(value.read_text().replace("bytes data = 2;", "bytes data = 2;\n  string unit = 3;"))
    assert "scart/dataflow/v1/value_pb2.py" in _generate.stale(copy)


@pytest.mark.parametrize("proto", _generate.proto_files())
def test_every_proto_file_is_buf_style(proto: str) -> None:
    text = (_generate.SOURCE / proto).read_text()
    package = re.search(r"^package ([\w.]+);", text, re.M)[1]
    assert package.startswith("scart.") and package.endswith(".v1")
    assert proto.startswith(package.replace(".", "/") + "/"), "buf style: directory matches package"


def test_sca_imports_only_the_value_message() -> None:
    from scart_wire.proto.scart.sca.v1 import sca_pb2

    assert [d.name for d in sca_pb2.DESCRIPTOR.dependencies] == ["scart/dataflow/v1/value.proto"]


def test_buf_style_one_request_response_pair_per_rpc() -> None:
    for service in (_proto.DEPLOYER_SERVICE, _proto.NAMING_SERVICE):
        assert service.name.endswith("Service")
        for method in service.methods:
            assert method.input_type.name == f"{method.name}Request"
            assert method.output_type.name == f"{method.name}Response"


def test_version_bounds_match_the_generated_code() -> None:
    """The generated modules refuse an older grpcio/protobuf than made them: pyproject's lower
    bounds are exactly those versions, and grpcio-tools is no runtime dependency."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    runtime = _pyproject_requirements(data["project"]["dependencies"])
    test = _pyproject_requirements(data["project"]["optional-dependencies"]["test"])
    assert "grpcio-tools" not in runtime and "grpcio-tools" in test
    grpc_code = (_generate.ROOT / "scart/dataflow/v1/dataflow_pb2_grpc.py").read_text()
    pb_code = (_generate.ROOT / "scart/dataflow/v1/dataflow_pb2.py").read_text()
    grpc_made = re.search(r"^GRPC_GENERATED_VERSION = '([\d.]+)'", grpc_code, re.M)[1]
    pb_made = ".".join(re.search(r"Domain\.PUBLIC,\s*(\d+),\s*(\d+),\s*(\d+),", pb_code).groups())
    assert _lower(runtime["grpcio"]) == Version(grpc_made) == _lower(test["grpcio-tools"])
    assert _lower(runtime["protobuf"]) == Version(pb_made)


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


@pytest.mark.integration
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


def test_every_servicer_answers_every_method_of_its_service() -> None:
    """Servicers subclass the generated bases (which answer UNIMPLEMENTED): each must
    override every method of its proto service."""
    from scart_wire.proto.scart.sca.v1 import sca_pb2, sca_pb2_grpc
    from dataflow.remote._servicer import DeployerServicer
    from dataflow.remote.naming import NamingServicer
    from scart.bindings.grpc._server import _Servicer

    from dataflow import transports

    # the sample path's methods are answered by the transports' serving halves, the rest by
    # the control plane's servicer
    servings = []
    for name in transports.names():
        try:
            kind = transports.load(name).serving()
        except transports.TransportError:  # a plug-in whose extra is not installed serves nothing
            continue
        if kind is not None:
            servings.append(kind)
    served = {method for kind in servings for method in kind.methods}
    assert {"Link", "Subscribe", "OpenIpcWriter", "OpenIpcReader"} <= served, served
    cases = [(DeployerServicer, _proto.df_grpc.DeployerServiceServicer, _proto.DEPLOYER_SERVICE, served),
             (NamingServicer, _proto.ns_grpc.NamingServiceServicer, _proto.NAMING_SERVICE, set())]
    for servicer, base, service, elsewhere in cases:
        missing = [m.name for m in service.methods
                   if getattr(servicer, m.name) is getattr(base, m.name) and m.name not in elsewhere]
        assert missing == [], f"{servicer.__name__} leaves {missing} UNIMPLEMENTED"
    sca = sca_pb2.DESCRIPTOR.services_by_name["ScaService"]
    answered = set(vars(_Servicer(object.__new__(_FakeServer))))
    assert answered == {m.name for m in sca.methods}
    assert issubclass(_Servicer, sca_pb2_grpc.ScaServiceServicer)


class _FakeServer:
    """Stands in for a GrpcServer: the servicer only takes its bound handlers."""

    _call = _send = _invoke = _reply = _open_session = _list = staticmethod(lambda *a: None)
