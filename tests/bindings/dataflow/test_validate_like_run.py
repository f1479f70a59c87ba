"""``scart validate`` finds what ``scart run`` would refuse, and says it the same way: task
property values (types, bounds, read-only), ``scart:connect`` ends and bridge inputs that
name nothing and are not declared external (an error with "did you mean"; a declared one
no name service knows: an error with ``--online``), names
after ``--remap``, the bridge's own rules; and a bridge whose remote source is absent
waits for it. Each case runs ``scart validate`` and ``scart run`` (or ``run --dry-run``)
in real subprocesses and compares what they print."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

import scart
from dataflow import Deployer
from dataflow.remote import serve_nameserver
from scart.bindings.dataflow import DataflowSettings, deployer_of
from support import ROOT, wait_until
from support.cli import run
from support.sca import composite, line_of, write

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]

PROBLEM = re.compile(r"^\S.*?: .*\[(?:ASM\d+|SCART-[A-Z0-9-]+)\]$")


def problems(stderr: str) -> list[str]:
    """The ``path:line: message [CODE]`` lines (warnings too) of a command's stderr."""
    return [line for line in stderr.splitlines() if PROBLEM.match(line)]


def youbot(tmp_path: Path, properties: str) -> tuple[Path, str]:
    """The youBot contribution with the driver's properties replaced by ``properties``."""
    folder = tmp_path / "youbot"
    shutil.copytree(ROOT / "composites" / "youbot", folder, ignore=shutil.ignore_patterns("__pycache__"))
    text = (folder / "youbot.composite").read_text(encoding="utf-8")
    text = text.replace('<property name="seed">0</property>', properties)
    (folder / "bad.composite").write_text(text, encoding="utf-8")
    return folder / "bad.composite", text


def validate_and_run_refuse_alike(path: Path, *extra: str) -> list[str]:
    """``scart validate`` and ``scart run`` both refuse ``path`` (exit 2, nothing started)
    with the same problem lines; those lines."""
    checked = run("validate", str(path), *extra)
    ran = run("run", str(path), *extra)
    assert checked.returncode == 2, checked.stdout + checked.stderr
    assert ran.returncode == 2 and "nothing started" in ran.stderr, ran.stdout + ran.stderr
    assert problems(checked.stderr) == problems(ran.stderr) != []
    return problems(checked.stderr)


# ---- task properties -----------------------------------------------------------------------

def test_task_property_bounds_and_read_only_are_refused_by_validate_as_by_run(tmp_path: Path) -> None:
    path, text = youbot(tmp_path, '<property name="seed">-5</property><!--seed-->\n'
                                  '        <property name="noise">-1</property><!--noise-->\n'
                                  '        <property name="period_status">hacked</property><!--status-->')
    said = validate_and_run_refuse_alike(path)
    assert said == [
        f"{path}:{line_of(text, '<!--seed-->')}: component 'youBotDriver' property 'seed': invalid value -5 for "
        "int64: Input should be greater than or equal to 0 [ASM50027]",
        f"{path}:{line_of(text, '<!--noise-->')}: component 'youBotDriver' property 'noise': invalid value -1.0 for "
        "float64: Input should be greater than or equal to 0 [ASM50027]",
        f"{path}:{line_of(text, '<!--status-->')}: component 'youBotDriver' property 'period_status': rejected "
        "'hacked': read-only: set by the driver itself [ASM50027]",
    ]


def test_task_property_values_within_bounds_validate_and_a_bad_set_is_named(tmp_path: Path) -> None:
    path, _ = youbot(tmp_path, '<property name="seed">7</property><property name="noise">0.5</property>')
    assert run("validate", str(path)).returncode == 0
    said = validate_and_run_refuse_alike(path, "--set", "youBotDriver.noise=1000")
    assert said == ["<command line>: component 'youBotDriver' property 'noise': invalid value 1000.0 for float64: "
                    "Input should be less than or equal to 100 [ASM50027]"]


# ---- scart:connect ends -------------------------------------------------------------------------

@pytest.fixture
def first_on_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """composites/first on sys.path: its Ticker, for a deployer of the test's own."""
    monkeypatch.syspath_prepend(str(ROOT / "composites" / "first"))


def first(tmp_path: Path, source: str, extra: str = "", external: str = "") -> tuple[Path, str]:
    """composites/first with its connect's source replaced (``extra`` attributes added), and
    ``external`` declared a task another process serves."""
    folder = tmp_path / "first"
    shutil.copytree(ROOT / "composites" / "first", folder, ignore=shutil.ignore_patterns("__pycache__"))
    text = (folder / "first.composite").read_text(encoding="utf-8")
    text = text.replace('from="ticker.ticks"', f'from="{source}"{extra}')
    if external:
        text = text.replace("<scart:connect ", f'<scart:external task="{external}"/>\n    <scart:connect ')
    (folder / "first.composite").write_text(text, encoding="utf-8")
    return folder / "first.composite", text


