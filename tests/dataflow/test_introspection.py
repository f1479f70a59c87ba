"""Storage semantics against a reference model (hypothesis), and the hot path never
touching the setup lock."""

from __future__ import annotations

import threading
from collections import deque

from hypothesis import given, settings
from hypothesis import strategies as st

from dataflow import ConnPolicy, ConnType, FlowStatus, InputPort, LockPolicy, OutputPort, WriteStatus
from dataflow import ports as ports_module

NO, OLD, NEW = FlowStatus.NO_DATA, FlowStatus.OLD_DATA, FlowStatus.NEW_DATA


class Model:
    """What RTT 2.9 specifies for one connection, written as plainly as possible."""

    def __init__(self, policy: ConnPolicy) -> None:
        self.policy = policy
        self.items: deque[int] = deque()
        self.last: int | None = None
        self.ever = False
        self.dropped = 0

    def write(self, v: int) -> WriteStatus:
        if self.policy.type is ConnType.DATA:
            if self.items:
                self.dropped += 1
            self.items = deque([v])
            self.last, self.ever = v, True  # DATA: OLD is the last written, read or not
            return WriteStatus.WRITE_SUCCESS
        if len(self.items) == self.policy.size:
            self.dropped += 1
            if self.policy.type is ConnType.BUFFER:
                return WriteStatus.WRITE_FAILURE
            self.items.popleft()
        self.items.append(v)
        return WriteStatus.WRITE_SUCCESS

    def read(self):
        if self.items:
            v = self.items.popleft()
            self.last, self.ever = v, True
            return NEW, v
        if self.policy.type is ConnType.DATA:
            return (OLD, self.last) if self.ever else (NO, None)
        return (OLD, self.last) if self.ever else (NO, None)

    def clear(self) -> None:
        if self.policy.type is not ConnType.DATA:
            self.dropped += len(self.items)
        self.items.clear()
        self.ever, self.last = False, None


policies = st.sampled_from(
    [
        ConnPolicy.data(),
        ConnPolicy.data(lock_policy=LockPolicy.LOCKED),
        ConnPolicy.buffer(1),
        ConnPolicy.buffer(3),
        ConnPolicy.circular_buffer(1),
        ConnPolicy.circular_buffer(3, lock_policy=LockPolicy.LOCKED),
    ]
)
ops = st.lists(st.sampled_from(["w", "r", "c"]), max_size=40)


@settings(max_examples=60, deadline=None)
@given(policies, ops)
def test_storage_matches_model(policy, script):
    out, inp = OutputPort(int, "o"), InputPort(int, "i")
    conn = out.connect_to(inp, policy)
    model = Model(policy)
    for k, op in enumerate(script):
        if op == "w":
            assert out.write(k) is model.write(k)
        elif op == "r":
            assert inp.read() == model.read()
        else:
            inp.clear()
            model.clear()
    if policy.type is not ConnType.DATA:
        assert conn.dropped == model.dropped


def test_hot_path_never_takes_the_setup_lock():
    out, inp = OutputPort(int, "o"), InputPort(int, "i")
    out.connect_to(inp, ConnPolicy.buffer(4))
    done = threading.Event()

    def user() -> None:
        out.write(1)
        inp.read()
        done.set()

    with ports_module._setup_lock:  # held by this thread for the whole check
        t = threading.Thread(target=user, daemon=True)
        t.start()
        assert done.wait(5.0), "write/read waited on the setup lock"
    t.join(5.0)
