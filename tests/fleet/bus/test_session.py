"""Real Zenoh sessions on loopback: another OS process publishes, this one receives; ports are freed."""

import socket
import subprocess
import sys
import textwrap
import time

import pytest

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ControllerStep
from fleet.bus.session import BusEndpoints, Inbox, free_loopback_port, loopback_endpoint, make_config, open_session

PUBLISHER = textwrap.dedent(
    """
    import sys, time
    from fleet.bus.codec import encode
    from fleet.bus.keys import Keys
    from fleet.bus.messages import ControllerStep
    from fleet.bus.session import BusEndpoints, open_session
    key = Keys("test").arm_step("arm_0")
    with open_session(BusEndpoints(connect=(sys.argv[1],))) as session:
        time.sleep(1.0)
        for i in range(20):
            session.put(key, encode(ControllerStep("arm_0", i, i + 5)))
            session.put(key, b"garbage")
        time.sleep(0.5)
    """
)


def port_is_listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_config_is_peer_loopback_without_multicast():
    config = make_config(BusEndpoints())
    assert config.get_json("scouting/multicast/enabled") == "false"
    assert config.get_json("listen/endpoints") == '["tcp/127.0.0.1:0"]'
    assert config.get_json("mode") == '"peer"'


def test_messages_cross_processes_and_garbage_is_counted():
    port = free_loopback_port()
    endpoint = loopback_endpoint(port)
    keys, inbox = Keys("test"), Inbox()
    drops = DropCounter()
    decoder = Decoder(ControllerStep, drops)
    received = []
    with open_session(BusEndpoints(listen=(endpoint,))) as session:
        sub = session.declare_subscriber(keys.all_arms("step"), inbox)
        proc = subprocess.Popen([sys.executable, "-c", PUBLISHER, endpoint])
        try:
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and proc.poll() is None or inbox.items:
                for key, payload in inbox.drain():
                    msg = decoder.decode(key, payload)
                    if msg is not None:
                        received.append((Keys.arm_of(key), msg.tick))
                time.sleep(0.01)
        finally:
            proc.kill() if proc.poll() is None else None
            proc.wait(timeout=5)
        sub.undeclare()
        assert port_is_listening(port)
    assert received == [("arm_0", i) for i in range(20)]
    assert drops.total == 20
    time.sleep(0.2)
    assert not port_is_listening(port), "closing the session frees its port"


def test_bad_run_or_arm_ids_are_refused():
    with pytest.raises(ValueError, match="run id"):
        Keys("Run 1")
    with pytest.raises(ValueError, match="arm id"):
        Keys("r").arm_state("arm/0")
