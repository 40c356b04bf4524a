"""`fleet twin serve-bus`: the SO-101 of a running mixed_fleet line as six STS3215 servos on a pseudo-terminal.
Feetech's own SDK reads its joints where the line's states put them, and a sync write of goals moves the sim arm
there as an outside driver: the plant takes it (and lets it go after), nothing touches."""

import time

import numpy as np
import pytest
from scservo_sdk import COMM_SUCCESS, GroupSyncRead, GroupSyncWrite, PacketHandler, PortHandler

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, open_session
from fleet.nodes.attached import line_scene
from fleet.run.launcher import Launcher, RunOptions
from fleet.twin.line_arm import rad_of, ticks_of
from fleet.twin.serve_bus import Wear, served_arm
from robots.feetech.control_table import BY_NAME
from tests.fleet.line_beside import run_beside

# a realtime line, nothing heavy beside it: the SDK gives each answer about 34 ms, and in clean-clone CI a lockstep
# line beside another test starved the servo line past that three reads running ([-6, -6, -6]: no answer in time)
pytestmark = pytest.mark.slow

IDS = (1, 2, 3, 4, 5, 6)
HELD_S = 12.0  # sim seconds the servos hold their goals before they are read: past SERVO_HOLD_S and the release
PRESENT, GOAL, TORQUE = (BY_NAME[n].address for n in ("Present_Position", "Goal_Position", "Torque_Enable"))


def sync_read(port: PortHandler, sdk: PacketHandler, tries: int = 3) -> dict[int, int]:
    """Every servo's Present Position. The SDK gives six answers about 34 ms in all; on a loaded machine a Python
    servo line may miss that, so the read is tried again, as LeRobot's driver does (`num_retry`)."""
    read = GroupSyncRead(port, sdk, PRESENT, 2)
    for servo_id in IDS:
        read.addParam(servo_id)
    results = []
    while len(results) < tries and COMM_SUCCESS not in results:
        port.ser.reset_input_buffer()  # a late answer to a try that timed out is not the next one's
        results.append(read.txRxPacket())
    assert results[-1] == COMM_SUCCESS, results
    return {i: read.getData(i, PRESENT, 2) for i in IDS}


def sync_write(port: PortHandler, sdk: PacketHandler, address: int, size: int, values: dict[int, int]) -> None:
    write = GroupSyncWrite(port, sdk, address, size)
    for servo_id, value in values.items():
        write.addParam(servo_id, list(value.to_bytes(size, "little")))
    assert write.txPacket() == COMM_SUCCESS


def drive_arm_1(launcher: Launcher, seen: dict) -> None:
    """Once the line runs: the servos read, then the shoulder pan and elbow sent 0.3 rad on (the rest held)."""
    deadline = time.monotonic() + 60.0
    keys = Keys(launcher.options.run_id)
    with open_session(BusEndpoints(config_file=launcher.bus.config_for("twin"))) as session:
        scene = line_scene(session, keys, 30.0, "test")
        with served_arm(session, keys, scene.arm("arm_1")) as (bus, arm):
            port, sdk = PortHandler(bus.port), PacketHandler(0)
            assert port.openPort()
            while (state := arm.take()) is None or state.sim_time_s < 2.0:
                assert time.monotonic() < deadline, "no state of arm_1 past 2 s"
                time.sleep(0.01)
            seen["before"], seen["state_q"] = sync_read(port, sdk), [*state.q, state.gripper_q[0]]
            seen["goals"] = dict(seen["before"]) | {1: seen["before"][1] + 196, 3: seen["before"][3] - 196}
            sync_write(port, sdk, TORQUE, 1, {i: 1 for i in IDS})
            sync_write(port, sdk, GOAL, 2, seen["goals"])
            sent_at = arm.take().sim_time_s
            while arm.take().sim_time_s < sent_at + HELD_S:
                assert time.monotonic() < deadline, f"the line stopped before {sent_at + HELD_S:.1f} s"
                time.sleep(0.01)
            seen["after"], seen["sent"] = sync_read(port, sdk), arm.sent
            # the same arm, held still, served again as a worn arm reads: 2 degrees of encoder noise
            with served_arm(session, keys, scene.arm("arm_1"), wear=Wear(noise_deg=2.0, seed=3)) as (worn, _):
                worn_port = PortHandler(worn.port)
                assert worn_port.openPort()
                seen["worn"] = [sync_read(worn_port, sdk) for _ in range(40)]
                worn_port.closePort()
            port.closePort()
            seen["corrupt"] = bus.reader.corrupt


def test_feetechs_sdk_reads_and_moves_a_line_s_so_101_through_its_servo_bus():
    options = RunOptions(scene="mixed_fleet", duration_s=60.0, seed=0, mode="realtime")
    summary, seen, _ = run_beside(options, drive_arm_1)
    assert "error" not in seen, seen["error"]
    # the driver ended the line once it was done (`run_beside`)
    assert summary["status"] == "interrupted" and summary["inter_arm_contacts"] == 0, summary["error"]
    # the servos read where the state put the joints (a tick or two of motion between them)
    read_rad = np.array([rad_of(seen["before"][i]) for i in IDS])
    assert np.allclose(read_rad, seen["state_q"], atol=0.02), (read_rad, seen["state_q"])
    # the goals reached within a degree (11 ticks), and still held 12 s of sim time after the sync write: a servo
    # holds its goal while its torque is on (the plant would give the arm back 2 s after a goal's end)
    err = {i: abs(seen["after"][i] - seen["goals"][i]) for i in (1, 2, 3, 4, 5)}
    assert max(err.values()) <= 11, (err, seen["before"], seen["goals"], seen["after"])
    assert seen["sent"] >= 1 and seen["corrupt"] == 0
    # the worn servos read the held arm with the noise asked for (2 degrees: 22.8 ticks), about the true reading
    worn = np.array([[r[i] for i in (1, 2, 3, 4, 5)] for r in seen["worn"]], float)
    spread_deg = worn.std(axis=0).mean() * 360 / 4096
    assert 1.4 < spread_deg < 2.6, spread_deg
    assert np.abs(worn.mean(axis=0) - [seen["after"][i] for i in (1, 2, 3, 4, 5)]).max() < 15, worn.mean(axis=0)
    events = [(e["arm"], e["event"]) for e in summary["arm_events"]]
    assert ("arm_1", "taken") in events, events
    assert ticks_of(0.0) == 2048
