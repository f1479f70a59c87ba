"""The ros1 transport's node settings, without a master: loopback unless insecure, the
process's defaults (``--ros-master``, ``--ros-name``, ``--insecure``) under a stream's
options, and what is refused before anything is made."""

from __future__ import annotations

import pytest

from dataflow.transports import load
from dataflow.transports.ros1.transport import Ros1Transport
from scart_ros1.names import RosNameError


def test_the_ros1_transport_is_registered_like_a_plug_in() -> None:
    transport = load("ros1")
    assert isinstance(transport, Ros1Transport)
    assert (transport.topics, transport.converts, transport.rank) == (True, True, None)  # never picked by auto


def test_loopback_unless_insecure() -> None:
    transport = Ros1Transport()
    assert transport.node_settings({}).host == "127.0.0.1"
    assert transport.node_settings({"insecure": "true"}).host == "0.0.0.0"
    assert transport.node_settings({"insecure": "true", "host": "10.0.0.7"}).host == "10.0.0.7"
    assert transport.node_settings({"host": "::1"}).host == "::1"
    with pytest.raises(ValueError, match="listens on loopback unless told insecure"):
        transport.node_settings({"host": "0.0.0.0"})


def test_the_process_defaults_and_a_streams_options() -> None:
    transport = Ros1Transport()
    assert transport.node_settings({}).node_name.startswith("scart_")
    transport.configure(master="http://127.0.0.1:11999/", name="robot", insecure=True)
    settings = transport.node_settings({})
    assert (settings.master, settings.node_name, settings.host) == ("http://127.0.0.1:11999/", "robot", "0.0.0.0")
    asked = transport.node_settings({"master": "http://127.0.0.1:12000/", "node": "arm", "__ns": "/left"})
    assert (asked.master, asked.node_name, asked.namespace) == ("http://127.0.0.1:12000/", "arm", "/left")
    for bad in ({"node": "a/b"}, {"master": "ftp://x"}, {"insecure": "maybe"}):
        with pytest.raises((ValueError, RosNameError)):
            transport.node_settings(bad)
    with pytest.raises(ValueError):
        transport.configure(name="not a name")
