"""The settings of one runtime: what it and every extension it loads are configured with.

A :class:`Settings` is a frozen value handed to ``Runtime.from_file(path, settings=...)``;
the runtime gives it to every extension (``host.settings``) and component
(``ComponentContext.settings``). Nothing in scart reads configuration from a module
global: ``scart run`` fills a ``Settings`` from its options, and
:meth:`scart.ExtensionRegistry.settings_from_env` reads the environment variables for
callers that want them (the runtime does when it is given no settings).

It holds only what the SCA core itself reads; every extension owns its own settings, a
frozen value of its own type carried in :attr:`Settings.extensions` (the data-flow
extension's name service, serving and remapping: ``scart.bindings.dataflow.DataflowSettings``)
and read back with :meth:`Settings.extension`, as Tuscany's providers read their own
configuration:

==============  ===========================================================================
field           meaning
==============  ===========================================================================
``online``      load-time checks may ask running services (``scart validate --online``);
                off by default: loading never touches the network
``timeout``     deadline (s) of a remote call an extension makes on the runtime's behalf
``security``    TLS files, the token to send, the auth file to check
                (:class:`scart_wire.security.Security`): every gRPC server and client the
                runtime's extensions make uses it
``extensions``  the extensions' own settings, one value per type
==============  ===========================================================================
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError, field_validator, model_validator

from scart.errors import ScartError
from scart_wire.security import Security

__all__ = ["Settings"]

M = TypeVar("M", bound=BaseModel)
MAX_EXTENSIONS = 64


class Settings(BaseModel):
    """Runtime configuration (see the module docstring). Frozen; copy with
    ``model_copy(update=...)`` or :meth:`with_extension`."""

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=True)

    online: bool = False
    timeout: float = 2.0
    security: Security = Security()
    extensions: tuple[BaseModel, ...] = ()

    @model_validator(mode="before")
    @classmethod
    def _known_fields(cls, data: object) -> object:
        if isinstance(data, Mapping):
            unknown = sorted(str(k) for k in data if k not in cls.model_fields)
            if unknown:
                raise ValueError(f"{', '.join(unknown)}: not a setting of the SCA core "
                                 f"({', '.join(cls.model_fields)}); an extension's settings go in "
                                 "extensions=(...), e.g. scart.bindings.dataflow.DataflowSettings(ns=..., serve=...)")
        return data

    @field_validator("timeout")
    @classmethod
    def _finite(cls, value: float) -> float:
        if not (math.isfinite(value) and 0 < value <= 3600):
            raise ValueError(f"timeout {value!r}: expected seconds in (0, 3600]")
        return value

    @field_validator("extensions")
    @classmethod
    def _one_per_type(cls, value: tuple[BaseModel, ...]) -> tuple[BaseModel, ...]:
        kinds = [type(v) for v in value]
        if len(value) > MAX_EXTENSIONS or len(set(kinds)) != len(kinds):
            raise ValueError(f"extensions: at most one value of each type (and {MAX_EXTENSIONS} in all)")
        if any(not v.model_config.get("frozen") for v in value):
            raise ValueError("extensions: each value is a frozen pydantic model (ConfigDict(frozen=True))")
        return value

    def extension(self, kind: type[M]) -> M:
        """The settings of type ``kind`` this value carries, else ``kind()`` (its defaults)."""
        for value in self.extensions:
            if type(value) is kind:
                return value
        return kind()

    def with_extension(self, value: BaseModel) -> Settings:
        """A copy carrying ``value`` (in place of any of the same type)."""
        kept = tuple(v for v in self.extensions if type(v) is not type(value))
        return self.model_copy(update={"extensions": (*kept, value)})

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None, **fields: object) -> Settings:
        """Settings with ``security`` from the ``SCART_TLS_*``, ``SCART_TOKEN`` and
        ``SCART_AUTH_FILE`` variables (when not given in ``fields``). The extensions'
        variables are theirs to read (:meth:`scart.ExtensionRegistry.settings_from_env`).

        Raises :class:`~scart.errors.ScartError` naming the field and what is wrong with
        its value."""
        env = os.environ if environ is None else environ
        if "security" not in fields:
            fields["security"] = Security.from_env(env)
        try:
            return cls.model_validate(fields)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(map(str, first["loc"])) or "settings"
            raise ScartError(f"{where}: {first['msg'].removeprefix('Value error, ')}") from None
