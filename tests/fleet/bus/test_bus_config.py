"""`fleet bus-config`: one Zenoh config per node, the sim a router; TLS, logins and access control by default."""

import json
import stat
import subprocess
import sys
import time

import pytest
import zenoh

from fleet.bus.bus_config import BusConfigError, BusConfigSet, access_control, write_bus_configs
from fleet.bus.session import BusEndpoints, make_config


def test_each_node_gets_its_own_login_and_only_its_owner_reads_keys_and_passwords(tmp_path):
    made = write_bus_configs(tmp_path, "127.0.0.1", 17461, ["arm_0", "arm_1"])
    assert made.endpoint == "tls/127.0.0.1:17461" and BusConfigSet.load(tmp_path) == made
    users = dict(line.split(":", 1) for line in (tmp_path / "users.txt").read_text().split())
    services = ["coordinator", "launcher", "monitor", "perception", "recorder", "ros", "ros_client", "twin"]
    assert sorted(users) == ["arm_0", "arm_1", *services]
    assert len(set(users.values())) == len(users), "a password per node"
    for private in ("sim.key", "users.txt", "sim.json5", "arm_0.json5"):
        assert stat.S_IMODE((tmp_path / private).stat().st_mode) == 0o600
    arm_0 = json.loads((tmp_path / "arm_0.json5").read_text())
    assert arm_0["mode"] == "client" and arm_0["transport"]["auth"]["usrpwd"]["user"] == "arm_0"
    assert make_config(BusEndpoints(config_file=made.config_for("arm_0"))).get_json("mode") == '"client"', (
        "the file's mode stands"
    )
    with pytest.raises(BusConfigError, match="nodes: sim, coordinator"):
        made.config_for("arm_7")


def test_the_router_lets_each_node_publish_only_its_own_keys():
    acl = access_control(["arm_0", "arm_1"])
    assert acl["default_permission"] == "deny"
    publishes = {r["id"]: r["key_exprs"] for r in acl["rules"] if r["id"].startswith("publish_")}
    assert publishes["publish_arm_0"] == [
        "clawfleet/*/arm/arm_0/step",
        "clawfleet/*/arm/arm_0/goal",
        "clawfleet/*/arm/arm_0/status",
        "clawfleet/*/snapshot/arm_0",
    ], "its own arm's answers, goals and heartbeats, and its own part of a snapshot"
    assert publishes["publish_coordinator"] == [
        "clawfleet/*/arm/*/assign",
        "clawfleet/*/coord/**",
        "clawfleet/*/snapshot/coordinator",
    ]
    assert publishes["publish_launcher"] == ["clawfleet/*/launcher/roster"], "the launcher says only its roster"
    assert publishes["publish_ros"] == ["clawfleet/*/arm/*/drive", "clawfleet/*/estop", "clawfleet/*/world/control"], (
        "ROS clients drive arms only as outside drivers (the arm is taken), never as its controller"
    )
    assert not any("state" in k or "world/events" in k for keys in publishes.values() for k in keys), (
        "only the sim reports the line"
    )
    assert all("declare_queryable" not in r["messages"] for r in acl["rules"] if "ingress" in r["flows"]), (
        "no client serves a queryable"
    )


def test_on_a_native_ros_2_line_only_the_ros_client_login_commands_and_only_its_arms():
    acl = access_control(["arm_0", "arm_1"], ros_domain=4, ros_arms=("arm_1",))
    rules = {r["id"]: r for r in acl["rules"]}
    by_subject = {s: p["rules"] for p in acl["policies"] for s in p["subjects"]}
    assert rules["ros2_command"]["key_exprs"] == [
        "4/arm_1/follow_joint_trajectory/_action/**",
        "4/arm_1/gripper_cmd/_action/**",
        "4/estop/**",
    ], "arm_1's actions and the e-stop; not pause or resume (not every arm is given)"
    assert rules["ros2_drive"]["key_exprs"] == ["4/arm_1/joint_trajectory/**"]
    assert by_subject["ros_client"] == ["ros2_command", "ros2_drive"] and by_subject["ros"] == ["ros2_publish"]
    assert rules["ros2_caches"]["key_exprs"] == ["4/**/@adv/**"], "everyone may read latched topics' caches"
    assert "query" not in rules["ros2_listen"]["messages"], "and call nothing"
    every = {r["id"]: r for r in access_control(["arm_0", "arm_1"], ros_domain=4)["rules"]}
    assert {"4/pause/**", "4/resume/**"} <= set(every["ros2_command"]["key_exprs"])
    with pytest.raises(BusConfigError, match="--ros-arms arm_7"):
        write_bus_configs("/nonexistent", "127.0.0.1", 7447, ["arm_0"], ros_domain=4, ros_arms=("arm_7",))


def test_a_client_with_a_login_may_publish_its_keys_and_one_without_cannot_log_in(tmp_path):
    made = write_bus_configs(tmp_path, "127.0.0.1", 17462, ["arm_0"])
    heard = []
    with zenoh.open(make_config(BusEndpoints(config_file=made.config_for("sim")))) as router:
        sub = router.declare_subscriber("clawfleet/line/**", lambda s: heard.append(str(s.key_expr)))
        with zenoh.open(make_config(BusEndpoints(config_file=made.config_for("arm_0")))) as arm_0:
            arm_0.put("clawfleet/line/arm/arm_0/status", b"x")  # its own
            arm_0.put("clawfleet/line/arm/arm_0/state", b"x")  # the sim's
            arm_0.put("clawfleet/line/estop", b"x")  # the monitor's
            deadline = time.monotonic() + 2.0
            while not heard and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(0.3)
        sub.undeclare()
        config = json.loads((tmp_path / "arm_0.json5").read_text())
        del config["transport"]["auth"]
        (tmp_path / "anonymous.json5").write_text(json.dumps(config))
        with pytest.raises(zenoh.ZError):
            zenoh.open(make_config(BusEndpoints(config_file=str(tmp_path / "anonymous.json5"))))
    assert heard == ["clawfleet/line/arm/arm_0/status"]


@pytest.mark.parametrize(
    "argv, says",
    [
        (["--address", "sim.local"], "an IP address of the sim's host"),
        (["--address", "10.0.0.5", "--port", "0"], "a TCP port"),
    ],
)
def test_bad_bus_config_requests_are_one_line(tmp_path, argv, says):
    done = subprocess.run(
        [sys.executable, "-m", "fleet", "bus-config", *argv, "--out", str(tmp_path / "bus")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and says in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr


def test_a_folder_that_is_not_a_bus_config_is_one_line(tmp_path):
    with pytest.raises(BusConfigError, match="not a bus config directory written by `fleet bus-config`"):
        BusConfigSet.load(tmp_path)
