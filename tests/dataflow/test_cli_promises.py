"""What a new user met and took for success (issue: "every promise kept"): each case
through the ``scart`` command a user types, as a real subprocess against a real served
deployer. A typo never prints ``null`` and exit 0; a field a model does not have is
refused, not dropped; an address without a port, a negative timeout and a huge argument
get one short line."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator

import pydantic
import pytest

from dataflow import Deployer, InputPort, OutputPort, PeriodicActivity, TaskContext, operation, register_type
from support import ROOT, wait_until
from support.remote import subprocess_env

sys.path.insert(0, str(ROOT / "composites" / "youbot"))
from driver import YouBotDriver  # noqa: E402

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


@register_type("PromisePose")
class Pose(pydantic.BaseModel):
    x: float
    y: float


class Filter(TaskContext):
    """A task with a model input and a counter output (a new user's first task)."""

    pose_in = InputPort(Pose, doc="where to go")
    ticks = OutputPort(int, doc="cycle counter")

    def __init__(self, name: str = "Filter") -> None:
        super().__init__(name)
        self.count = 0
        self.poses: list[Pose] = []

    def update_hook(self) -> None:
        self.count += 1
        self.ticks.write(self.count)
        flow, pose = self.pose_in.read()
        if flow.name == "NEW_DATA":
            self.poses.append(pose)

    @operation
    def scale(self, pose: Pose, factor: float = 1.0) -> float:
        """``factor`` times the pose's x."""
        return pose.x * factor


class Hoarder(TaskContext):
    """A sink that never reads what arrives (a slow consumer at its worst)."""

    inp = InputPort(int, doc="never read")


@pytest.fixture(scope="module")
def served() -> Iterator[tuple[str, Filter]]:
    """A served deployer (embedded name service) hosting one Filter, running."""
    deployer = Deployer()
    task = Filter()
    task.set_activity(PeriodicActivity(0.02))
    deployer.add(task)
    deployer.add(YouBotDriver())
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0")
    try:
        yield server.address, task
    finally:
        server.stop()
        deployer.stop_all()


def scart(ns: str | None, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60,
                          env={**subprocess_env(ns), **(env or {})}, cwd=ROOT)


def test_echo_of_a_field_the_samples_lack_exits_1_naming_the_fields(served: tuple[str, Filter]) -> None:
    ns, _ = served
    done = scart(ns, "echo", "Filter.ticks", "--once", "--field", "jionts")
    assert done.returncode == 1, done
    assert "null" not in done.stdout and done.stdout == ""
    assert "has no jionts" in done.stderr and done.stderr.count("\n") == 1


def test_write_refuses_a_field_the_model_does_not_have(served: tuple[str, Filter]) -> None:
    ns, task = served
    done = scart(ns, "write", "Filter.pose_in", "{x: 1, y: 2, z: 3}")
    assert done.returncode == 1, done
    assert "unknown field z" in done.stderr and "Pose has: x, y" in done.stderr, done.stderr
    near = scart(ns, "write", "Filter.pose_in", "{x: 1, yy: 2}")
    assert near.returncode == 1 and "did you mean 'y'?" in near.stderr, near.stderr
    assert task.poses == []  # nothing reached the task
    ok = scart(ns, "write", "Filter.pose_in", "{x: 1, y: 2}")
    assert ok.returncode == 0, ok.stderr


def test_an_address_without_a_port_and_a_negative_timeout_are_refused() -> None:
    for args in (["ls", "--ns", "localhost"], ["ls", "--timeout", "-1"], ["ls", "--timeout", "nan"],
                 ["call", "--at", "localhost", "x.y"]):
        done = scart(None, *args)
        assert done.returncode == 2, (args, done)
        assert "443" not in done.stderr and ("HOST:PORT" in done.stderr or "> 0" in done.stderr), done.stderr
    env = scart(None, "ls", env={"SCART_NS": "localhost"})
    assert env.returncode == 2 and "$SCART_NS 'localhost': expected HOST:PORT" in env.stderr, env.stderr


def test_an_error_line_echoes_a_bounded_part_of_a_huge_argument() -> None:
    huge = "x" * 120_000  # as long as one argument of a command line may be
    for args in (["info", huge], ["state", "task", huge]):
        done = scart(None, *args)
        assert done.returncode in (1, 2), done
        assert len(done.stderr) < 4000 and "characters left out" in done.stderr, len(done.stderr)


def test_call_takes_the_arguments_by_name_as_one_mapping(served: tuple[str, Filter]) -> None:
    ns, _ = served
    named = scart(ns, "call", "Filter.scale", "{pose: {x: 2, y: 0}, factor: 3}")
    assert named.returncode == 0 and json.loads(named.stdout) == 6.0, named
    in_order = scart(ns, "call", "Filter.scale", "{x: 2, y: 0}", "2")  # a model's fields: one argument
    assert in_order.returncode == 0 and json.loads(in_order.stdout) == 4.0, in_order
    missing = scart(ns, "call", "Filter.scale", "{pose: {x: 2, y: 0}, factr: 3}")
    assert missing.returncode == 1 and "missing 'factor'" in missing.stderr and "no argument 'factr'" in missing.stderr


def test_call_and_write_refuse_a_value_alike(served: tuple[str, Filter]) -> None:
    """``call set_period 5`` printed ``false`` and exited 0 where ``write period 5`` exited
    1: a value the task's declaration refuses is refused at either door, exit 1."""
    ns, _ = served
    write = scart(ns, "write", "youBotDriver.period", "5")
    call = scart(ns, "call", "youBotDriver.set_period", "5")
    assert (write.returncode, call.returncode) == (1, 1), (write, call)
    assert call.stdout == "" and "set_period(seconds): 5 refused" in call.stderr and "1" in call.stderr
    accepted = scart(ns, "call", "youBotDriver.set_period", "{seconds: 0.02}")
    assert accepted.returncode == 0 and json.loads(accepted.stdout) is True, accepted


def test_a_garbage_tls_ca_gets_one_clear_line(tmp_path) -> None:  # noqa: ANN001 - pytest's tmp_path
    garbage = tmp_path / "ca.pem"
    garbage.write_text("not a certificate\n")
    done = scart(None, "ls", "--ns", "127.0.0.1:9", "--tls-ca", str(garbage))
    assert done.returncode == 1, done
    assert done.stderr == f"scart ls: --tls-ca {garbage}: no PEM certificate in it (give the CA's certificate, a " \
                          "file starting '-----BEGIN CERTIFICATE-----')\n", done.stderr  # no gRPC line, no "nothing answers"


def test_a_recording_is_made_private(served: tuple[str, Filter], tmp_path) -> None:  # noqa: ANN001
    ns, _ = served
    fresh, old = tmp_path / "run.mcap", tmp_path / "old.mcap"
    old.write_text("")
    old.chmod(0o644)
    for path, extra in ((fresh, ()), (old, ("--overwrite",))):
        done = scart(ns, "record", "Filter.ticks", "-o", str(path), "-n", "2", *extra)
        assert done.returncode == 0, done.stderr
        assert path.stat().st_mode & 0o777 == 0o600, oct(path.stat().st_mode)


@pytest.fixture
def far(served: tuple[str, Filter]) -> Iterator[str]:
    """A second served deployer, joining the first's name service, hosting a Hoarder."""
    ns, _ = served
    deployer = Deployer()
    deployer.add(Hoarder("hoard"))
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0", ns=ns)
    try:
        yield ns
    finally:
        server.stop()
        deployer.stop_all()


def test_connecting_again_over_another_transport_says_so_and_disconnect_counts(far: str) -> None:
    ns = far
    made = scart(ns, "connect", "Filter.ticks", "hoard.inp", "--policy", "buffer:1000", "--transport", "ipc",
                 "--name", "feed")
    assert made.returncode == 0 and made.stdout.strip() == \
        "connected Filter.ticks -> hoard.inp (buffer:1000, ipc) as feed", made
    again = scart(ns, "connect", "Filter.ticks", "hoard.inp", "--policy", "buffer:1000", "--transport", "grpc",
                  "--name", "feed2")
    assert again.returncode == 0, again.stderr
    assert again.stdout.strip() == ("connected Filter.ticks -> hoard.inp (buffer:1000, grpc) as feed2: "
                                    "transport changed from ipc to grpc; renamed from feed to feed2")  # not "data to data"

    def written() -> int:
        links = json.loads(scart(ns, "links", "--json").stdout)
        return next((lk["samples"] for lk in links if lk["name"] == "feed2"), 0)

    wait_until(lambda: written() >= 10, timeout=20, interval=0.2, message="nothing went over the link")
    gone = scart(ns, "disconnect", "feed2")
    assert gone.returncode == 0, gone.stderr
    said = re.fullmatch(r"disconnected: (\d+) sample\(s\) written were never delivered", gone.stdout.strip())
    assert said is not None and int(said[1]) >= 10, gone.stdout  # the sink read none of them


def test_a_stream_to_zenoh_uses_the_deployer_s_own_session() -> None:
    """``scart stream w.out zenoh:KEY`` against a deployer started with ``--zenoh`` said "run
    the deployer with --zenoh": its session was never handed to streams."""
    pytest.importorskip("zenoh")
    from dataflow.transports.zenoh import open_session
    from support.remote import address_of, start_scart, stop_process

    proc, line = start_scart(["deploy", "support.remote:Pinger", "--name", "zp", "--period", "0.02",
                              "--ns", "127.0.0.1:0", "--zenoh"], ready="serving")
    client = None
    try:
        endpoint, address = line.rpartition("listening on ")[2], address_of(line)
        client = open_session(connect=[endpoint], mode="client")
        got: list[object] = []
        subscriber = client.declare_subscriber("robot/ticks", got.append)
        made = scart(address, "stream", "zp.ticks", "zenoh:robot/ticks")
        assert made.returncode == 0, made.stderr
        assert "run the deployer with --zenoh" not in made.stderr
        wait_until(lambda: len(got) >= 2, timeout=15, message="nothing published on robot/ticks")
        subscriber.undeclare()
    finally:
        if client is not None:
            client.close()
        assert stop_process(proc) == 0


def test_a_server_echoes_a_bounded_part_of_a_huge_name(served: tuple[str, Filter]) -> None:
    """A 3 MB port name came back whole in the error, past gRPC's metadata limit: the
    client then saw "Stream removed" instead of the reason."""
    from dataflow import NotFoundError
    from dataflow.remote import connect

    ns, _ = served
    with connect(ns) as system:
        with pytest.raises(NotFoundError) as refused:
            system.component("Filter").write("y" * 3_000_000, 1.0)
    said = str(refused.value)
    assert len(said) < 4000 and "characters left out" in said and "ports:" in said, said[:300]
