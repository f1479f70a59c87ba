"""The latency a ``<scart:bridge>`` adds, against a hand-written TaskContext doing the same work.

Both run in one deployer, event-driven: a source task writes an ``Arm`` (6 joints) and a
flag; the bridge (or the hand-written task) takes the joint positions with a field path,
builds a ``Summary`` model and writes it; a probe port's data callback stamps the arrival.
One sample at a time (the next after the previous arrived), so the figure is latency, not
throughput. The goal: the bridge within 1.2× of the hand-written task.

    python benchmarks/bench_bridge.py [--quick | --smoke] [N]

(N samples, 3000 by default; ``--quick`` 600, ``--smoke`` 60: that it runs.)
"""

from __future__ import annotations

import argparse
import tempfile
import textwrap
import threading
import time
from pathlib import Path

from _common import pct

import scart
from dataflow import ConnPolicy, InputPort
from scart.bindings.dataflow import deployer_of

MODS = '''
from __future__ import annotations

from pydantic import BaseModel

from dataflow import FlowStatus, InputPort, OutputPort, TaskContext


class Joint(BaseModel):
    position: float
    velocity: float = 0.0


class Arm(BaseModel):
    joints: list[Joint]


class Summary(BaseModel):
    arm: list[float]
    busy: bool


class Source(TaskContext):
    status = OutputPort(Arm)
    busy = OutputPort(bool)


class HandWritten(TaskContext):
    """What a user writes today instead of the bridge."""

    arm = InputPort(Arm, event=True)
    busy = InputPort(bool, event=True)
    summary = OutputPort(Summary)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._arm = None
        self._busy = None

    def update_hook(self) -> None:
        status, value = self.arm.read_newest()
        fresh = status is FlowStatus.NEW_DATA
        if fresh:
            self._arm = [j.position for j in value.joints]
        status, value = self.busy.read_newest()
        if status is FlowStatus.NEW_DATA:
            self._busy, fresh = value, True
        if fresh and self._arm is not None and self._busy is not None:
            self.summary.write(Summary(arm=self._arm, busy=self._busy))
'''

COMPOSITE = '''<?xml version="1.0"?>
<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0"
           targetNamespace="urn:bench" name="Bench">
  <component name="src"><scart:implementation.task class="mods:Source"/></component>
  <component name="hand"><scart:implementation.task class="mods:HandWritten"/></component>
  <scart:connect from="src.status" to="hand.arm"/>
  <scart:connect from="src.busy" to="hand.busy"/>
  <scart:bridge name="bridge" trigger="any">
    <scart:input name="arm" from="src.status" field="joints[*].position"/>
    <scart:input name="busy" from="src.busy"/>
    <scart:output name="summary" type="mods:Summary"/>
  </scart:bridge>
</composite>
'''


def measure(rt: scart.Runtime, task: str, n: int) -> list[float]:
    """Per-sample latency (s) from the source's write to the arrival at ``task``'s output."""
    import mods

    deployer = deployer_of(rt)
    src = deployer.task("src")
    probe: InputPort[object] = InputPort(mods.Summary, "probe")
    arrived = threading.Event()
    probe.add_data_callback(lambda port: arrived.set())
    deployer.task(task).port("summary").connect_to(probe, ConnPolicy.data())
    src.port("busy").write(False)
    arrived.wait(5)
    arm = mods.Arm(joints=[mods.Joint(position=i / 10) for i in range(6)])
    out = []
    for _ in range(n):
        arrived.clear()
        began = time.perf_counter()
        src.port("status").write(arm)
        if not arrived.wait(5):
            raise RuntimeError(f"{task}: no output within 5 s")
        out.append(time.perf_counter() - began)
        probe.read()
    deployer.task(task).port("summary").disconnect(probe)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=None, help="samples (default 3000)")
    parser.add_argument("--quick", action="store_true", help="600 samples")
    parser.add_argument("--smoke", action="store_true", help="60 samples: that it runs")
    args = parser.parse_args()
    n = args.n or (60 if args.smoke else 600 if args.quick else 3000)
    with tempfile.TemporaryDirectory() as folder:
        Path(folder, "mods.py").write_text(textwrap.dedent(MODS))
        Path(folder, "bench.composite").write_text(COMPOSITE)
        with scart.Runtime.from_file(str(Path(folder, "bench.composite"))) as rt:
            rows = {}
            for _ in range(2):  # alternate, twice, so neither gets the warm caches only
                for task in ("hand", "bridge"):
                    rows.setdefault(task, []).extend(measure(rt, task, n // 2))
    base = pct(rows["hand"], 0.5)
    print(f"{'path':<28} {'p50 µs':>8} {'p99 µs':>8} {'p50 ratio':>10}")
    for task, label in (("hand", "hand-written TaskContext"), ("bridge", "scart:bridge")):
        p50, p99 = pct(rows[task], 0.5), pct(rows[task], 0.99)
        print(f"{label:<28} {p50 * 1e6:8.1f} {p99 * 1e6:8.1f} {p50 / base:10.2f}")


if __name__ == "__main__":
    main()
