"""A ROS 2 user on pyzeros: another pure-Python rmw_zenoh implementation, with its own message types and type hashes
(ros2_pyterfaces) and its own CDR, logged in to the line's router as an outside ROS 2 stack (`ros_client`)."""

from __future__ import annotations

import asyncio
import os
import tempfile
from pathlib import Path

import zenoh

# pyzeros' CDR (cydr) compiles its code into a cache, by default in the working directory: the checkout
os.environ.setdefault("CYDR_CACHE_DIR", str(Path(tempfile.gettempdir()) / "clawfleet-test-cydr-cache"))

TOPICS = ("/joint_states", "/clock")


async def _use(node, heard: dict) -> None:
    import pyzeros
    from ros2_pyterfaces.cyclone.rosgraph_msgs.msg import Clock
    from ros2_pyterfaces.cyclone.sensor_msgs.msg import JointState
    from ros2_pyterfaces.cyclone.std_srvs.srv import SetBool

    subs = {"/joint_states": pyzeros.Sub(JointState, "/joint_states", session=node),
            "/clock": pyzeros.Sub(Clock, "/clock", session=node)}  # fmt: skip
    for topic, sub in subs.items():
        heard[topic] = await asyncio.wait_for(sub.wait_for_new(), timeout=20)
    estop = pyzeros.Client(SetBool, "/estop", session=node)
    await asyncio.wait_for(estop.wait_for_service(), timeout=20)
    heard["estop"] = await asyncio.wait_for(estop.call_async(SetBool.Request(data=False)), timeout=20)
    for endpoint in (*subs.values(), estop):
        endpoint.close()


def use_the_line(config_file: str, endpoint: str, domain_id: int) -> dict:
    """What pyzeros heard on the line's topics and from its e-stop service (released: the line goes on)."""
    import pyzeros

    config = zenoh.Config.from_file(config_file)
    config.insert_json5("connect/endpoints", f'["{endpoint}"]')
    heard: dict = {}
    with zenoh.open(config) as session:
        with pyzeros.auto_context(node="pyzeros_user", zenoh_session=session, domain_id=domain_id) as node:
            asyncio.run(_use(node, heard))
    return heard
