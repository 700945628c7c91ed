"""One virtual STS3215's register memory and its link to a simulated joint.

The registers start from the factory image (:data:`FACTORY`), seeded with
the joint's lerobot calibration (ID, Homing_Offset, position limits); the
register semantics that move the arm (goals, torque, Present_*) are applied
by :mod:`so101_kinematics.virtual.emulator`, which owns the simulation.
"""

from __future__ import annotations

from collections.abc import Mapping

from so101_kinematics.servo import COUNTS_PER_TURN, MIN_VOLTS, VARIANTS
from so101_kinematics.virtual.electrical import AMBIENT_C
from so101_kinematics.virtual.protocol import (
    ADDR,
    BAUD_RATES,
    EEPROM_END,
    FIRMWARE,
    MODEL_NUMBER,
    SIGN_BITS,
    decode_sign_magnitude,
    encode_sign_magnitude,
)
from so101_kinematics.virtual.shipped_calibration import radians_to_present

__all__ = ["FACTORY_ID", "VirtualServo", "factory_eeprom"]

# Factory values. Source: Feetech's STS3215 memory table (the spreadsheet lerobot's tables.py
# links to, "Initial value" column; the same values where ftservo/ftservo-wiki's
# docs/en/reference/parameter/memory-sts.md gives one), except: Return_Delay_Time as lerobot leaves
# it (see virtual_so101: deviations; a new servo's is FACTORY_RETURN_DELAY), Max_Voltage_Limit
# 14.0 V (the 12 V C018's; the table's 8.0 V is the 7.4 V C001's, and the virtual arm's supply may
# be 12 V: --supply; 5 V by default), Lock 1 (the wiki; the spreadsheet says 0). Goal_Time (44,
# the PWM mode's duty): 1000, the wiki's initial value. Addresses 80-86 (the factory parameters:
# moving-speed threshold, DTs, speed unit coefficient, minimum and maximum speed, acceleration
# limit and multiplier; read-only) have no public value: the wiki's table gives "-" for each,
# Feetech's SMS_STS.h does not name them and lerobot's tables.py names them without values. They
# read 0 (docs/virtual_arm_protocol.md).
FACTORY = {
    "Firmware_Major_Version": FIRMWARE[0], "Firmware_Minor_Version": FIRMWARE[1],
    "Model_Number": MODEL_NUMBER, "Baud_Rate": 0, "Return_Delay_Time": 0,
    "Response_Status_Level": 1, "Min_Position_Limit": 0, "Max_Position_Limit": COUNTS_PER_TURN - 1,
    "Max_Temperature_Limit": 70, "Max_Voltage_Limit": round(VARIANTS["C018"].max_volts * 10),
    "Min_Voltage_Limit": round(MIN_VOLTS * 10),
    "Max_Torque_Limit": 1000, "Phase": 12, "Unloading_Condition": 44, "LED_Alarm_Condition": 47,
    "P_Coefficient": 32, "D_Coefficient": 32, "I_Coefficient": 0, "Minimum_Startup_Force": 16,
    "CW_Dead_Zone": 1, "CCW_Dead_Zone": 1, "Protection_Current": 500, "Angular_Resolution": 1,
    "Homing_Offset": 0, "Operating_Mode": 0, "Protective_Torque": 20, "Protection_Time": 200,
    "Overload_Torque": 80, "Velocity_closed_loop_P_proportional_coefficient": 10,
    "Over_Current_Protection_Time": 200, "Velocity_closed_loop_I_integral_coefficient": 10,
    "Torque_Enable": 0, "Acceleration": 0, "Goal_Time": 1000, "Torque_Limit": 1000,
    "Lock": 1, "Present_Voltage": 120, "Present_Temperature": 25, "Maximum_Acceleration": 0,
}
FACTORY_ID = 1  # every STS3215 leaves the factory as ID 1 ...
FACTORY_BAUD_RATE = 0  # ... at 1 Mbit/s (Baud_Rate register value 0) ...
FACTORY_RETURN_DELAY = 250  # ... answering 500 us after a request (lerobot's configure writes 0)


def factory_eeprom() -> bytes:
    """A new STS3215's EEPROM (addresses 0-39): :data:`FACTORY` as it leaves the factory."""
    regs = bytearray(256)
    for name, value in {**FACTORY, "ID": FACTORY_ID, "Baud_Rate": FACTORY_BAUD_RATE,
                        "Return_Delay_Time": FACTORY_RETURN_DELAY}.items():
        _store(regs, name, value)
    return bytes(regs[:EEPROM_END])


