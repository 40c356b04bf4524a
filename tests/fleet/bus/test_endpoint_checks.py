"""Bus flags judged before anything starts, against real sockets and a real Zenoh session on loopback."""

import socket
import threading
import time

import pytest

from fleet.bus.endpoint_checks import EndpointError, await_connect, check_endpoints, check_listen, split_endpoint
from fleet.bus.session import BusEndpoints, free_loopback_port, loopback_endpoint, open_session

NOT_HERE = "192.0.2.1"  # TEST-NET-1 (RFC 5737): no machine has it; binding to it fails without sending anything


def test_an_endpoint_splits_into_protocol_host_and_port():
    assert split_endpoint("tcp/127.0.0.1:7447") == ("tcp", "127.0.0.1", 7447)
    assert split_endpoint("tcp/[::1]:7447") == ("tcp", "::1", 7447)
    assert split_endpoint("unixsock-stream//tmp/bus.sock") == ("unixsock-stream", "/tmp/bus.sock", None)


def test_an_address_this_machine_lacks_is_refused_and_loopback_is_not():
    with pytest.raises(EndpointError, match=rf"^--listen tcp/{NOT_HERE}:7447: this machine has no address {NOT_HERE}$"):
        check_listen(f"tcp/{NOT_HERE}:7447")
    check_listen(loopback_endpoint(free_loopback_port()))
    check_listen("tcp/127.0.0.1:0")


def test_a_port_another_program_listens_on_is_refused():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        ep = loopback_endpoint(taken.getsockname()[1])
        with pytest.raises(EndpointError, match=r"port \d+ is taken"):
            check_listen(ep)


def test_connecting_where_nothing_listens_is_refused_and_to_a_zenoh_session_passes():
    dead = loopback_endpoint(free_loopback_port())
    with pytest.raises(EndpointError, match=rf"^--connect {dead}: nothing answers there \(connection refused\)$"):
        check_endpoints(BusEndpoints(connect=(dead,)))
    live = loopback_endpoint(free_loopback_port())
    with open_session(BusEndpoints(listen=(live,))):
        check_endpoints(BusEndpoints(connect=(live,)))


def test_a_command_that_waits_for_its_line_waits_for_the_endpoint_too():
    later = loopback_endpoint(free_loopback_port())
    opened = threading.Event()

    def open_later():
        time.sleep(1.0)
        with open_session(BusEndpoints(listen=(later,))):
            opened.set()
            time.sleep(3.0)

    opener = threading.Thread(target=open_later)
    opener.start()
    try:
        await_connect(later, wait_s=20.0)
        assert opened.wait(5.0)
    finally:
        opener.join()
    with pytest.raises(EndpointError, match=r"nothing answers there \(connection refused\) \(waited 0.5 s\)"):
        await_connect(loopback_endpoint(free_loopback_port()), wait_s=0.5)
