"""The ROS 1 transport's tests: a master of each test's own (``ros``)."""

from support.ros1 import ros  # noqa: F401 - the fixture, for every test here
