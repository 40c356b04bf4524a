"""Six emulated STS3215s on a pseudo-terminal, driven by Feetech's own SDK (`scservo_sdk`) as it drives real
ones over USB: pings give the model, reads and writes reach the registers, sync read and sync write cover the
line, a packet with a wrong checksum gets no answer (counted), and a goal outside the limits is held to them."""

import os

import pytest
from scservo_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, GroupSyncRead, GroupSyncWrite, PacketHandler, PortHandler

from fleet.twin.pty_bus import PtyServoBus
from robots.feetech.control_table import BY_NAME, STS3215_MODEL_NUMBER
from robots.feetech.packets import ErrorBit, Instruction, packet
from robots.feetech.servos import Servo, ServoLine
from tests.robots.feetech.joints import StiffJoint

IDS = (1, 2, 3, 4, 5, 6)  # an SO-101's servos: shoulder pan to gripper
ADDRESS = {name: r.address for name, r in BY_NAME.items()}


@pytest.fixture
def line():
    joints = {i: StiffJoint(2000 + 10 * i) for i in IDS}
    with PtyServoBus(ServoLine(Servo(i, joints[i]) for i in IDS)) as bus:
        port = PortHandler(bus.port)
        assert port.openPort(), "the SDK opens the terminal as a serial port at 1 Mbaud"
        yield bus, port, PacketHandler(0), joints
        port.closePort()


def test_each_servo_answers_a_ping_with_its_model_and_an_absent_one_does_not(line):
    _, port, sdk, _ = line
    for servo_id in IDS:
        model, result, error = sdk.ping(port, servo_id)
        assert (model, result, error) == (STS3215_MODEL_NUMBER, COMM_SUCCESS, 0)
    _, result, _ = sdk.ping(port, 9)
    assert result == COMM_RX_TIMEOUT


def test_a_broadcast_ping_is_answered_by_every_servo_in_turn_and_no_other_broadcast_is(line):
    """How LeRobot's driver finds the servos on a line (its own `broadcast_ping`, over the SDK's port)."""
    _, port, sdk, _ = line
    port.writePort(packet(0xFE, Instruction.PING))
    port.setPacketTimeoutMillis(200)
    answers = [sdk.rxPacket(port) for _ in IDS]
    assert [(result, rx[2], rx[4]) for rx, result in answers] == [(COMM_SUCCESS, i, 0) for i in IDS]
    port.writePort(packet(0xFE, Instruction.WRITE, bytes([ADDRESS["Torque_Enable"], 1])))
    port.setPacketTimeoutMillis(50)
    assert sdk.rxPacket(port)[1] == COMM_RX_TIMEOUT, "a broadcast write is taken by all and answered by none"
    assert sdk.read1ByteTxRx(port, 4, ADDRESS["Torque_Enable"])[0] == 1


def test_a_goal_written_with_torque_on_moves_the_joint_and_reads_back_less_the_homing_offset(line):
    _, port, sdk, joints = line
    assert sdk.read2ByteTxRx(port, 3, ADDRESS["Present_Position"]) == (2030, COMM_SUCCESS, 0)
    assert sdk.write1ByteTxRx(port, 3, ADDRESS["Torque_Enable"], 1) == (COMM_SUCCESS, 0)
    assert sdk.write2ByteTxRx(port, 3, ADDRESS["Goal_Position"], 2500) == (COMM_SUCCESS, 0)
    assert joints[3].goal == 2500 and sdk.read2ByteTxRx(port, 3, ADDRESS["Present_Position"])[0] == 2500
    # a calibration's offset, written with torque off as LeRobot does: the servo then reads (and is driven)
    # relative to it; a negative offset in sign and magnitude
    sdk.write1ByteTxRx(port, 3, ADDRESS["Torque_Enable"], 0)
    assert joints[3].goal is None, "torque off: the joint is free"
    assert sdk.write2ByteTxRx(port, 3, ADDRESS["Homing_Offset"], (1 << 11) | 100)[0] == COMM_SUCCESS
    assert sdk.read2ByteTxRx(port, 3, ADDRESS["Present_Position"])[0] == 2600
    sdk.write1ByteTxRx(port, 3, ADDRESS["Torque_Enable"], 1)
    sdk.write2ByteTxRx(port, 3, ADDRESS["Goal_Position"], 2600)
    assert joints[3].goal == 2500, "the goal plus the offset: the shaft stays where it stood"


