"""The ``<scart:frames>`` composite element: the process's frame tree served, and joined to ROS::

    <scart:frames ros1="true" ros2="false" cache="10">
        <scart:frame parent="base_link" child="laser" xyz="0.3 0 -0.03" rpy="0 0 0"/>
        <scart:frame parent="base_link" child="camera" xyz="0.1 0 0.4" quaternion="0 0 0 1"/>
    </scart:frames>

One tree per process: the runtime's :class:`dataflow.Deployer` has it (``deployer.frames``)
and every task reads and publishes through it as ``self.frames``. This element

* keeps ``cache`` seconds of history per dynamic frame (default 10, as tf2);
* adds the declared ``<scart:frame>`` s as static transforms (``xyz`` in metres, and
  ``rpy`` in radians, fixed axes as URDF, or ``quaternion`` ``x y z w``);
* hosts the tree's task, :class:`dataflow.tf.FrameServer`, named ``name`` (default
  ``tf``; remapped as tasks are), served and registered in the name service like any
  task: ``scart tf echo``, ``scart tf frames`` and other processes follow its ports;
* with ``ros1="true"`` / ``ros2="true"`` joins the tree to ROS's ``/tf`` and
  ``/tf_static`` while the composite runs (:mod:`dataflow.tf.ros`), through the process's
  one ROS 1 node (options ``master``, ``node``, ``__ns``, ``host``, ``insecure``, as a
  ros1 stream's; ``scart run --ros-master`` is its default) or ROS 2 participant
  (``domain``, ``insecure``, ``interface``, ``peers``).

Checked at load (``SCART-F001``, ``file:line``): one element per process, its attributes,
each frame's names and numbers (finite, a rotation near a unit quaternion), and the
declared frames form a tree (no frame with two parents, no cycle). Started after every
component (a task publishing in its ``start_hook`` is in the tree already), stopped
before them.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

from dataflow import DataflowError
from dataflow.tf import FrameServer, Transform, TransformError
from dataflow.tf.buffer import MAX_CACHE, FrameBuffer
from scart.bindings.dataflow._host import host_of
from scart.bindings.dataflow.settings import DataflowSettings
from scart.bindings.dataflow.task import retire
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Participant, Problem

__all__ = ["FRAMES_CODE", "FramesElement", "FramesParticipant"]

log = logging.getLogger("scart.dataflow")

FRAMES_CODE = "SCART-F001"  #: a scart:frames that cannot be made (attributes, frames, more than one)
ROS1_OPTIONS = ("master", "node", "__ns", "host", "insecure")
ROS2_OPTIONS = ("domain", "insecure", "interface", "peers")
_OWN = ("ros1", "ros2", "cache", "name")
_FRAME = ("parent", "child", "xyz", "rpy", "quaternion")


@dataclass(frozen=True)
class Frames:
    """One ``<scart:frames>`` as read."""

    name: str
    cache: float
    ros1: dict[str, str] | None
    ros2: dict[str, str] | None
    statics: tuple[Transform, ...]
    where: str


def _flag(value: str | None, what: str, problems: list[str]) -> bool:
    text = (value or "false").strip().lower()
    if text not in ("true", "false", "1", "0"):
        problems.append(f"<scart:frames> {what}={value!r}: true or false")
    return text in ("true", "1")


def _numbers(text: str, count: int, what: str, problems: list[str]) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        values = ()
    if len(values) != count or not all(map(math.isfinite, values)):
        problems.append(f"{what}={text!r}: {count} finite numbers, separated by spaces")
        return (0.0,) * count
    return values


def _frame(el: Element, problems: list[str]) -> Transform | None:
    a = el.attributes
    where = "<scart:frame>"
    unknown = sorted(k for k in a if k not in _FRAME and ":" not in k)
    if unknown:
        problems.append(f"{where}: unknown attribute(s) {', '.join(unknown)}; attributes: {', '.join(_FRAME)}")
    if "rpy" in a and "quaternion" in a:
        problems.append(f"{where}: rpy or quaternion, not both")
    before = len(problems)
    xyz = _numbers(a.get("xyz", "0 0 0"), 3, f"{where} xyz", problems)
    if "quaternion" in a:
        q = _numbers(a["quaternion"], 4, f"{where} quaternion", problems)
        made = Transform(a.get("parent", ""), a.get("child", ""), (xyz[0], xyz[1], xyz[2]), (q[0], q[1], q[2], q[3]))
    else:
        r = _numbers(a.get("rpy", "0 0 0"), 3, f"{where} rpy", problems)
        made = Transform.from_rpy(a.get("parent", ""), a.get("child", ""), (xyz[0], xyz[1], xyz[2]), (r[0], r[1], r[2]))
    return made if len(problems) == before else None


def _parse(prefix: str, el: Element) -> tuple[Frames | None, list[tuple[Element, str]]]:
    """One element read, and its problems (each with the element it is about)."""
    a = el.attributes
    problems: list[str] = []
    ros1, ros2 = _flag(a.get("ros1"), "ros1", problems), _flag(a.get("ros2"), "ros2", problems)
    try:
        cache = float(a.get("cache") or 10.0)
        if not 0 < cache <= MAX_CACHE:
            raise ValueError
    except ValueError:
        problems.append(f"<scart:frames> cache={a.get('cache')!r}: seconds, more than 0, at most {MAX_CACHE:g}")
        cache = 10.0
    name = (a.get("name") or "tf").strip()
    if not name or len(name) > 128 or any(c.isspace() or c in "./" for c in name):
        problems.append(f"<scart:frames> name={name!r}: a task name (no space, '.' or '/', at most 128 characters)")
    unknown = sorted(k for k in a if k not in (*_OWN, *ROS1_OPTIONS, *ROS2_OPTIONS) and ":" not in k)
    if unknown:
        problems.append(f"<scart:frames>: unknown attribute(s) {', '.join(unknown)}; attributes: "
                        f"{', '.join((*_OWN, *ROS1_OPTIONS, 'domain', 'interface', 'peers'))}")
    out: list[tuple[Element, str]] = [(el, p) for p in problems]
    statics = []
    for child in el.children:
        if child.kind != "frame":
            out.append((child, f"<scart:{child.kind}> in <scart:frames>: only <scart:frame> elements"))
            continue
        found: list[str] = []
        made = _frame(child, found)
        out += [(child, p) for p in found]
        if made is not None:
            statics.append((child, made))
    out += _tree_problems(statics)
    if out:
        return None, out
    options = {k: v for k, v in a.items() if k in (*ROS1_OPTIONS, *ROS2_OPTIONS)}
    return Frames(prefix + name, cache, {k: v for k, v in options.items() if k in ROS1_OPTIONS} if ros1 else None,
                  {k: v for k, v in options.items() if k in ROS2_OPTIONS} if ros2 else None,
                  tuple(t for _, t in statics), str(el.loc)), []


def _tree_problems(statics: list[tuple[Element, Transform]]) -> list[tuple[Element, str]]:
    """What the declared frames would be refused for, in a tree of their own."""
    tree, out = FrameBuffer(), []
    for child, transform in statics:
        try:
            tree.publish(transform, static=True)
        except TransformError as exc:
            out.append((child, f"<scart:frame>: {exc}"))
    return out


def _ros_problems(spec: Frames) -> list[str]:
    """What the ROS options would be refused for when the tree joins ROS (no network)."""
    from dataflow.transports import TransportError, load

    out = []
    for name, options in (("ros1", spec.ros1), ("ros2", spec.ros2)):
        if options is None:
            continue
        try:
            transport: Any = load(name)
            if name == "ros1":
                transport.node_settings(options)
            else:
                import cyclonedds  # noqa: F401 - ROS 2 needs it: say so at load

                transport.where(options)
        except ImportError:
            out.append("<scart:frames> ros2=\"true\" needs Cyclone DDS: pip install 'scart[ros2]'")
        except (TransportError, ValueError, AttributeError) as exc:
            out.append(f"<scart:frames> {name}: {exc}")
    return out


class FramesElement(ElementProvider):
    """The ``scart:frames`` composite element (see the module docstring)."""

    name = "frames"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        out: list[Problem] = []
        for prefix, el in elements:
            found, problems = _parse(prefix, el)
            if found is not None:
                problems = [(el, msg) for msg in _ros_problems(found)]
            out += [Problem(FRAMES_CODE, msg, at.loc.path, at.loc.line) for at, msg in problems]
        for _, el in elements[1:]:
            first = elements[0][1]
            out.append(Problem(FRAMES_CODE, f"<scart:frames>: one per process (one is at {first.loc})",
                               el.loc.path, el.loc.line))
        return out

    def activate(self, host: Host) -> FramesParticipant:
        found = [f for prefix, el in host.assembly.elements_of(self.name) if (f := _parse(prefix, el)[0])]
        return FramesParticipant(found[0] if found else None, host)


class FramesParticipant(Participant):
    """Sets the runtime's tree up, adds and starts its task at start; stops it at stop."""

    def __init__(self, frames: Frames | None, host: Host) -> None:
        self.frames = frames
        self.host = host
        self.task: FrameServer | None = None

    def start(self) -> None:
        """Cache, static frames, the tree's task (joining ROS as asked). Raises
        ``DataflowError`` naming the element when the task does not start."""
        spec = self.frames
        if spec is None:
            return
        dataflow_host = host_of(self.host)
        deployer = dataflow_host.deployer
        buffer = deployer.frames
        buffer.cache_time = spec.cache
        if spec.statics:
            buffer.publish(spec.statics, static=True, authority="composite")
        remap = DataflowSettings.of(self.host.settings).remap
        task = FrameServer(remap.component(spec.name) if remap else spec.name, buffer, ros1=spec.ros1, ros2=spec.ros2)
        task.set_property("cache", spec.cache)
        deployer.add(task)
        self.task = task
        if not (task.configure() and task.start()):
            why = task.failure or f"it is {task.state.name}"
            self.stop()
            raise DataflowError(f"frames ({spec.where}): the frame tree's task {task.name} did not start: {why}")
        dataflow_host.start()
        dataflow_host.refresh()
        log.info("frames: tree served as %s (%g s kept%s)", task.name, spec.cache,
                 "".join(f", on {what}" for what, opts in (("ROS 1", spec.ros1), ("ROS 2", spec.ros2)) if opts is not None))

    def stop(self) -> None:
        """Stop the tree's task (leaving ROS); idempotent."""
        task, self.task = self.task, None
        if task is not None:
            retire(task)
