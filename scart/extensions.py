"""The extension registry of one runtime: which provider handles which XML element.

Providers are found through the ``scart.extensions`` entry points, by the local name of
their element; scart's own are registered the same way (``implementation.python``,
``binding.sca`` in the core; ``binding.grpc``, ``binding.dataflow``,
``implementation.task`` and ``connect`` in :mod:`scart.bindings`). A third-party package adds
a kind with one line in its ``pyproject.toml``, and no change to scart::

    [project.entry-points."scart.extensions"]
    "binding.foo" = "foo_binding:FooBinding"

An entry point names a provider class (a :class:`scart.spi.Extension` subclass, made
with no arguments) or instance. It is loaded only when a composite uses its name, so
``scart validate`` of a composite without remote bindings imports no gRPC. The kind of
a name follows its prefix: ``binding.*``, ``implementation.*``, anything else a
composite element.

What an extension adds to ``scart run``, ``validate`` and ``graph`` (its settings,
options, names, graph edges, what it serves beside a run) is a
:class:`scart.spi.LaunchProvider` in the ``scart.launch`` entry points; every one
installed takes part (:meth:`ExtensionRegistry.launch_providers`)::

    [project.entry-points."scart.launch"]
    foo = "foo_binding:FooLaunch"

A registry belongs to a runtime (``Runtime.from_file(path, extensions=...)``); tests
build their own with :meth:`ExtensionRegistry.with_providers`. Thread-safe.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Iterable, Mapping
from importlib.metadata import EntryPoint, entry_points
from types import MappingProxyType
from typing import TypeVar

from pydantic import BaseModel

from scart.errors import ScartError
from scart.settings import Settings
from scart.spi import BindingProvider, ElementProvider, Extension, ImplementationProvider, LaunchProvider

__all__ = ["ENTRY_POINT_GROUP", "LAUNCH_GROUP", "ExtensionError", "ExtensionRegistry"]

log = logging.getLogger("scart.extensions")

ENTRY_POINT_GROUP = "scart.extensions"
LAUNCH_GROUP = "scart.launch"

#: The core's own kinds, used when scart's entry points are not installed (a source tree
#: on ``sys.path``, or package metadata older than the code), so plain composites still
#: load; a warning says how to get the extensions back.
CORE_KINDS = MappingProxyType({"implementation.python": "scart.implementations:PythonImplementation",
                              "binding.sca": "scart.local:LocalBinding"})

P = TypeVar("P", bound=Extension)


class ExtensionError(ScartError):
    """An extension could not be loaded, or is not what its name says it is."""


def _kind_of(name: str) -> type[Extension]:
    if name.startswith("binding."):
        return BindingProvider
    if name.startswith("implementation."):
        return ImplementationProvider
    return ElementProvider


class ExtensionRegistry:
    """Providers by element local name (see the module docstring).

    ``providers`` are registered as given (replacing an entry point of the same name);
    ``discover=False`` ignores the entry points (only ``providers``)."""

    def __init__(self, providers: Iterable[Extension | LaunchProvider] = (), *, discover: bool = True) -> None:
        self._lock = threading.Lock()
        self._found: dict[str, EntryPoint] = _discover() if discover else {}
        self._loaded: dict[str, Extension] = {}
        self._discover_launch = discover
        self._launch: dict[str, LaunchProvider] | None = None  # read on first use
        self._given_launch: dict[str, LaunchProvider] = {}
        for provider in providers:
            self._add(provider)

    def _add(self, provider: Extension | LaunchProvider) -> None:
        if isinstance(provider, LaunchProvider):
            if not provider.name:
                raise ExtensionError(f"{type(provider).__qualname__} has no name (its scart.launch entry point's)")
            self._given_launch[provider.name] = provider
            return
        if not provider.name:
            raise ExtensionError(f"{type(provider).__qualname__} has no name (the local name of its element)")
        self._check_kind(provider.name, provider, "given")
        self._loaded[provider.name] = provider

    def with_providers(self, *providers: Extension | LaunchProvider) -> ExtensionRegistry:
        """A copy with ``providers`` added (or replacing those of the same name)."""
        copy = ExtensionRegistry(discover=False)
        with self._lock:
            copy._found = dict(self._found)
            copy._loaded = dict(self._loaded)
            copy._discover_launch = self._discover_launch
            copy._launch = None if self._launch is None else dict(self._launch)
            copy._given_launch = dict(self._given_launch)
        for provider in providers:
            copy._add(provider)
        return copy

    def names(self) -> list[str]:
        """Every name this registry knows (loaded or not), sorted."""
        with self._lock:
            return sorted(self._found.keys() | self._loaded.keys())

    def get(self, name: str) -> Extension | None:
        """The provider of ``name``, loaded on first use; None when unknown.

        Raises :class:`ExtensionError` when its entry point cannot be loaded or names
        something that is not a provider of the right kind."""
        with self._lock:
            provider = self._loaded.get(name)
            if provider is not None:
                return provider
            ep = self._found.get(name)
        if ep is None:
            return None
        provider = _load(name, ep)
        self._check_kind(name, provider, f"entry point {ep.value!r}")
        with self._lock:
            return self._loaded.setdefault(name, provider)

    def binding(self, name: str) -> BindingProvider | None:
        """The provider of ``binding.NAME`` elements, or None."""
        provider = self._typed(name, BindingProvider)
        return provider if isinstance(provider, BindingProvider) else None

    def implementation(self, name: str) -> ImplementationProvider | None:
        """The provider of ``implementation.NAME`` elements, or None."""
        provider = self._typed(name, ImplementationProvider)
        return provider if isinstance(provider, ImplementationProvider) else None

    def element(self, name: str) -> ElementProvider | None:
        """The provider of ``<scart:NAME>`` composite children, or None."""
        provider = self._typed(name, ElementProvider)
        return provider if isinstance(provider, ElementProvider) else None

    def known(self, kind: type[Extension]) -> list[str]:
        """The names of ``kind`` this registry knows (by prefix; nothing is loaded), sorted."""
        return [n for n in self.names() if _kind_of(n) is kind]

    def launch_providers(self) -> list[LaunchProvider]:
        """Every launch provider, by name: the ``scart.launch`` entry points (read and
        loaded once per registry) and those given. One that cannot be loaded, or is not a
        :class:`~scart.spi.LaunchProvider` of its name, is left out with a warning: a
        broken plug-in never stops the others' verbs."""
        with self._lock:
            if self._launch is None:
                self._launch = _load_launch() if self._discover_launch else {}
            found = {**self._launch, **self._given_launch}
        return [found[name] for name in sorted(found)]

    def settings_from_env(self, environ: Mapping[str, str] | None = None, **fields: object) -> Settings:
        """:meth:`Settings.from_env` with every launch provider's own settings read from
        the environment too (``SCART_NS`` for the data-flow extension's name service):
        what a runtime made without settings runs with. Raises
        :class:`~scart.errors.ScartError` naming the variable and what is wrong with it."""
        env = os.environ if environ is None else environ
        if "extensions" not in fields:
            found: list[BaseModel] = []
            for provider in self.launch_providers():
                try:
                    value = provider.from_env(env)
                except ValueError as exc:
                    raise ScartError(str(exc)) from None
                if value is not None:
                    found.append(value)
            fields["extensions"] = tuple(found)
        return Settings.from_env(env, **fields)

    def _typed(self, name: str, kind: type[Extension]) -> Extension | None:
        if _kind_of(name) is not kind:
            return None
        provider = self.get(name)
        return provider if isinstance(provider, kind) else None

    @staticmethod
    def _check_kind(name: str, provider: object, where: str) -> None:
        kind = _kind_of(name)
        if not isinstance(provider, kind):
            raise ExtensionError(f"extension {name!r} ({where}) is a {type(provider).__qualname__}, "
                                 f"not a scart.spi.{kind.__name__}")
        if getattr(provider, "name", None) != name:
            raise ExtensionError(f"extension {name!r} ({where}) says its name is {provider.name!r}")


