"""The log handler both ROS transports put on the root logger (``_roslog``): records reach
``/rosout``'s publisher, a record logged while publishing is dropped, loggers are listed
and set as ROS's logger services do, and the root logger is left as it was found."""

from __future__ import annotations

import logging

import pytest

from dataflow.transports._roslog import RosLog, loggers, set_level


@pytest.fixture
def pristine_root():
    """A root logger as Python makes it (WARNING, no handler: pytest's are set aside in the
    test itself), given back afterwards."""
    root = logging.getLogger()
    saved = root.level
    root.setLevel(logging.WARNING)
    yield root
    root.setLevel(saved)


def test_records_are_published_and_the_root_logger_is_left_as_found(pristine_root: logging.Logger) -> None:
    captures = list(pristine_root.handlers)  # pytest's log capture
    for handler in captures:
        pristine_root.removeHandler(handler)
    try:
        _publish_and_leave(pristine_root)
    finally:
        for handler in captures:
            pristine_root.addHandler(handler)


def _publish_and_leave(pristine_root: logging.Logger) -> None:
    published: list[str] = []

    def publish(record: logging.LogRecord) -> None:
        published.append(record.getMessage())
        logging.getLogger("scart.test.roslog").warning("logged while publishing")  # dropped: no loop

    ros1, ros2 = RosLog(publish), RosLog(lambda record: None)  # a process with both ROS nodes
    assert pristine_root.level == logging.INFO and logging.lastResort in pristine_root.handlers
    logging.getLogger("scart.test.roslog").info("an info, as ROS publishes")
    assert published == ["an info, as ROS publishes"]
    ros1.close()
    assert pristine_root.level == logging.INFO and logging.lastResort in pristine_root.handlers  # ros2's still
    ros2.close()
    ros2.close()
    assert pristine_root.level == logging.WARNING and pristine_root.handlers == []


def test_the_logger_services_list_and_set_existing_loggers_only() -> None:
    logger = logging.getLogger("scart.test.levels")
    try:
        set_level("scart.test.levels", "debug")
        assert ("scart.test.levels", "debug") in loggers() and loggers()[0][0] == "root"
        with pytest.raises(ValueError, match="no logger 'nobody.made.me'"):
            set_level("nobody.made.me", "info")
        assert "nobody.made.me" not in logging.Logger.manager.loggerDict
        with pytest.raises(ValueError, match="no level 'loud'"):
            set_level("scart.test.levels", "loud")
    finally:
        logger.setLevel(logging.NOTSET)
