"""The data-flow extension's own settings: a frozen :class:`DataflowSettings` carried in
``scart.Settings.extensions`` (the SCA core reads none of it), read back with
:meth:`DataflowSettings.of`::

    settings = scart.Settings().with_extension(DataflowSettings(ns="127.0.0.1:7850", serve=True))
    with scart.Runtime.from_file(path, settings=settings) as rt: ...

=====================  ======================================================================
field                  meaning
=====================  ======================================================================
``ns``                 the name service of data-flow tasks (and of ``scart run``'s SCA
                       services), ``HOST:PORT``; None: the default ``127.0.0.1:7850``
                       (:attr:`~DataflowSettings.ns_address` resolves it). ``SCART_NS`` when
                       read from the environment (:meth:`DataflowSettings.from_env`)
``serve``              serve the composite's data-flow tasks over gRPC at start, with a name
                       service embedded at ``ns_address`` or joined there (``scart run``)
``listen``             where that data-flow server listens, ``HOST:PORT`` (``scart run
                       --listen``); None: the name service's address when it embeds one,
                       else a free loopback port
``remap``              names of data-flow tasks and ports changed at launch (:class:`Remap`,
                       ``--remap FROM=TO``)
``foxglove``           ``scart run --foxglove [HOST:]PORT``: also serve the tasks to Foxglove
``foxglove_control``   ``--foxglove-control [TOKEN_FILE]``: make that server writable
=====================  ======================================================================
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

from pydantic import BaseModel, ConfigDict, ValidationError, ValidationInfo, field_validator

from scart.spi import Settings, parse_host_port, port_in_range
from scart_wire.defaults import DEFAULT_NS_ADDRESS, NS_ENV

__all__ = ["DataflowSettings", "Remap"]

_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_./-]{0,255}")
MAX_REMAP_RULES = 256


class Remap(BaseModel):
    """Names changed at launch, as ROS 2 remapping does: ``FROM=TO`` (or ``FROM:=TO``) rules.

    * ``youBotDriver=left/youBotDriver`` renames the task (or bridge) ``youBotDriver``;
    * ``jointStatus=joint_states`` renames every port called ``jointStatus``;
      ``youBotDriver.jointStatus=joint_states`` only that task's;
    * ``__ns=left`` puts every task name not renamed otherwise under ``left/``, and the
      component services ``scart run`` registers with the name service too (``scart call
      left/Locomotor.move_to_pose``).

    They apply wherever the composite names a task or a port: the task's own name (so its
    name-service registration), its ports, ``scart:connect`` ends, bridge inputs and
    ``binding.dataflow`` targets, and what ``scart graph`` and ``scart run`` print. The
    composite itself is not edited: its checks see the names as written.
    """

    model_config = ConfigDict(frozen=True)

    rules: tuple[tuple[str, str], ...] = ()

    @classmethod
    def parse(cls, items: Sequence[str]) -> Remap:
        """Rules from ``FROM=TO`` / ``FROM:=TO`` texts; raises ``ValueError`` naming the bad one."""
        if len(items) > MAX_REMAP_RULES:
            raise ValueError(f"{len(items)} remap rules: at most {MAX_REMAP_RULES}")
        rules: list[tuple[str, str]] = []
        for item in items:
            old, sep, new = item.partition(":=") if ":=" in item else item.partition("=")
            old, new = old.strip(), new.strip()
            if not sep or not _NAME.fullmatch(old) or not _NAME.fullmatch(new) or new.endswith("/"):
                raise ValueError(f"--remap {item!r}: expected FROM=TO (names of letters, digits, _ . / -)")
            if old == "__ns" and "." in new:
                raise ValueError(f"--remap {item!r}: a namespace has no '.'")
            if "." in new:  # a port would keep only what follows the dot; a task name would read as COMP.PORT
                raise ValueError(f"--remap {item!r}: a new name has no '.' (a port's new name is its name alone: "
                                 f"{old}={new.rpartition('.')[2]}; a task's cannot be read apart from its ports)")
            rules.append((old, new))
        return cls(rules=tuple(rules))

    def __bool__(self) -> bool:
        return bool(self.rules)

    @property
    def namespace(self) -> str:
        """The namespace of ``__ns=NS`` (``"left"``), else ``""``: SCA services are found
        under it too (``left/Locomotor``), as tasks run under it."""
        return (self._rule("__ns") or "").strip("/")

    def _rule(self, name: str) -> str | None:
        return next((new for old, new in reversed(self.rules) if old == name), None)

    def component(self, name: str) -> str:
        """The name a task (or bridge) written ``name`` in the composite runs under."""
        new = self._rule(name)
        if new is not None:
            return new
        ns = self._rule("__ns")
        return f"{ns.strip('/')}/{name}" if ns else name

    def port(self, component: str, port: str) -> str:
        """The name port ``port`` of the task written ``component`` runs under."""
        new = self._rule(f"{component}.{port}")
        if new is None:
            new = self._rule(port)
        return new if new is not None else port

    def endpoint(self, component: str, port: str) -> tuple[str, str]:
        """``(task, port)`` as they run (both remapped)."""
        return self.component(component), self.port(component, port)


class DataflowSettings(BaseModel):
    """The data-flow extension's settings (see the module docstring). Frozen."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    ns: str | None = None
    serve: bool = False
    listen: str | None = None
    remap: Remap = Remap()
    foxglove: str | None = None
    foxglove_control: str | None = None

    @field_validator("ns", "listen")
    @classmethod
    def _host_port(cls, value: str | None, info: ValidationInfo) -> str | None:
        if value is None:
            return None
        parsed = parse_host_port(value.strip())
        if parsed is None or not port_in_range(parsed[1], zero_ok=True):
            what = "name service" if info.field_name == "ns" else "listen address"
            raise ValueError(f'{what} {value[:80]!r}: expected "host:port" (port 0..65535)')
        return value.strip()

    @property
    def ns_address(self) -> str:
        """The name service to use: ``ns``, else the default address."""
        return self.ns or DEFAULT_NS_ADDRESS

    @classmethod
    def of(cls, settings: Settings) -> DataflowSettings:
        """The data-flow settings ``settings`` carries, else the defaults."""
        return settings.extension(cls)

    @classmethod
    def from_env(cls, environ: Mapping[str, str], **fields: object) -> DataflowSettings:
        """Settings with ``ns`` from ``SCART_NS`` when not given in ``fields``; raises
        ``ValueError`` naming the variable (or the field) and what is wrong with it."""
        source = "settings"
        if "ns" not in fields and environ.get(NS_ENV, "").strip():
            fields["ns"] = environ[NS_ENV].strip()
            source = f"${NS_ENV}"
        try:
            return cls.model_validate(fields)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = source if first["loc"] == ("ns",) else ".".join(map(str, first["loc"])) or source
            raise ValueError(f"{where}: {first['msg'].removeprefix('Value error, ')}") from None

    def apply(self, settings: Settings | None = None) -> Settings:
        """``settings`` (default ``scart.Settings()``) carrying these data-flow settings."""
        return (settings if settings is not None else Settings()).with_extension(self)
