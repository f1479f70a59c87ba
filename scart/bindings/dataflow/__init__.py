"""The data-flow extension: Orocos-style tasks inside a composite, and SCA meeting ports.

One module per composite element, over one runtime-wide
:class:`~scart.bindings.dataflow._host.DataflowHost` (the runtime's
:class:`dataflow.Deployer`, its gRPC server and name service):

* ``<scart:implementation.task class="pkg.mod:Task" period="0.01"/>`` —
  :class:`TaskImplementation` (:mod:`~scart.bindings.dataflow.task`);
* ``<scart:connect from="a.out" to="b.in" policy="buffer:8"/>`` — :class:`ConnectElement`
  (:mod:`~scart.bindings.dataflow.connect`);
* ``<scart:binding.dataflow component="task"/>`` on a reference or a service —
  :class:`DataflowBinding` (:mod:`~scart.bindings.dataflow.binding`);
* ``<scart:bridge name="b">`` with ``<scart:input>`` s and one ``<scart:output>`` — many
  ports, converted, built into one typed output (:mod:`~scart.bindings.dataflow.bridge`);
* ``<scart:stream>`` (:mod:`~scart.bindings.dataflow.stream`), ``<scart:external>``
  (:mod:`~scart.bindings.dataflow.external`), ``<scart:rosservice>``
  (:mod:`~scart.bindings.dataflow.rosservice`), ``<scart:yarprpc>``
  (:mod:`~scart.bindings.dataflow.yarprpc`) and ``<scart:frames>``
  (:mod:`~scart.bindings.dataflow.frames`).

The ``_``-prefixed modules are the elements' shared helpers, never imported from outside
the extension.

Its settings are its own: a :class:`DataflowSettings` (name service, serving, remapping:
:mod:`scart.bindings.dataflow.settings`) carried in ``scart.Settings.extensions``; what
it adds to ``scart run``, ``validate`` and ``graph`` is :class:`DataflowLaunch`
(:mod:`scart.bindings.dataflow.launch`). With ``DataflowSettings(serve=True)`` (``scart
run`` sets it) the runtime serves its tasks over gRPC after every component started,
with a name service embedded at the settings' address, or joined there when one
answers. For programs and tests: :func:`deployer_of` (the runtime's deployer) and
:func:`bindings_of` (its ``binding.dataflow`` instances).
"""

from __future__ import annotations

from dataflow import Deployer
from scart.bindings.dataflow._host import DataflowHost, host_of
from scart.bindings.dataflow.bridge import BridgeElement, BridgeTask
from scart.bindings.dataflow.binding import DataflowBinding, DataflowReferenceBinding, DataflowServiceBinding, bindings_of
from scart.bindings.dataflow.launch import DataflowLaunch
from scart.bindings.dataflow.settings import DataflowSettings, Remap
from scart.bindings.dataflow.connect import ConnectElement, ConnectParticipant, Link
from scart.bindings.dataflow.task import TaskImplementation, TaskManager, task_interface
from scart.spi import Host

__all__ = [
    "BridgeElement", "BridgeTask", "ConnectElement", "ConnectParticipant", "DataflowBinding", "DataflowHost",
    "DataflowLaunch", "DataflowReferenceBinding", "DataflowServiceBinding", "DataflowSettings", "Link", "Remap",
    "TaskImplementation", "TaskManager", "bindings_of", "deployer_of", "host_of", "task_interface",
]


def deployer_of(runtime: Host) -> Deployer:
    """The :class:`dataflow.Deployer` hosting ``runtime``'s ``implementation.task`` components."""
    return host_of(runtime).deployer
