"""Servos that answer packets as STS3215s do, on one line (`ServoLine`), each backed by a joint it reads and
drives (`ServoJoint`): ping, read, write, registered write and action, sync read and sync write. A servo answers
only packets for its id, a broadcast ping and its slot in a sync read, as its status-return level allows."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol

from robots.feetech.control_table import (
    BY_NAME,
    MEMORY_BYTES,
    STS3215_REGISTERS,
    TICKS_PER_TURN,
    Register,
    from_register,
    to_register,
)
from robots.feetech.packets import BROADCAST_ID, ErrorBit, Instruction, Packet, packet

GOAL = BY_NAME["Goal_Position"]
PRESENT = BY_NAME["Present_Position"]
TORQUE = BY_NAME["Torque_Enable"]
READ_ONLY = frozenset(
    a for r in STS3215_REGISTERS if not r.writable for a in range(r.address, r.address + r.size_bytes)
)  # byte addresses a write leaves alone


class ServoJoint(Protocol):
    """What a servo turns: where its shaft stands and how fast it turns (encoder ticks, ticks/s), and a goal for
    it while torque is on (None: torque off, the shaft is free)."""

    def position_ticks(self) -> int: ...

    def velocity_ticks_per_s(self) -> int: ...

    def drive(self, goal_ticks: int | None) -> None: ...


class Servo:
    """One STS3215: its memory (the control table at factory values, `id` set) and the joint it turns. Present
    Position reads the shaft less the Homing Offset, as the servo's own calibration does; a goal goes to the shaft
    plus that offset, within the position limits."""

    def __init__(self, servo_id: int, joint: ServoJoint) -> None:
        self.memory = bytearray(MEMORY_BYTES)
        self.joint = joint
        for register in STS3215_REGISTERS:
            self.set(register, register.factory)
        self.set(BY_NAME["ID"], servo_id)
        self.registered: tuple[int, bytes] | None = None  # a REG_WRITE waiting for ACTION

    @property
    def servo_id(self) -> int:
        return self.memory[BY_NAME["ID"].address]

    def get(self, register: Register) -> int:
        raw = int.from_bytes(self.memory[register.address : register.address + register.size_bytes], "little")
        return from_register(raw, register)

    def set(self, register: Register, value: int) -> None:
        raw = to_register(value, register).to_bytes(register.size_bytes, "little")
        self.memory[register.address : register.address + register.size_bytes] = raw

    def read(self, address: int, length: int) -> bytes:
        """`length` bytes from `address`, the present registers read off the joint first."""
        self.set(PRESENT, self._present())
        velocity = self.joint.velocity_ticks_per_s()
        self.set(BY_NAME["Present_Velocity"], velocity)
        self.set(BY_NAME["Moving"], int(velocity != 0))
        end = min(address + length, MEMORY_BYTES)
        return bytes(self.memory[address:end]) + bytes(address + length - end)

    def write(self, address: int, data: bytes) -> int:
        """Write `data` at `address` (read-only bytes keep their value), then drive the joint; the error byte. Torque
        turned on holds the shaft where it stands: the goal becomes the present position, as on the servo (within
        the limits: a worn encoder may read a shaft at its limit a tick past it, and no goal was written)."""
        torque_was = self.get(TORQUE)
        for i, byte in enumerate(data):
            if address + i < MEMORY_BYTES and address + i not in READ_ONLY:
                self.memory[address + i] = byte
        if self.get(TORQUE) and not torque_was:
            low, high = self.get(BY_NAME["Min_Position_Limit"]), self.get(BY_NAME["Max_Position_Limit"])
            self.set(GOAL, min(max(self._present(), low), high))
        return self._drive()

    def _present(self) -> int:
        return (self.joint.position_ticks() - self.get(BY_NAME["Homing_Offset"])) % TICKS_PER_TURN

    def _drive(self) -> int:
        """The joint driven to the goal (within the limits) while torque is on; ANGLE where the goal was outside."""
        if not self.get(TORQUE):
            self.joint.drive(None)
            return 0
        goal = self.get(GOAL)
        low, high = self.get(BY_NAME["Min_Position_Limit"]), self.get(BY_NAME["Max_Position_Limit"])
        held = min(max(goal, low), high)
        self.joint.drive((held + self.get(BY_NAME["Homing_Offset"])) % TICKS_PER_TURN)
        return ErrorBit.ANGLE if held != goal else 0

    def status(self, error: int, params: bytes = b"") -> bytes:
        return packet(self.servo_id, error, params)


class ServoLine:
    """Servos sharing one half-duplex line: `answer(packet)` is what they send back, in order (b"" when none
    answers). Counts what they were sent that no servo could take (`refused`, by why)."""

    def __init__(self, servos: Iterable[Servo]) -> None:
        self.servos = {s.servo_id: s for s in servos}
        self.refused: dict[str, int] = {}

    def answer(self, p: Packet) -> bytes:
        if p.code == Instruction.SYNC_READ and p.servo_id == BROADCAST_ID:
            return self._sync_read(p.params)
        if p.code == Instruction.SYNC_WRITE and p.servo_id == BROADCAST_ID:
            return self._sync_write(p.params)
        if p.servo_id != BROADCAST_ID:
            servo = self.servos.get(p.servo_id)
            return self._one(servo, p) if servo is not None else b""
        answers = [self._one(self.servos[i], p) for i in sorted(self.servos)]
        # a broadcast ping is answered by every servo in turn (how a driver finds them: LeRobot's broadcast_ping);
        # any other broadcast by none
        return b"".join(answers) if p.code == Instruction.PING else b""

    def _refuse(self, why: str) -> bytes:
        self.refused[why] = self.refused.get(why, 0) + 1
        return b""

    def _one(self, servo: Servo, p: Packet) -> bytes:
        level = servo.get(BY_NAME["Response_Status_Level"])
        if p.code == Instruction.PING:
            return servo.status(0)
        if p.code == Instruction.READ:
            if len(p.params) != 2:
                return self._refuse("read without address and length")
            return servo.status(0, servo.read(p.params[0], p.params[1]))
        if p.code in (Instruction.WRITE, Instruction.REG_WRITE):
            if not p.params:
                return self._refuse("write without an address")
            if p.code == Instruction.REG_WRITE:
                servo.registered, error = (p.params[0], bytes(p.params[1:])), 0
            else:
                error = servo.write(p.params[0], bytes(p.params[1:]))
            return servo.status(error) if level else b""
        if p.code == Instruction.ACTION:
            if servo.registered is not None:
                servo.write(*servo.registered)
                servo.registered = None
            return servo.status(0) if level else b""
        return self._refuse(f"instruction {p.code:#04x}")

    def _sync_read(self, params: bytes) -> bytes:
        if len(params) < 2:
            return self._refuse("sync read without address and length")
        address, length = params[0], params[1]
        return b"".join(s.status(0, s.read(address, length)) for i in params[2:] if (s := self.servos.get(i)))

    def _sync_write(self, params: bytes) -> bytes:
        if len(params) < 2 or params[1] == 0 or (len(params) - 2) % (params[1] + 1):
            return self._refuse("sync write whose data does not fit its length")
        address, length = params[0], params[1]
        for at in range(2, len(params), length + 1):
            if (servo := self.servos.get(params[at])) is not None:
                servo.write(address, bytes(params[at + 1 : at + 1 + length]))
        return b""
