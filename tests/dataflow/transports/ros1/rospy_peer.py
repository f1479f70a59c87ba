"""A rospy node the ROS 1 tests run with the system Python (Debian's python3-rospy).

Not collected by pytest (no ``test_`` prefix). Usage, one role per process::

    rospy_peer.py pub TOPIC COUNT RATE_HZ      # std_msgs/Int64 data = 0..COUNT-1, then waits
    rospy_peer.py sub TOPIC COUNT              # prints "got N" per std_msgs/Int64, exits after COUNT
    rospy_peer.py serve SERVICE                # roscpp/GetLoggers: answers one logger "scart.test"
    rospy_peer.py call SERVICE                 # calls roscpp/GetLoggers twice on one persistent
                                               # connection, prints the names each time

Each prints "ready" once registered, flushes every line, and ends by itself (a deadline
of 60 s) or at SIGTERM.
"""

import sys
import time

import rospy
from roscpp.msg import Logger
from roscpp.srv import GetLoggers, GetLoggersResponse
from std_msgs.msg import Int64

DEADLINE = time.monotonic() + 60.0


def say(text):
    print(text, flush=True)


def pub(topic, count, rate):
    publisher = rospy.Publisher(topic, Int64, queue_size=10, tcp_nodelay=True)
    say("ready")
    while publisher.get_num_connections() == 0 and time.monotonic() < DEADLINE and not rospy.is_shutdown():
        time.sleep(0.01)
    time.sleep(0.2)  # the subscriber's side of the handshake settles
    for i in range(int(count)):
        publisher.publish(Int64(data=i))
        time.sleep(1.0 / float(rate))
    say("done")
    while time.monotonic() < DEADLINE and not rospy.is_shutdown():
        time.sleep(0.05)


def sub(topic, count):
    got = []

    def callback(msg):
        got.append(msg.data)
        say(f"got {msg.data}")

    rospy.Subscriber(topic, Int64, callback, tcp_nodelay=True)
    say("ready")
    while len(got) < int(count) and time.monotonic() < DEADLINE and not rospy.is_shutdown():
        time.sleep(0.01)


def serve(service):
    rospy.Service(service, GetLoggers, lambda req: GetLoggersResponse(loggers=[Logger(name="scart.test", level="info")]))
    say("ready")
    while time.monotonic() < DEADLINE and not rospy.is_shutdown():
        time.sleep(0.05)


def call(service):
    rospy.wait_for_service(service, timeout=20)
    proxy = rospy.ServiceProxy(service, GetLoggers, persistent=True)
    for _ in range(2):
        answer = proxy()
        say("loggers " + " ".join(f"{lg.name}={lg.level}" for lg in answer.loggers))
    proxy.close()


if __name__ == "__main__":
    role, args = sys.argv[1], sys.argv[2:]
    rospy.init_node(f"rospy_{role}", anonymous=True, disable_signals=False)
    {"pub": pub, "sub": sub, "serve": serve, "call": call}[role](*args)
