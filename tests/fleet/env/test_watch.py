"""`render_mode="human"` serves the browser monitor's 3D view of the env's cell, redrawn each step, on loopback;
closing the env frees the port."""

import socket
import urllib.request

from fleet.env import parallel_env


def test_human_render_serves_the_cell_and_frees_its_port_on_close():
    env = parallel_env(
        scenario="pick_place", action_mode="ee_delta", n_arms=2, max_cycles=10, render_mode="human", monitor_port=0
    )
    env.reset(seed=0)
    while env.agents:
        env.step({a: env.action_space(a).sample() for a in env.agents})
    monitor = env.monitor
    assert monitor.frames == 11  # the reset and every step
    assert monitor.url.startswith("http://127.0.0.1:")
    assert b"<html" in urllib.request.urlopen(monitor.url, timeout=5).read().lower()
    assert set(monitor.view.parts) == set(env.scenario.part.values())  # both parts drawn
    port = monitor.port
    env.close()
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))