def _store(regs: bytearray, name: str, value: int) -> None:
    addr, size = ADDR[name]
    if name in SIGN_BITS:
        value = encode_sign_magnitude(int(value), SIGN_BITS[name])
    value = int(value) & (0xFF if size == 1 else 0xFFFF)
    regs[addr] = value & 0xFF
    if size == 2:
        regs[addr + 1] = value >> 8


class VirtualServo:
    """One STS3215: its register memory and its link to a simulated joint.

    The registers live in ``regs`` (256 bytes); the values the hot paths need
    (torque, limits, offsets, the tick <-> radian affine map) are cached as
    attributes and refreshed by :meth:`sync_cache` after every generic write.
    """

    def __init__(self, joint: str, cal: Mapping[str, int], m):
        self.joint = joint
        self.cal = dict(cal)
        self.qadr = int(m.joint(joint).qposadr[0])
        self.dofadr = int(m.joint(joint).dofadr[0])
        self.act = int(m.actuator(joint).id)
        self.kp = float(m.actuator_gainprm[self.act, 0])
        self.kv = float(-m.actuator_biasprm[self.act, 2])
        self.max_force = float(m.actuator_forcerange[self.act, 1])  # [N m] = Present_Load 1000
        # present = base + scale * angle (calibration frame), exactly lerobot's mapping
        self.base = radians_to_present(m, self.cal, joint, 0.0)
        self.scale = radians_to_present(m, self.cal, joint, 1.0) - self.base
        self.regs = bytearray(256)
        for name, value in FACTORY.items():
            self.set(name, value)
        self.set("ID", cal["id"])
        self.set("Homing_Offset", cal["homing_offset"])
        self.set("Min_Position_Limit", cal["range_min"])
        self.set("Max_Position_Limit", cal["range_max"])
        self.saved = bytes(self.regs[:EEPROM_END])
        self.load_torque_limit()
        self.registered: tuple[int, bytes] | None = None  # REG_WRITE's (address, data) until ACTION
        self.backup = factory_eeprom()  # what RESET (0x06) restores; BACKUP (0x09) replaces it
        # faults
        self.drop = 0
        self.corrupt = 0
        self.removed = False
        self.stalled_at: float | None = None  # [rad]
        self.load = 0.0  # stall load [0.1 %]
        self.error_bits = 0  # injected status error bits (voltage, overheat, overload)
        # the electrical model (virtual/electrical.py)
        self.temperature = AMBIENT_C  # [degC]
        self.overload_time = 0.0  # [s] the load has been at or above Overload_Torque
        self.protected = False  # in overload protection: output at Protective_Torque
        self.plugged = True  # on the bus (factory mode plugs the servos in one at a time)
        self.sync_cache()

    def sync_cache(self) -> None:
        """Refresh the cached register values from ``regs``."""
        self.id = self.regs[5]
        self.baud = BAUD_RATES.get(self.regs[6])
        self.torque = self.regs[40] != 0
        self.position_mode = self.regs[33] == 0
        lo, hi = self.get("Min_Position_Limit"), self.get("Max_Position_Limit")
        self.limits = (lo, hi) if lo < hi else None
        # encoder = calibration present + calibration offset; present = encoder - register offset
        self.delta = self.cal["homing_offset"] - self.get("Homing_Offset")
        self.return_delay = 2e-6 * self.regs[7]

    def load_torque_limit(self) -> None:
        """Power-up: Torque_Limit (48) := Max_Torque_Limit (16), as the memory table says."""
        self.set("Torque_Limit", self.get("Max_Torque_Limit"))

    def get(self, name: str) -> int:
        """The named register's value (sign-magnitude registers decoded)."""
        addr, size = ADDR[name]
        raw = self.regs[addr] if size == 1 else self.regs[addr] | self.regs[addr + 1] << 8
        return decode_sign_magnitude(raw, SIGN_BITS[name]) if name in SIGN_BITS else raw

    def set(self, name: str, value: int) -> None:
        """Store ``value`` in the named register (sign-magnitude registers encoded)."""
        _store(self.regs, name, value)

    def angle_to_present(self, angle: float) -> int:
        """Joint angle [rad] -> Present_Position with the current Homing_Offset register."""
        return round(self.base + self.scale * angle + self.delta) % COUNTS_PER_TURN

    def goal_to_angle(self, goal: int) -> float:
        """Goal_Position (clamped to the limit registers) -> actuator target [rad]."""
        if self.limits is not None:
            goal = min(self.limits[1], max(self.limits[0], goal))
        return (goal - self.delta - self.base) / self.scale
