"""``<scart:bridge>``: many ports → converters → one typed output, declared in the composite.

The hub / converters / output-builder shape of a generated middleware bridge, with no
generated code and with the types checked at load time::

    <scart:bridge name="statusBridge" trigger="periodic" period="0.01">
      <scart:input name="arm" from="youBotDriver.jointStatus" field="joints[*].position"/>
      <scart:input name="busy" from="locomotor.busy" missing="default" default="false"/>
      <scart:output name="summary" type="summary:ArmSummary" build="summary:make"/>
    </scart:bridge>

* **Inputs** — ``from`` is ``TASK.PORT``: a task of this composite, another bridge's
  output, or a task of another deployer found through the name service (``ns``, else the
  runtime's). ``policy`` is the connection's (``ConnPolicy.parse`` form, default
  ``data``). Each input is converted by a Python callable (``convert="mod:function"``,
  called with the sample), or by a field path (``field="joints[*].position"``: ``.name``
  a field or key, ``[N]`` an item, ``[*]`` every item; the input's own name may lead the
  path, as in ``arm.joints[*].position``), or not at all.
* **Output** — one port, ``name`` and ``type`` (``mod:Class``, or a registry name such as
  ``float64``). ``build="mod:function"`` is called with the converted inputs as keyword
  arguments (by input name); without it the type is a pydantic model whose fields are the
  inputs (by name).
* **Topics** — an input may be fed by a topic instead of a port, and the output may be
  written to one: a ``<scart:stream transport=".." topic=".." .../>`` inside the
  ``<scart:input>`` (which then takes a ``type`` and no ``from``) or the ``<scart:output>``,
  its other attributes the transport's options, as ``<scart:stream>``'s. So a bridge joins
  two middlewares by itself (a YARP port to a ROS topic: ``composites/yarp-ros/``), the
  port's type checked against each topic's at load.
* **Trigger** — ``periodic`` (every ``period`` s, the default when ``period`` is given),
  ``any`` (on any new input, the default otherwise) or ``all`` (when every input has a new
  sample and their arrival times lie within ``window`` s of each other, as
  message_filters' ApproximateTime; an older sample is dropped for a newer one). A
  ``period`` with ``any`` or ``all`` is refused (it would not apply).
* **Missing inputs** (``missing``, periodic and any-input triggers) — ``hold`` (default: the last value; no output until
  the first one), ``skip`` (no output unless this input has a new sample) or ``default``
  (the last value, and the ``default`` value, JSON, until the first sample).

**Type-checked at load time** (``file:line`` — the ``<scart:input>``'s for what concerns
one input — naming the input, the converter and both types): a converter's parameter
against its source port's type, a field path through the source's model, the builder's
parameters against the converted inputs and its return against the output type (or the
model's fields against them); a converter without type annotations is a warning. A
source of another deployer is checked when its name service answers at load time
(``settings.online``; one it does not know is then an error, and offline a warning), else
when the bridge starts: a mismatch then fails the start, naming the same things, and a
source not in the name service yet is waited for (the bridge starts when it appears).

It runs as a :class:`dataflow.TaskContext` (:class:`BridgeTask`) in the runtime's
deployer, named after the bridge, connected like ``scart:connect`` links, served and
registered like ``implementation.task`` components. ``scart describe NAME`` shows, for
each input, the age of its last sample (``INPUT.age``, seconds; null before the first)
and how many it got (``INPUT.samples``), and ``outputs``: how many were written.

The package, by what it does — the spec, the checks, the runtime: :mod:`._spec` (the
element as read); :mod:`._resolve` (the types, checked) and :mod:`._element` (the element's
load-time check); :mod:`._runtime` (the participant that runs the bridges) and
:mod:`._task` (the task a bridge runs as).
"""

from __future__ import annotations

from ._element import BridgeElement
from ._resolve import Resolved, Resolver, path_type, same_type, shown
from ._runtime import RETRY_S, BridgeParticipant
from ._spec import BRIDGE, BRIDGE_TYPE, BridgeSpec, InputSpec, TopicSpec, bridges_of, parse_bridge
from ._task import BridgeTask

__all__ = ["BRIDGE", "BRIDGE_TYPE", "RETRY_S", "BridgeElement", "BridgeParticipant", "BridgeSpec", "BridgeTask",
           "InputSpec", "Resolved", "Resolver", "TopicSpec", "bridges_of", "parse_bridge", "path_type", "same_type",
           "shown"]
