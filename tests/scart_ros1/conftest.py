"""The ROS 1 node library's tests: a master of each test's own (``ros``), one type store
per module with roscpp's logger types (``types``), and a node on the master (``node``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from support.ros1 import RosMaster, ros  # noqa: F401 - the fixture, for every test here

from scart_ros1 import MessageTypes, Node


@pytest.fixture(scope="module")
def types() -> MessageTypes:
    mt = MessageTypes()
    mt.add_msg("roscpp/Logger", "string name\nstring level\n")
    mt.add_srv("roscpp/GetLoggers", "---\nLogger[] loggers\n")
    mt.add_srv("roscpp/SetLoggerLevel", "string logger\nstring level\n---\n")
    return mt


@pytest.fixture
def node(ros: RosMaster, types: MessageTypes) -> Iterator[Node]:  # noqa: F811 - ros: the fixture imported
    with Node("scart", master_uri=ros.uri, types=types) as n:
        yield n
