"""``scart run``'s services endpoint in the name service: found by name, not by address.

The endpoint is registered as one entry, ``sca:HOST:PORT`` (its address; ``sca:NS/HOST:PORT``
under ``--remap __ns=NS``, whose services are then named ``NS/Component/Service``), under a lease
renewed by heartbeats like a deployer's (:class:`dataflow.remote.naming.Registration`),
so it goes when the process goes. The name service is the one the runtime's tasks are
served with (embedded or joined); for a composite without tasks, the one answering at
``--ns`` (``SCART_NS``, the default), else one embedded there. Clients list these
entries apart from the tasks (:data:`dataflow.remote.naming.SCA_PREFIX`). Nothing here stops a run: a name
service that refuses (no ``admin`` token where tokens are checked) or cannot be had is
said in one line, and ``--at`` still works.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import Settings

if TYPE_CHECKING:
    from dataflow.remote.naming import NameServer, Registration

__all__ = ["Announcement"]


class Announcement:
    """The services endpoint at ``address`` registered with a name service (``served``:
    what the runtime serves, its name service among them). :meth:`start` never raises
    (:attr:`note` says what went wrong); :meth:`stop` is idempotent."""

    def __init__(self, served: Mapping[str, str], settings: Settings, address: str) -> None:
        self.served, self.settings, self.address = served, settings, address
        self.ns = ""
        self.registered = False
        self.note = ""
        self._registration: Registration | None = None
        self._nameserver: NameServer | None = None

    @property
    def ns_option(self) -> str:
        """``" --ns HOST:PORT"`` when a client needs it to find this name service, else ``""``."""
        from scart_wire.defaults import DEFAULT_NS_ADDRESS

        return "" if self.ns == DEFAULT_NS_ADDRESS else f" --ns {self.ns}"

    def start(self) -> None:
        """Register (blocks for one call, bounded by the settings' timeout)."""
        from dataflow import DataflowError
        from dataflow.remote.naming import SCA_PREFIX, Registration

        try:
            self.ns = self._name_service()
        except DataflowError as exc:
            self.note = f"SCA services not in a name service ({exc}); reach them with --at {self.address}"
            return
        namespace = DataflowSettings.of(self.settings).remap.namespace
        entry = f"{SCA_PREFIX}{namespace + '/' if namespace else ''}{self.address}"
        registration = Registration(self.ns, self.address, lambda: [entry],
                                    security=self.settings.security, timeout=self.settings.timeout)
        try:
            registration.start()
        except DataflowError as exc:
            registration.stop()
            self.note = f"SCA services not registered with the name service at {self.ns}: {exc}; " \
                        f"reach them with --at {self.address}"
            return
        self._registration, self.registered = registration, True

    def _name_service(self) -> str:
        """The name service to register with: the runtime's, a running one, or one embedded
        at the settings' address (raises ``DataflowError`` when none can be had)."""
        from dataflow.remote.naming import name_service_answers, serve_nameserver

        served = self.served.get("name service")
        if served:
            return served.split()[0]
        ns = DataflowSettings.of(self.settings).ns_address
        if name_service_answers(ns, security=self.settings.security):
            return ns
        self._nameserver = serve_nameserver(ns, security=self.settings.security)
        self.note = f"name service at {self._nameserver.listen_address} (embedded)"
        return self._nameserver.address

    def stop(self) -> None:
        """Unregister (short deadline), stop an embedded name service. Idempotent."""
        registration, self._registration = self._registration, None
        if registration is not None:
            registration.stop()
        nameserver, self._nameserver = self._nameserver, None
        if nameserver is not None:
            nameserver.stop()
