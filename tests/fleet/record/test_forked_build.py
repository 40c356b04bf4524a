"""ROS messages built in a forked child come back in order, as bytes equal to those built here, and a stop said
to the recorder's process group (Ctrl-C, the launcher's SIGTERM) does not take the child's share with it."""

import os
import signal
import time

from fleet.record.forked_build import LaterInChild, serialized
from fleet.record.ros_types import deserialize, ros_type


def text_maker(text: str, delay_s: float = 0.0):
    def make():
        time.sleep(delay_s)
        return ros_type("std_msgs/msg/String")(data=text)

    return make


def test_the_later_share_comes_back_in_order_and_equal_to_building_it_here():
    makers = [text_maker(f"message {i}") for i in range(50)]
    with LaterInChild(makers, 20) as later:
        mine = [serialized(m) for m in makers[:20]]
        theirs = later.collect() + later.collect() + later.collect() + later.collect()  # in SLICES pieces
    assert mine + theirs == [serialized(m) for m in makers]
    assert [deserialize(data, name).data for name, data in theirs] == [f"message {i}" for i in range(20, 50)]


def test_the_child_ignores_a_sigterm_meant_for_the_recorder_and_still_delivers():
    makers = [text_maker(f"slow {i}", delay_s=0.05) for i in range(10)]
    with LaterInChild(makers, 0) as later:
        (child,) = later._executor._processes  # the one forked worker
        time.sleep(0.1)
        os.kill(child, signal.SIGTERM)
        os.kill(child, signal.SIGINT)
        built = [b for _ in range(4) for b in later.collect()]
    assert [deserialize(data, name).data for name, data in built] == [f"slow {i}" for i in range(10)]


def test_nothing_is_forked_when_this_process_builds_everything():
    with LaterInChild([text_maker("x")], 1) as later:
        assert later._executor is None
