"""The io threads' poll (ipc's hub, the ROS 1 node): readiness as ``selectors`` reports
it, with epoll and with plain poll (where there is no epoll)."""

from __future__ import annotations

import select
import socket

import pytest

from dataflow.transports._poll import IN, OUT, READABLE, Poller


@pytest.fixture(params=["epoll", "poll"])
def poller(request, monkeypatch) -> Poller:
    if request.param == "poll":
        monkeypatch.delattr(select, "epoll", raising=False)
    elif not hasattr(select, "epoll"):
        pytest.skip("no epoll on this platform")
    made = Poller()
    yield made
    made.close()


def test_a_socket_is_reported_ready_to_read_then_write_then_not_at_all(poller: Poller) -> None:
    a, b = socket.socketpair()
    try:
        handler = object()
        poller.register(b, IN, handler)
        assert poller.poll(0) == []
        a.send(b"x")
        [(fd, events)] = poller.poll(1.0)
        assert poller.watched[fd][1] is handler and events & IN
        poller.modify(b, IN | OUT, handler)
        [(fd, events)] = poller.poll(1.0)
        assert events & IN and events & OUT and poller.watched[fd][2] == IN | OUT
        poller.unregister(b)
        poller.unregister(b)  # idempotent
        assert poller.poll(0) == [] and poller.handlers() == []
    finally:
        a.close()
        b.close()


def test_a_closed_socket_is_unregistered_by_identity(poller: Poller) -> None:
    a, b = socket.socketpair()
    a.close()
    poller.register(b, IN, "h")
    [(_, events)] = poller.poll(1.0)
    assert events & READABLE  # a hang-up wakes its reader
    b.close()
    poller.unregister(b)  # its number is gone: found by the socket itself
    assert poller.watched == {}