def test_read_only_registers_keep_their_values_and_a_goal_beyond_the_limits_is_held_to_them(line):
    _, port, sdk, joints = line
    sdk.write2ByteTxRx(port, 1, ADDRESS["Model_Number"], 1234)
    assert sdk.read2ByteTxRx(port, 1, ADDRESS["Model_Number"])[0] == STS3215_MODEL_NUMBER
    sdk.write2ByteTxRx(port, 1, ADDRESS["Max_Position_Limit"], 3000)
    sdk.write1ByteTxRx(port, 1, ADDRESS["Torque_Enable"], 1)
    result, error = sdk.write2ByteTxRx(port, 1, ADDRESS["Goal_Position"], 3500)
    assert result == COMM_SUCCESS and error == ErrorBit.ANGLE and joints[1].ticks == 3000


def test_torque_on_holds_a_shaft_read_a_tick_past_its_limit_at_the_limit_with_no_error(line):
    """A worn encoder reads a shaft resting at its limit a little past it: torque on holds it there, and no goal was
    written, so no angle error (LeRobot's connect writes torque on and fails on any error bit)."""
    _, port, sdk, joints = line
    sdk.write2ByteTxRx(port, 2, ADDRESS["Min_Position_Limit"], 2030)  # the joint reads 2020
    assert sdk.write1ByteTxRx(port, 2, ADDRESS["Torque_Enable"], 1) == (COMM_SUCCESS, 0)
    assert joints[2].goal == 2030 and sdk.read2ByteTxRx(port, 2, ADDRESS["Goal_Position"])[0] == 2030


def test_sync_read_and_sync_write_cover_the_whole_line(line):
    _, port, sdk, joints = line
    write = GroupSyncWrite(port, sdk, ADDRESS["Torque_Enable"], 1)
    for servo_id in IDS:
        write.addParam(servo_id, [1])
    assert write.txPacket() == COMM_SUCCESS
    goals = GroupSyncWrite(port, sdk, ADDRESS["Goal_Position"], 2)
    for servo_id in IDS:
        goals.addParam(servo_id, list((1000 + servo_id).to_bytes(2, "little")))
    assert goals.txPacket() == COMM_SUCCESS
    read = GroupSyncRead(port, sdk, ADDRESS["Present_Position"], 2)
    for servo_id in IDS:
        read.addParam(servo_id)
    assert read.txRxPacket() == COMM_SUCCESS
    assert {i: read.getData(i, ADDRESS["Present_Position"], 2) for i in IDS} == {i: 1000 + i for i in IDS}
    assert all(joints[i].ticks == 1000 + i for i in IDS)


def test_a_packet_with_a_wrong_checksum_gets_no_answer_and_is_counted(line):
    bus, port, sdk, _ = line
    bad = bytearray(packet(2, Instruction.PING))
    bad[-1] ^= 0xFF
    os.write(port.ser.fileno(), bytes(bad))
    port.setPacketTimeoutMillis(50)
    _, result = sdk.rxPacket(port)
    assert result == COMM_RX_TIMEOUT and bus.reader.corrupt == 1
    assert sdk.ping(port, 2)[1] == COMM_SUCCESS, "the line goes on"


def test_serve_bus_without_a_line_to_join_is_one_line():
    import subprocess
    import sys

    for extra in (
        [],
        ["--connect", "tcp/127.0.0.1:1", "--wait", "0.5"],
        ["--connect", "tcp/127.0.0.1:1", "--noise-deg", "nan"],
        ["--connect", "tcp/127.0.0.1:1", "--backlash-deg", "-1"],
    ):
        done = subprocess.run(
            [sys.executable, "-m", "fleet", "twin", "serve-bus", "--arm", "arm_1", *extra],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 2 and done.stdout == "" and len(done.stderr.splitlines()) == 1, done.stderr
