"""Defaults shared by servers, clients and the CLI (no gRPC import)."""

from __future__ import annotations

#: Port of the name service when neither ``--ns`` nor ``SCART_NS`` says otherwise.
DEFAULT_NS_PORT = 7850
DEFAULT_NS_ADDRESS = f"127.0.0.1:{DEFAULT_NS_PORT}"
#: Environment variable naming the name service (``HOST:PORT``).
NS_ENV = "SCART_NS"
#: Default name-service lease (s); deployers heartbeat every third of it.
DEFAULT_LEASE = 10.0
