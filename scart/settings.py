"""The settings of one runtime: what it and every extension it loads are configured with.

A :class:`Settings` is a frozen value handed to ``Runtime.from_file(path, settings=...)``;
the runtime gives it to every extension (``host.settings``) and component
(``ComponentContext.settings``). Nothing in scart reads configuration from a module
global: ``scart run --ns`` fills a ``Settings``, and :meth:`Settings.from_env` reads the
environment variables (``SCART_NS``) for callers that want them.

==============  ===========================================================================
field           meaning
==============  ===========================================================================
``ns``          the name service of data-flow tasks, ``HOST:PORT``; None: the default
                ``127.0.0.1:7850`` (:attr:`ns_address` resolves it)
``serve``       serve the composite's data-flow tasks over gRPC at start, with a name
                service embedded at :attr:`ns_address` or joined there (``scart run``)
``online``      load-time checks may ask a running name service (``scart validate
                --online``); off by default: loading never touches the network
``timeout``     deadline (s) of a remote call an extension makes on the runtime's behalf
``security``    TLS files, the token to send, the auth file to check
                (:class:`dataflow.remote.Security`): every gRPC server and client the
                runtime's extensions make uses it
``remap``       names of data-flow tasks and ports changed at launch (:class:`Remap`,
                ``scart run --remap FROM=TO``)
==============  ===========================================================================
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence

from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from scart_wire.defaults import DEFAULT_NS_ADDRESS, NS_ENV
from scart_wire.security import Security
from scart.errors import ScartError

__all__ = ["Remap", "Settings"]

_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_./-]{0,255}")
MAX_REMAP_RULES = 256


class Remap(BaseModel):
    """Names changed at launch, as ROS 2 remapping does: ``FROM=TO`` (or ``FROM:=TO``) rules.

    * ``youBotDriver=left/youBotDriver`` renames the task (or bridge) ``youBotDriver``;
    * ``jointStatus=joint_states`` renames every port called ``jointStatus``;
      ``youBotDriver.jointStatus=joint_states`` only that task's;
    * ``__ns=left`` puts every task name not renamed otherwise under ``left/``.

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


class Settings(BaseModel):
    """Runtime configuration (see the module docstring). Frozen; copy with ``model_copy(update=...)``."""

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)

    ns: str | None = None
    serve: bool = False
    online: bool = False
    timeout: float = 2.0
    security: Security = Security()
    remap: Remap = Remap()

    @field_validator("ns")
    @classmethod
    def _host_port(cls, value: str | None) -> str | None:
        from scart.spi import parse_host_port, port_in_range

        if value is None:
            return None
        parsed = parse_host_port(value.strip())
        if parsed is None or not port_in_range(parsed[1], zero_ok=True):
            raise ValueError(f'name service {value!r}: expected "host:port" (port 0..65535)')
        return value.strip()

    @field_validator("timeout")
    @classmethod
    def _finite(cls, value: float) -> float:
        if not (math.isfinite(value) and 0 < value <= 3600):
            raise ValueError(f"timeout {value!r}: expected seconds in (0, 3600]")
        return value

    @property
    def ns_address(self) -> str:
        """The name service to use: ``ns``, else the default address."""
        return self.ns or DEFAULT_NS_ADDRESS

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None, **fields: object) -> Settings:
        """Settings with ``ns`` from ``SCART_NS`` and ``security`` from the ``SCART_TLS_*``,
        ``SCART_TOKEN`` and ``SCART_AUTH_FILE`` variables (when not given in ``fields``).

        Raises :class:`~scart.errors.ScartError` naming the variable (or the field) and
        what is wrong with its value."""
        env = os.environ if environ is None else environ
        source = "settings"
        if "ns" not in fields and env.get(NS_ENV, "").strip():
            fields["ns"] = env[NS_ENV].strip()
            source = f"${NS_ENV}"
        if "security" not in fields:
            fields["security"] = Security.from_env(env)
        try:
            return cls(**fields)  # type: ignore[arg-type]
        except ValidationError as exc:
            first = exc.errors()[0]
            where = source if first["loc"] == ("ns",) else ".".join(map(str, first["loc"]))
            raise ScartError(f"{where}: {first['msg'].removeprefix('Value error, ')}") from None
