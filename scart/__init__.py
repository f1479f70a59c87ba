"""scart: an SCA runtime for Python, bridged to an Orocos-style data-flow world.

The story, load -> start -> use -> stop::

    import scart

    with scart.Runtime.from_file("composites/calculator/calculator.composite") as rt:
        calc = rt.service("CalculatorServiceComponent")
        print(calc.add(3, 2))

``Runtime.from_file`` parses the composite safely, checks every assembly rule and raises
one :class:`ScdlError` listing every problem (``path:line: message [CODE]``); entering
the ``with`` creates the components and runs their ``@init`` (targets first); leaving it
runs ``@destroy`` in reverse. Components are plain classes declared with
:func:`component`, :func:`interface`, :func:`prop`, :func:`reference`,
:func:`callback`, :func:`oneway`, :func:`init` and :func:`destroy`.

A runtime is configured by a :class:`Settings` (timeouts, security, each extension's own) and runs the
extensions of its :class:`ExtensionRegistry` (found through entry points; see
:mod:`scart.spi` to write one): ``Runtime.from_file(path, settings=..., extensions=...)``.
"""

from scart.api import (
    ComponentContext,
    callback,
    component,
    context,
    destroy,
    init,
    interface,
    oneway,
    prop,
    reference,
)
from scart.errors import (
    InvocationError,
    NoCallbackError,
    Problem,
    RemoteError,
    RuntimeStateError,
    ScartError,
    ScdlError,
    ServiceNotFoundError,
    ServiceUnavailableError,
)
from scart.extensions import ExtensionError, ExtensionRegistry
from scart.runtime import Runtime, RuntimeState, ServiceProxy
from scart.settings import Settings

__all__ = [
    "ComponentContext",
    "ExtensionError",
    "ExtensionRegistry",
    "InvocationError",
    "NoCallbackError",
    "Problem",
    "RemoteError",
    "Runtime",
    "RuntimeState",
    "RuntimeStateError",
    "ScartError",
    "ScdlError",
    "ServiceNotFoundError",
    "ServiceProxy",
    "ServiceUnavailableError",
    "Settings",
    "callback",
    "component",
    "context",
    "destroy",
    "init",
    "interface",
    "oneway",
    "prop",
    "reference",
]
