"""ROS's own tf2 (Debian's python3-tf2-ros) as the frames tests' judge, run with the system Python.

Not collected by pytest (no ``test_`` prefix). One JSON object per line on stdout, flushed;
commands, one JSON object per line, on stdin. Usage::

    tf2_peer.py broadcast SUBSCRIBERS   # a rospy node with tf2_ros' broadcasters and a Buffer
    tf2_peer.py listen                   # a rospy node with a TransformListener only

``broadcast`` says ``{"ready": ...}``, waits until ``/tf`` has SUBSCRIBERS connections, sends
the statics and STAMPS stamps of a 4-frame tree with two moving joints (world → base →
arm, base → sensor), waits until its own Buffer holds them, and says ``{"sent": ...}``.
Then, for each command:

* ``{"lookup": [target, source, time_ns]}`` or ``{"full": [target, t_ns, source, s_ns,
  fixed]}``: tf2_ros' answer, ``{"t": [x, y, z], "q": [x, y, z, w], "stamp": ns}`` or
  ``{"error": "ExceptionName: text"}``;
* ``{"bad": true}``: publishes what a frame tree should refuse (NaN, a rotation far from
  unit, a second parent, a cycle), then says ``{"bad": ...}`` with what tf2 made of it;
* ``{"quit": true}``: ends.

``listen`` answers ``lookup`` commands from what its TransformListener heard (with a
5 s timeout). Each process ends by itself after 120 s.
"""

import json
import math
import sys
import time

import rospy
import tf2_ros
from geometry_msgs.msg import TransformStamped

DEADLINE = time.monotonic() + 120.0
T0 = 1000  # s: the first stamp (any stamp works: tf2 keeps 10 s before its newest)
STEP_NS = 50_000_000
STAMPS = 40


def say(**what):
    print(json.dumps(what), flush=True)


def stamped(parent, child, xyz, q, stamp_ns):
    t = TransformStamped()
    t.header.stamp = rospy.Time(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)
    t.header.frame_id, t.child_frame_id = parent, child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = xyz
    t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w = q
    return t


def unit(x, y, z, w):
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return (x / n, y / n, z / n, w / n)


def joints(k):
    """The moving joints at stamp k: the base drives and turns, the arm swings about a tilted axis."""
    stamp = T0 * 1_000_000_000 + k * STEP_NS
    a, b = 0.07 * k, 0.13 * k - 0.4
    base = stamped("world", "base", (0.5 * math.cos(a), 0.3 * math.sin(a), 0.01 * k),
                   (0.0, 0.0, math.sin(a / 2), math.cos(a / 2)), stamp)
    arm = stamped("base", "arm", (0.2, -0.1, 0.4 + 0.02 * math.sin(b)),
                  unit(0.3 * math.sin(b / 2), 0.8 * math.sin(b / 2), 0.1 * math.sin(b / 2), math.cos(b / 2)), stamp)
    return [base, arm]


def answer(call):
    try:
        t = call()
    except tf2_ros.TransformException as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    tr, q = t.transform.translation, t.transform.rotation
    return {"t": [tr.x, tr.y, tr.z], "q": [q.x, q.y, q.z, q.w], "stamp": t.header.stamp.to_nsec()}


def ns(value):
    return rospy.Time(int(value) // 1_000_000_000, int(value) % 1_000_000_000)


def serve(buffer, timeout, bad=None):
    for line in sys.stdin:
        if time.monotonic() > DEADLINE:
            return
        command = json.loads(line)
        if "quit" in command:
            return
        if "lookup" in command:
            target, source, when = command["lookup"]
            say(**answer(lambda: buffer.lookup_transform(target, source, ns(when), rospy.Duration(timeout))))
        elif "full" in command:
            target, tt, source, st, fixed = command["full"]
            say(**answer(lambda: buffer.lookup_transform_full(target, ns(tt), source, ns(st), fixed)))
        elif "bad" in command and bad is not None:
            say(bad=bad())


def broadcast(subscribers):
    buffer = tf2_ros.Buffer(debug=False)
    listener = tf2_ros.TransformListener(buffer)
    dynamic, static = tf2_ros.TransformBroadcaster(), tf2_ros.StaticTransformBroadcaster()
    say(ready=rospy.get_name())
    while dynamic.pub_tf.get_num_connections() < int(subscribers) and time.monotonic() < DEADLINE:
        time.sleep(0.01)
    static.sendTransform([stamped("base", "sensor", (0.1, 0.0, 0.3), unit(0.0, 0.2, 0.0, 1.0), 0)])
    for k in range(STAMPS):
        dynamic.sendTransform(joints(k))
        time.sleep(0.003)
    last = ns(T0 * 1_000_000_000 + (STAMPS - 1) * STEP_NS)
    ok = buffer.can_transform("world", "arm", last, rospy.Duration(20)) and \
        buffer.can_transform("sensor", "world", last, rospy.Duration(20))
    say(sent=STAMPS, ok=ok, first=T0 * 1_000_000_000, step=STEP_NS)

    def bad():
        stamp = T0 * 1_000_000_000 + (STAMPS - 1) * STEP_NS
        dynamic.sendTransform([stamped("world", "nan_frame", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, float("nan")), stamp)])
        dynamic.sendTransform([stamped("world", "long_frame", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 2.0), stamp)])
        dynamic.sendTransform([stamped("sensor", "arm", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), stamp)])
        dynamic.sendTransform([stamped("arm", "world", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), stamp)])
        time.sleep(0.5)
        return {name: buffer.can_transform("world", name, ns(stamp)) for name in ("nan_frame", "long_frame")}

    serve(buffer, 0.0, bad)
    del listener


def listen():
    buffer = tf2_ros.Buffer(debug=False)
    listener = tf2_ros.TransformListener(buffer)
    say(ready=rospy.get_name())
    serve(buffer, 5.0)
    del listener


if __name__ == "__main__":
    role, args = sys.argv[1], sys.argv[2:]
    rospy.init_node(f"tf2_{role}", anonymous=True, disable_signals=False)
    {"broadcast": broadcast, "listen": listen}[role](*args)
