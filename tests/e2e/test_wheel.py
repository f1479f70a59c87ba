"""scart as a user installs it: the built wheel, non-editable, in a fresh virtualenv, used
from a folder outside the checkout — plus a third-party extension package that adds
``binding.foo`` through an entry point alone.

One module-scoped fixture builds the wheel and the virtualenv (the slow part: pip
installs the dependencies, from its cache when it has them); the tests then run the
installed ``scart`` and ``python`` of that virtualenv in subprocesses, with every wait
bounded, never a sleep.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from support import DATA, ROOT, free_port
from support.cli import finish, read_until

pytestmark = pytest.mark.subprocess

PIP_TIMEOUT = 600


class Venv:
    """A fresh virtualenv with the scart wheel installed; runs its programs in ``workdir``."""

    def __init__(self, root: Path, workdir: Path) -> None:
        self.root = root
        self.workdir = workdir
        self.bin = root / "bin"

    def env(self) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "SCART_NS", "VIRTUAL_ENV")}
        env["PATH"] = f"{self.bin}{os.pathsep}{env.get('PATH', '')}"
        env["PYTHONPATH"] = str(self.workdir)  # the user's own modules (tasks, components)
        return env

    def run(self, *args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
        return subprocess.run(list(args), cwd=self.workdir, env=self.env(), capture_output=True, text=True,
                              timeout=timeout)

    def popen(self, *args: str) -> subprocess.Popen[bytes]:
        return subprocess.Popen(list(args), cwd=self.workdir, env=self.env(), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, bufsize=0)

    def python(self, code: str) -> subprocess.CompletedProcess[str]:
        return self.run(str(self.bin / "python"), "-c", code)


def _pip(*args: str) -> None:
    out = subprocess.run([*args, "--disable-pip-version-check", "-q"], capture_output=True, text=True,
                         timeout=PIP_TIMEOUT)
    assert out.returncode == 0, f"{' '.join(args)}:\n{out.stdout}\n{out.stderr}"


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Venv]:
    base = tmp_path_factory.mktemp("wheel")
    source = base / "source"  # a clean copy: the build never writes into the checkout
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(
        ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", "test-artifacts", ".pytest_cache"))
    _pip(sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", str(base / "dist"), str(source))
    (wheel,) = (base / "dist").glob("scart-*.whl")
    subprocess.run([sys.executable, "-m", "venv", str(base / "venv")], check=True, timeout=120)
    pip = str(base / "venv" / "bin" / "pip")
    _pip(pip, "install", str(wheel))
    _pip(pip, "install", "--no-deps", str(source / DATA.relative_to(ROOT) / "foo_binding"))  # from the copy too
    work = base / "work"  # outside the checkout, as a user's project folder
    work.mkdir()
    yield Venv(base / "venv", work)


def test_the_wheel_is_installed_not_the_checkout(venv: Venv) -> None:
    out = venv.python("import scart, dataflow.remote, scart_wire.proto; print(scart.__file__, scart_wire.proto.__file__)")
    assert out.returncode == 0, out.stderr
    assert str(venv.root) in out.stdout and str(ROOT) not in out.stdout


def test_scart_help_answers(venv: Venv) -> None:
    out = venv.run(str(venv.bin / "scart"), "--help")
    assert out.returncode == 0, out.stderr
    assert "validate" in out.stdout and "echo" in out.stdout and out.stderr == ""


def test_the_calculator_runs_through_the_runtime(venv: Venv) -> None:
    shutil.copytree(ROOT / "composites" / "calculator", venv.workdir / "calculator")
    out = venv.python("import scart\n"
                      "with scart.Runtime.from_file('calculator/calculator.composite') as rt:\n"
                      "    print(rt.service('CalculatorServiceComponent').add(3, 2))")
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "5"


TICKER = '''
from dataflow import OutputPort, TaskContext


class Ticker(TaskContext):
    count = OutputPort(int)

    def configure_hook(self) -> bool:
        self.n = 0
        return True

    def update_hook(self) -> None:
        self.n += 1
        self.count.write(self.n)
'''


def test_deploy_ls_echo_round_trip(venv: Venv) -> None:
    (venv.workdir / "ticker.py").write_text(TICKER, encoding="utf-8")
    ns = f"127.0.0.1:{free_port()}"
    scart = str(venv.bin / "scart")
    deploy = venv.popen(scart, "deploy", "ticker:Ticker@ticker", "--period", "0.01", "--ns", ns)
    try:
        read_until(deploy, "scart deploy: serving ticker", timeout=60)
        listed = venv.run(scart, "ls", "--ns", ns, "--json")
        assert listed.returncode == 0, listed.stderr
        assert '"name": "ticker"' in listed.stdout and '"state": "RUNNING"' in listed.stdout
        echoed = venv.run(scart, "echo", "ticker.count", "-n", "1", "--ns", ns, "--json")
        assert echoed.returncode == 0, echoed.stderr
        assert int(echoed.stdout.strip()) >= 1
    finally:
        deploy.send_signal(signal.SIGINT)
        finish(deploy)
    assert deploy.returncode == 0


FOO_COMPOSITE = '''<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912"
           xmlns:scart="urn:scart:1.0" xmlns:foo="urn:foo" targetNamespace="urn:t" name="Foo">
    <component name="Calc">
        <scart:implementation.python class="calculator:CalculatorServiceImpl"/>
        <reference name="add_service"><foo:binding.foo uri="Add" journal="{journal}"/></reference>
        <reference name="subtract_service" target="Sub"/>
        <reference name="multiply_service" target="Mul"/>
        <reference name="divide_service" target="Div"/>
    </component>
    <component name="Add"><scart:implementation.python class="operations:AddServiceImpl"/></component>
    <component name="Sub"><scart:implementation.python class="operations:SubtractServiceImpl"/></component>
    <component name="Mul"><scart:implementation.python class="operations:MultiplyServiceImpl"/></component>
    <component name="Div"><scart:implementation.python class="operations:DivideServiceImpl"/></component>
</composite>
'''


def test_a_third_party_binding_is_found_by_its_entry_point(venv: Venv) -> None:
    folder = venv.workdir / "foo"
    shutil.copytree(ROOT / "composites" / "calculator", folder)
    journal = folder / "journal.txt"
    (folder / "foo.composite").write_text(FOO_COMPOSITE.format(journal=journal), encoding="utf-8")
    (folder / "bad.composite").write_text(FOO_COMPOSITE.replace(' journal="{journal}"', ""), encoding="utf-8")
    out = venv.python("import scart\n"
                      "with scart.Runtime.from_file('foo/foo.composite') as rt:\n"
                      "    print(rt.service('Calc').add(3, 2))")
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "5"
    assert journal.read_text(encoding="utf-8") == "add(3, 2) -> 5\n"
    bad = venv.run(str(venv.bin / "scart"), "validate", "foo/bad.composite")
    assert bad.returncode == 2 and "binding.foo needs a 'journal' attribute [FOO-001]" in bad.stderr