def test_a_connect_end_that_names_no_task_is_an_error_with_did_you_mean(tmp_path: Path) -> None:
    """A typo (``tikcer``) was a warning: validate exited 0 and run waited forever."""
    path, text = first(tmp_path, "tikcer.ticks")
    checked = run("validate", str(path))
    dry = run("run", "--dry-run", str(path))
    assert checked.returncode == dry.returncode == 2, (checked.stderr, dry.stderr)
    assert problems(checked.stderr) == problems(dry.stderr) == [
        f"{path}:{line_of(text, 'tikcer')}: <scart:connect> from: 'tikcer' is no task of this composite "
        "(did you mean 'ticker'?); a task another process serves is declared <scart:external task=\"tikcer\"/> "
        "[SCART-T002]"]
    for named in (first(tmp_path / "ns", "far.ticks", ' ns="127.0.0.1:7850"')[0],  # an end said to be remote
                  first(tmp_path / "declared", "far.ticks", external="far")[0]):  # a task declared external
        quiet = run("validate", str(named))
        assert quiet.returncode == 0 and problems(quiet.stderr) == [], quiet.stderr


def test_online_a_connect_end_no_name_service_knows_is_an_error(tmp_path: Path, first_on_path: None) -> None:
    ns = serve_nameserver("127.0.0.1:0")
    other = Deployer()
    try:
        path, text = first(tmp_path, "tikcer.ticks", external="tikcer")
        refused = run("validate", "--online", "--ns", ns.address, str(path))
        assert refused.returncode == 2
        at = line_of(text, 'from="tikcer')
        assert problems(refused.stderr) == [
            f"{path}:{at}: <scart:connect> from: no task 'tikcer' in this composite nor in the "
            f"name service at {ns.address} (did you mean 'ticker'?); it knows: none [SCART-T002]"]
        from first import Ticker  # a task of another deployer, registered in that name service

        other.add(Ticker("farTicker"))
        server = other.serve("127.0.0.1:0", ns=ns.address)
        try:
            known, _ = first(tmp_path / "known", "farTicker.ticks", external="farTicker")
            ok = run("validate", "--online", "--ns", ns.address, str(known))
            assert ok.returncode == 0 and problems(ok.stderr) == [], ok.stderr
        finally:
            server.stop()
    finally:
        ns.stop()


# ---- names after --remap ------------------------------------------------------------------------

def test_a_dotted_name_after_remap_is_refused_by_validate_as_by_run(tmp_path: Path) -> None:
    path, _ = first(tmp_path, "ticker.ticks")
    checked, ran = (run(verb, str(path), "--remap", "ticker=a.b") for verb in ("validate", "run"))
    assert checked.returncode == ran.returncode == 2
    assert "--remap 'ticker=a.b': a new name has no '.'" in checked.stderr
    assert checked.stderr.strip() == ran.stderr.strip()


@pytest.mark.parametrize("remap, said", [
    ("ticker=summer", "12: --remap: 'ticker' and task 'summer' would both run as 'summer'"),
])
def test_names_after_remap_are_refused_by_validate_as_by_run(tmp_path: Path, remap: str, said: str) -> None:
    path, _ = first(tmp_path, "ticker.ticks")
    lines = validate_and_run_refuse_alike(path, "--remap", remap)
    assert len(lines) == 1 and lines[0].startswith(f"{path}:{said}") and lines[0].endswith("[SCART-T004]")
    renamed = run("validate", str(path), "--remap", "ticker=left/ticker", "--remap", "ticks=out")
    assert renamed.returncode == 0, renamed.stderr


# ---- the bridge ---------------------------------------------------------------------------------

MODS = '''
from __future__ import annotations

from pydantic import BaseModel

from dataflow import OutputPort, TaskContext


class Source(TaskContext):
    value = OutputPort(float)


class Out(BaseModel):
    value: float


def double(value: float) -> float:
    return 2 * value


def loose(value):
    return value


def wrong(text: str) -> str:
    return text


def from_text(text: str) -> float:
    return float(text)
'''


def bridge(tmp_path: Path, attrs: str, convert: str = "mods:double", source: str = "src.value") -> tuple[Path, str]:
    external = "" if source.startswith("src.") else f'<scart:external task="{source.partition(".")[0]}"/>'
    text = composite(f"""
        <component name="src"><scart:implementation.task class="mods:Source"/></component>{external}
        <scart:bridge name="b"{attrs}>
          <scart:input name="value" from="{source}" convert="{convert}"/><!--INPUT-->
          <scart:output name="out" type="mods:Out"/>
        </scart:bridge>""")
    return write(tmp_path, {"b.composite": text, "mods.py": MODS}, with_components=False), text


