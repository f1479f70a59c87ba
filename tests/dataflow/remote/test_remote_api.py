"""The public surface of dataflow.remote, and the neutral API staying free of gRPC."""

from __future__ import annotations

import subprocess
import sys

import dataflow.remote
from dataflow import Deployer
from dataflow.remote import connect
from support.remote import Pinger

EXPORTS = {
    "connect", "local_system", "serve_nameserver",
    "System", "ComponentProxy", "Subscription", "PortWriter", "SampleEvent", "GapEvent", "ComponentInfo",
    "RemoteError", "UnavailableError", "RemoteTimeoutError", "RemoteNotFoundError", "RemoteTypeError",
    "RemoteValueError", "AlreadyRegisteredError", "ClosedError", "DEFAULT_NS_PORT", "DEFAULT_NS_ADDRESS",
    "AuthenticationError", "PermissionDeniedError", "Security", "SecurityError", "Role",
}


def test_public_exports_are_guarded() -> None:
    assert set(dataflow.remote.__all__) == EXPORTS
    for name in EXPORTS:
        assert hasattr(dataflow.remote, name), name
    assert dataflow.remote.DEFAULT_NS_PORT == 7850


def test_neutral_api_and_in_process_implementation_import_no_grpc() -> None:
    code = (
        "import sys, dataflow.remote, dataflow.remote.api, dataflow.remote.local, dataflow.remote.errors;"
        "print(sorted(m for m in sys.modules if m == 'grpc' or m.startswith(('grpc.', 'google.protobuf'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == "[]"


def test_dataflow_never_imports_scart() -> None:
    code = "import sys, dataflow, dataflow.remote.server, dataflow.remote.client; print('scart' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == "False"


def test_errors_are_dataflow_errors_and_remote_ones_keep_core_meaning() -> None:
    from dataflow import DataflowError, NotFoundError, PortTypeError
    from dataflow.remote import RemoteNotFoundError, RemoteTypeError, UnavailableError

    assert issubclass(RemoteNotFoundError, NotFoundError)
    assert issubclass(RemoteTypeError, PortTypeError)
    assert issubclass(UnavailableError, DataflowError)


def test_embedded_name_service_publishes_tasks_added_later() -> None:
    deployer = Deployer()
    deployer.add(Pinger("first"))
    server = deployer.serve("127.0.0.1:0")
    try:
        with connect(server.address) as system:
            assert system.component_names() == ["first"]
            deployer.add(Pinger("second"))
            assert system.component_names() == ["first", "second"]
            assert system.component("second").state == "STOPPED"
    finally:
        server.stop()