def _discover() -> dict[str, EntryPoint]:
    found: dict[str, EntryPoint] = {}
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: (e.name, e.value)):
        if ep.name in found and found[ep.name].value != ep.value:
            log.warning("extension %r is provided twice (%s and %s); using %s", ep.name, found[ep.name].value,
                        ep.value, found[ep.name].value)
            continue
        found.setdefault(ep.name, ep)
    missing = [name for name in CORE_KINDS if name not in found]
    if missing:
        log.warning("scart's own entry points are not installed (%s missing): only the core kinds are "
                    "available; install scart (pip install -e .) for binding.grpc, implementation.task and "
                    "the other extensions", ", ".join(missing))
        found.update((name, EntryPoint(name, CORE_KINDS[name], ENTRY_POINT_GROUP)) for name in missing)
    return found


def _load_launch() -> dict[str, LaunchProvider]:
    found: dict[str, LaunchProvider] = {}
    for ep in sorted(entry_points(group=LAUNCH_GROUP), key=lambda e: (e.name, e.value)):
        if ep.name in found:
            continue
        try:
            obj = ep.load()
            provider = obj() if isinstance(obj, type) else obj
        except Exception as exc:  # noqa: BLE001 - a broken plug-in: said, the others go on
            log.warning("launch provider %r (%s) not loaded: %s: %s", ep.name, ep.value, type(exc).__name__, exc)
            continue
        if not isinstance(provider, LaunchProvider) or provider.name != ep.name:
            log.warning("launch provider %r (%s) is a %s named %r, not a scart.spi.LaunchProvider of that name; "
                        "left out", ep.name, ep.value, type(provider).__qualname__, getattr(provider, "name", None))
            continue
        found[ep.name] = provider
    return found


def _load(name: str, ep: EntryPoint) -> Extension:
    try:
        obj = ep.load()
        return obj() if isinstance(obj, type) else obj
    except Exception as exc:
        dist = getattr(getattr(ep, "dist", None), "name", None) or "?"
        raise ExtensionError(f"extension {name!r} (entry point {ep.value!r} of {dist}) cannot be loaded: "
                             f"{type(exc).__name__}: {exc}") from exc