@pytest.mark.parametrize("attrs", [' trigger="all" period="0.1"', ' trigger="any" period="0.1"'])
def test_a_bridge_period_with_an_event_trigger_is_refused(tmp_path: Path, attrs: str) -> None:
    path, text = bridge(tmp_path, attrs)
    [line] = validate_and_run_refuse_alike(path)
    assert line.startswith(f"{path}:{line_of(text, '<scart:bridge')}: <scart:bridge name='b'>: period '0.1' applies "
                           'to trigger "periodic" only')
    ok, _ = bridge(tmp_path / "ok", ' trigger="periodic" period="0.1"')
    assert run("validate", str(ok)).returncode == 0


def test_a_bridge_input_error_cites_the_input_line(tmp_path: Path) -> None:
    path, text = bridge(tmp_path, "", convert="mods:wrong")
    lines = validate_and_run_refuse_alike(path)
    assert (f"{path}:{line_of(text, '<!--INPUT-->')}: bridge 'b' input 'value': converter mods:wrong takes str, but "
            "src.value is float [SCART-B002]") in lines
    assert f"{path}:{line_of(text, '<scart:bridge')}: bridge 'b' output 'out': Out.value is float" in lines[0]


def test_a_converter_without_annotations_is_a_warning(tmp_path: Path) -> None:
    path, text = bridge(tmp_path, "", convert="mods:loose")
    checked, dry = run("validate", str(path)), run("run", "--dry-run", str(path))
    assert checked.returncode == 0 and dry.returncode == 0
    assert problems(checked.stderr) == problems(dry.stderr) == [
        f"{path}:{line_of(text, '<!--INPUT-->')}: warning: bridge 'b' input 'value': converter mods:loose has no type "
        "annotation on its parameter and return: what it is given and gives is not checked, and pydantic coerces it "
        'silently where a type is declared ("1.5" becomes 1.5); annotate it [SCART-B001]']
    annotated, _ = bridge(tmp_path / "ok", "")
    assert problems(run("validate", str(annotated)).stderr) == []


def test_a_bridge_whose_remote_source_is_absent_waits_for_it(tmp_path: Path) -> None:
    path, _ = bridge(tmp_path, ' trigger="any"', source="farSrc.value")
    ns = serve_nameserver("127.0.0.1:0")
    other = Deployer()
    servers = []
    try:
        with scart.Runtime.from_file(str(path), settings=DataflowSettings(ns=ns.address, serve=True).apply()) as rt:
            deployer = deployer_of(rt)
            assert "b" not in deployer.names()  # started: the bridge waits, the rest runs
            import mods  # the contribution's module, imported by the runtime

            other.add(mods.Source("farSrc"))
            other.configure_all()
            other.start_all()
            servers.append(other.serve("127.0.0.1:0", ns=ns.address))
            wait_until(lambda: "b" in deployer.names(), timeout=15, message="the bridge never started")
            task = deployer.task("b")
            wait_until(lambda: task.port("value").connection_count() == 1, timeout=15,
                       message="the remote input never connected")

            def came_through() -> bool:
                other.task("farSrc").port("value").write(1.5)
                return task.outputs >= 1

            wait_until(came_through, timeout=15, interval=0.05, message="nothing came through the bridge")
    finally:
        for server in servers:
            server.stop()
        other.stop_all()
        other.cleanup_all()
        ns.stop()


def test_a_remote_source_that_appears_with_the_wrong_type_is_logged_and_the_run_goes_on(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path, _ = bridge(tmp_path, ' trigger="any"', source="farSrc.value", convert="mods:from_text")
    ns = serve_nameserver("127.0.0.1:0")
    other = Deployer()
    servers = []
    try:
        with scart.Runtime.from_file(str(path), settings=DataflowSettings(ns=ns.address, serve=True).apply()) as rt:
            import mods

            other.add(mods.Source("farSrc"))  # a float port; the converter takes str
            servers.append(other.serve("127.0.0.1:0", ns=ns.address))
            wait_until(lambda: "converter mods:from_text takes str, but farSrc.value is float" in caplog.text,
                       timeout=15, message="the mismatch was not logged")
            assert "b" not in deployer_of(rt).names() and "src" in deployer_of(rt).names()
    finally:
        for server in servers:
            server.stop()
        ns.stop()


def test_runtime_from_file_logs_the_warnings(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path, _ = bridge(tmp_path, "", convert="mods:loose")
    with caplog.at_level("WARNING", logger="scart.runtime"):
        rt = scart.Runtime.from_file(str(path))
    assert "warning: bridge 'b' input 'value': converter mods:loose has no type annotation" in caplog.text
    assert [w.code for w in rt.assembly.warnings] == ["SCART-B001"]
