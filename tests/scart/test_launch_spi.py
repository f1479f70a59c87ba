"""What an extension adds to ``scart run``, ``validate`` and ``graph`` through a
:class:`scart.spi.LaunchProvider` (Tuscany's providers' way): its own options and
settings, the names its components run under, its graph edges and what it serves beside
a run. The core names none of them; a provider given to a registry takes part as the
data-flow extension does through its entry point."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence

import pytest
from pydantic import BaseModel, ConfigDict

import scart
from scart.assembly import assemble
from scart.commands._composite import add_launch_options, run_names, settings_of
from scart.commands.graph import to_dot
from scart.commands.run import _Extras, summary
from scart.spi import (
    AssemblyView, GraphEdge, GraphNode, LaunchContext, Launched, LaunchProvider, Settings, Verb,
)
from support import ROOT

CALCULATOR = ROOT / "composites" / "calculator" / "calculator.composite"


class Loud(BaseModel):
    model_config = ConfigDict(frozen=True)
    level: int = 1
    verb: str = ""


class Shouting(Launched):
    def __init__(self, level: int) -> None:
        self.level, self.log = level, []

    def start(self) -> None:
        if self.level > 9:
            raise scart.ScartError(f"--level {self.level}: too loud")
        self.log.append("start")

    def stop(self) -> None:
        self.log.append("stop")

    def addresses(self) -> dict[str, str]:
        return {"shouting": f"level {self.level}"}

    def notes(self) -> list[str]:
        return ["ears covered"]


class LoudLaunch(LaunchProvider):
    name = "loud"

    def __init__(self) -> None:
        self.launched: list[Shouting] = []

    def add_arguments(self, parser: argparse.ArgumentParser, verb: Verb) -> None:
        parser.add_argument("--level", type=int, default=1)

    def settings(self, args: argparse.Namespace, verb: Verb, environ: Mapping[str, str]) -> Loud:
        if args.level < 0:
            raise ValueError(f"--level {args.level}: expected 0 or more")
        return Loud(level=args.level, verb=verb)

    def names(self, assembly: AssemblyView, settings: Settings) -> Mapping[str, str]:
        return {path: path.upper() for path in assembly.nodes if path.startswith("Add")}

    def graph(self, assembly: AssemblyView, settings: Settings) -> Sequence[GraphNode | GraphEdge]:
        level = settings.extension(Loud).level
        return [GraphNode("speaker", f"level {level}", shape="ellipse"),
                GraphEdge("speaker", "AddServiceComponent", "shouts", style="dotted", color="red")]

    def launch(self, context: LaunchContext) -> Launched:
        self.launched.append(Shouting(context.settings.extension(Loud).level))
        return self.launched[-1]


def _registry(provider: LaunchProvider) -> scart.ExtensionRegistry:
    return scart.ExtensionRegistry().with_providers(provider)


def test_options_and_settings_come_from_the_provider(capsys: pytest.CaptureFixture[str]) -> None:
    registry = _registry(LoudLaunch())
    parser = argparse.ArgumentParser()
    add_launch_options(parser, "validate", registry)
    settings = settings_of(parser.parse_args(["--level", "3"]), "validate", registry)
    assert settings is not None and settings.extension(Loud) == Loud(level=3, verb="validate")
    assert settings_of(parser.parse_args(["--level", "-1"]), "validate", registry) is None
    assert "scart: --level -1: expected 0 or more" in capsys.readouterr().err


def test_names_and_graph_edges_come_from_the_provider() -> None:
    registry = _registry(LoudLaunch())
    settings = Settings().with_extension(Loud(level=7))
    assembly = assemble(str(CALCULATOR), extensions=registry, settings=settings)
    assert run_names(assembly, settings) == {"AddServiceComponent": "ADDSERVICECOMPONENT"}
    dot = to_dot(assembly, settings)
    assert 'label="ADDSERVICECOMPONENT\\n[AddService]"' in dot
    assert '"speaker" [shape=ellipse, label="level 7"];' in dot
    assert '"speaker" -> "AddServiceComponent" [style=dotted, color=red, label="shouts"];' in dot
    said = summary(assembly, {}, run_names(assembly, settings))
    assert "component AddServiceComponent (runs as ADDSERVICECOMPONENT)" in said


@pytest.mark.parametrize("level", [2, 10])
def test_what_a_provider_serves_starts_after_the_composite_and_stops_before(level: int) -> None:
    provider = LoudLaunch()
    settings = Settings().with_extension(Loud(level=level))
    with scart.Runtime.from_file(CALCULATOR, settings=settings, extensions=_registry(provider)) as rt:
        extras = _Extras(rt, settings)
        problem = extras.start(argparse.Namespace(services="off"))
        if level > 9:  # refused: said in one line naming the option, nothing kept running
            assert problem == "--level 10: too loud"
            assert not any(isinstance(x, Shouting) for x in extras.launched)
        else:
            assert problem == "" and provider.launched[0].log == ["start"]
            assert provider.launched[0].addresses() == {"shouting": "level 2"}
        extras.stop()
    assert provider.launched[0].log == ([] if level > 9 else ["start", "stop"])


def test_a_runtime_without_settings_reads_each_providers_own_from_the_environment() -> None:
    class EnvLaunch(LoudLaunch):
        def from_env(self, environ: Mapping[str, str]) -> Loud:
            return Loud(level=int(environ.get("LOUD_LEVEL", "1")))

    settings = _registry(EnvLaunch()).settings_from_env({"LOUD_LEVEL": "5"})
    assert settings.extension(Loud).level == 5
