"""What `fleet run` is asked for, as the node commands read it."""

import pytest

from fleet.run.run_options import RunOptions


@pytest.mark.parametrize(
    ("asked", "expected"),
    [
        ({}, "raw"),
        ({"hosts": "hosts.yaml"}, "png"),
        ({"listen": "tcp/127.0.0.1:7447"}, "png"),
        ({"connect": ("tcp/127.0.0.1:7447",)}, "png"),
        ({"bus_config": "bus"}, "png"),
        ({"zenoh_config": "zenoh.json5"}, "png"),
        ({"camera_encoding": "jpeg"}, "jpeg"),
        ({"camera_encoding": "png", "hosts": "hosts.yaml"}, "png"),
        ({"camera_encoding": "raw", "hosts": "hosts.yaml"}, "raw"),
    ],
)
def test_images_travel_raw_where_the_bus_stays_on_this_machine_and_packed_where_it_may_not(asked, expected):
    assert RunOptions(cameras="all", **asked).rgb_encoding() == expected
