"""The STS3215's control table: each register's address, width and whether a driver may write it, as Feetech's
STS/SMS manual and LeRobot's Feetech driver (`lerobot.motors.feetech.tables`) give them. Words are little-endian;
a few registers carry a sign bit (sign and magnitude, not two's complement)."""

from __future__ import annotations

from dataclasses import dataclass

STS3215_MODEL_NUMBER = 777
TICKS_PER_TURN = 4096  # the magnetic encoder's resolution: a position register counts 0..4095
MEMORY_BYTES = 256  # one instruction's address and length are one byte each


@dataclass(frozen=True)
class Register:
    """One register: its name as LeRobot spells it, address and width in bytes, whether writes reach it, the bit
    that holds its sign (None: unsigned), and what a servo holds there when it leaves the factory."""

    name: str
    address: int
    size_bytes: int
    writable: bool = True
    sign_bit: int | None = None
    factory: int = 0


STS3215_REGISTERS: tuple[Register, ...] = (
    # EEPROM: kept across power cycles on the real servo
    Register("Firmware_Major_Version", 0, 1, writable=False, factory=3),
    Register("Firmware_Minor_Version", 1, 1, writable=False, factory=10),
    Register("Model_Number", 3, 2, writable=False, factory=STS3215_MODEL_NUMBER),
    Register("ID", 5, 1, factory=1),
    Register("Baud_Rate", 6, 1),  # 0: 1 Mbaud
    Register("Return_Delay_Time", 7, 1),
    Register("Response_Status_Level", 8, 1, factory=1),  # every instruction answered
    Register("Min_Position_Limit", 9, 2),
    Register("Max_Position_Limit", 11, 2, factory=TICKS_PER_TURN - 1),
    Register("Max_Temperature_Limit", 13, 1, factory=70),
    Register("Max_Voltage_Limit", 14, 1, factory=140),
    Register("Min_Voltage_Limit", 15, 1, factory=40),
    Register("Max_Torque_Limit", 16, 2, factory=1000),
    Register("Phase", 18, 1),
    Register("Unloading_Condition", 19, 1),
    Register("LED_Alarm_Condition", 20, 1),
    Register("P_Coefficient", 21, 1, factory=32),
    Register("D_Coefficient", 22, 1, factory=32),
    Register("I_Coefficient", 23, 1),
    Register("Minimum_Startup_Force", 24, 2),
    Register("CW_Dead_Zone", 26, 1),
    Register("CCW_Dead_Zone", 27, 1),
    Register("Protection_Current", 28, 2),
    Register("Angular_Resolution", 30, 1, factory=1),
    Register("Homing_Offset", 31, 2, sign_bit=11),
    Register("Operating_Mode", 33, 1),  # 0: position control
    Register("Protective_Torque", 34, 1),
    Register("Protection_Time", 35, 1),
    Register("Overload_Torque", 36, 1),
    Register("Velocity_closed_loop_P_proportional_coefficient", 37, 1),
    Register("Over_Current_Protection_Time", 38, 1),
    Register("Velocity_closed_loop_I_integral_coefficient", 39, 1),
    # SRAM
    Register("Torque_Enable", 40, 1),
    Register("Acceleration", 41, 1),
    Register("Goal_Position", 42, 2),
    Register("Goal_Time", 44, 2),
    Register("Goal_Velocity", 46, 2, sign_bit=15),
    Register("Torque_Limit", 48, 2, factory=1000),
    Register("Lock", 55, 1, factory=1),
    Register("Present_Position", 56, 2, writable=False),
    Register("Present_Velocity", 58, 2, writable=False, sign_bit=15),
    Register("Present_Load", 60, 2, writable=False),
    Register("Present_Voltage", 62, 1, writable=False, factory=120),  # 12.0 V
    Register("Present_Temperature", 63, 1, writable=False, factory=30),
    Register("Status", 65, 1, writable=False),
    Register("Moving", 66, 1, writable=False),
    Register("Present_Current", 69, 2, writable=False),
    # factory settings LeRobot's driver writes (its `configure_motors`)
    Register("Moving_Velocity_Threshold", 80, 1),
    Register("DTs", 81, 1),
    Register("Velocity_Unit_factor", 82, 1),
    Register("Hts", 83, 1),
    Register("Maximum_Velocity_Limit", 84, 1),
    Register("Maximum_Acceleration", 85, 1),
    Register("Acceleration_Multiplier", 86, 1),
)
BY_NAME: dict[str, Register] = {r.name: r for r in STS3215_REGISTERS}


def to_register(value: int, register: Register) -> int:
    """A signed value as the register holds it (sign and magnitude where it has a sign bit)."""
    if register.sign_bit is None:
        return value & ((1 << (8 * register.size_bytes)) - 1)
    magnitude = min(abs(value), (1 << register.sign_bit) - 1)
    return magnitude | (1 << register.sign_bit) if value < 0 else magnitude


def from_register(raw: int, register: Register) -> int:
    """The value a register's raw bits stand for."""
    if register.sign_bit is None or not raw & (1 << register.sign_bit):
        return raw
    return -(raw & ((1 << register.sign_bit) - 1))
