"""A virtual SO-101: six Feetech STS3215 servos on a pseudo-terminal, driving a MuJoCo arm.

lerobot's unmodified ``FeetechMotorsBus`` (and ``SO101Follower``) connect to
:attr:`VirtualSO101.port` exactly as to a real arm::

    from virtual_so101 import VirtualSO101, DEFAULT_CALIBRATION_PATH

    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as arm:
        bus = FeetechMotorsBus(port=arm.port, motors=..., calibration=...)
        bus.connect()                       # PING, model 777, firmware 3.10
        bus.sync_write("Goal_Position", {"elbow_flex": 30.0, ...})
        arm.joint_positions()               # measured in MuJoCo [deg], gripper [0, 100]

Command line: ``python virtual_so101.py [--calibration PATH] [--viewer]
[--wire-timing] [--faults SPEC]`` prints the pty path as the first line of
stdout, then logs to stderr and serves until Ctrl-C.

Design
------
- One emulator process (a fresh interpreter, as multiprocessing's "spawn",
  started with subprocess so the caller's ``__main__`` is not re-run) holds
  the pty, the servo registers and the MuJoCo simulation of
  ``model/scene.xml`` in a single-threaded event loop: it answers the bus
  first and steps the physics (2 ms steps) to keep up with the wall clock in
  between. Nothing of the emulator runs in the client's process (lerobot
  busy-polls the port; a Python thread there slows it, and a second thread in
  the emulator would fight for its GIL). The parent object talks to it over a
  socket pair. Measured on 2 busy cores (load 3), a 6-motor sync_read +
  sync_write cycle of lerobot: 0.36-0.38 ms median without wire timing
  (lerobot's own cost 0.13 ms, the emulator 0.23-0.25 ms), 1.06-1.24 ms with
  it (0.88 ms of wire); see :func:`measure_cycle`.
- Protocol 0 (``FF FF ID LEN INST P.. CHK``): PING (also broadcast: every servo
  answers, in id order), READ, WRITE, SYNC_READ (replies in the request's id
  order), SYNC_WRITE and broadcast WRITE (never answered). Packets with a bad
  checksum are ignored, as a servo does. REG_WRITE/ACTION/RESET are not
  emulated (lerobot does not send them): they are ignored.
- A servo only understands the host when the pty's baud rate (set by pyserial)
  equals its Baud_Rate register, so baud scans behave as on a real bus. (Rates
  termios cannot name, 128000 and 250000, read as "unchanged".) Wire timing
  uses the same rate.

Registers (STS3215 control table, sizes and sign-magnitude as lerobot's
tables): Present_Position = encoder - Homing_Offset (mod 4096); Goal_Position
is in the same frame (so a new Homing_Offset written with torque on moves the
joint; lerobot writes it with torque off) and is clamped to [Min_Position_Limit,
Max_Position_Limit] (silently: the STS status byte has no angle-limit bit;
its bit 1 is the encoder-sensor error). Torque_Enable = 0 makes the joint
limp (the position actuator's gains are zeroed; gravity and the joint's
damping and friction act) and, as on the STS, Goal_Position then follows
Present_Position so re-enabling torque does not jump. Max_Torque_Limit scales
the actuator's force range. Lock = 0 saves EEPROM writes (addresses < 40) to
the image restored by :meth:`VirtualSO101.power_cycle`; with Lock = 1 they act
until the next power cycle. Present_Velocity [ticks/s] and Present_Load
[0.1 % of the stall torque, sign bit 10] come from the simulation. Acceleration,
speed limits and the PID coefficients are stored but do not shape the motion:
the MuJoCo position actuator (upstream's sts3215 gains) does. Only
Operating_Mode 0 (position) is emulated; in other modes goals are stored but
the joint keeps its last target.

Ticks <-> joint angles go through the lerobot calibration, so they agree with
``so101_mujoco_utils.to_radians``:
- arm joints: angle [deg] = (present - (range_min + range_max) / 2) * 360 / 4095,
  lerobot's DEGREES;
- gripper: opening [0, 100] = (present - range_min) / (range_max - range_min) * 100,
  lerobot's RANGE_0_100, and 0..100 spans the model's gripper range.
The shipped calibration (:func:`make_default_calibration`) centres each arm
joint's range on the model's zero (2047 +/- the joint's range, rounded up by a
tick so that lerobot's truncation at the exact joint limit stays inside). The
wrist_roll range of the model is asymmetric (-157.2..162.8 deg): its middle is
not its zero, so its calibration is what lerobot-calibrate records for this
full-turn joint, range 0..4095 (middle 2047.5 = 0 deg); the mapping stays exact
and the model's limits stop the joint. Each servo's encoder reading is the
calibration's present value plus the calibration's Homing_Offset (fixed,
plausible offsets), and the registers are seeded from the calibration, so
``SO101Follower.connect()`` finds the arm calibrated and never prompts.

Deviations from a real arm (deliberate, for testing):
- At power-up torque is ON, holding the initial pose (``torque_on_start``);
  a real STS3215 starts with torque off. Pass ``torque_on_start=False`` for the
  real behaviour (the arm then sags under gravity until torque is enabled).
- Return_Delay_Time starts at 0 (what lerobot's configure_motors writes), not
  the factory 250.
- Goal log times are ``time.time()`` [s] of the emulator process at the moment
  the write was applied.

Beyond the agreed API, :class:`VirtualSO101` also offers ``commanded_positions()``,
``set_torque()``, ``set_wire_timing()``, ``registers(joint)``, ``power_cycle()``,
``reply_stats()`` / ``clear_stats()`` and the ``torque_on_start`` argument.

Fault injection (``--faults`` / :meth:`VirtualSO101.inject`), comma-separated;
SERVO is an id or a joint name:
- ``drop:SERVO[:N]``: the next N replies (default 1) of the servo are not sent
  (lerobot: ConnectionError "... There is no status packet!").
- ``corrupt:SERVO[:N]``: the next N replies carry a wrong checksum
  (ConnectionError "... Incorrect status packet!").
- ``remove:SERVO``: the servo is off the bus (connect: RuntimeError
  "... Missing motor IDs ...").
- ``stall:SERVO``: the joint is blocked where it is; Present_Load rises
  (2000 per s, signed towards the goal) while the goal is off, and the overload
  bit (0x20) is set in its status once the load reaches Overload_Torque
  (read: RuntimeError "... Overload error!"; sync_read ignores status bits).
- ``firmware:[SERVO:]MAJOR.MINOR``: the servo (default id 1) reports that
  firmware (connect: RuntimeError "Some Motors use different firmware versions").
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import select
import signal
import socket
import statistics
import subprocess
import sys
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Mapping
from multiprocessing.connection import Connection
from pathlib import Path

_HERE = Path(__file__).resolve().parent
DEFAULT_CALIBRATION_PATH = _HERE / "calibration" / "virtual_so101.json"

logger = logging.getLogger("virtual_so101")

# --- STS3215 facts --------------------------------------------------------------------------
MODEL_NUMBER = 777
FIRMWARE = (3, 10)
RESOLUTION = 4096  # encoder ticks per turn
TICKS_PER_RAD = (RESOLUTION - 1) / (2.0 * math.pi)  # lerobot's scale (360 deg = 4095 ticks)
BAUD_RATES = {0: 1_000_000, 1: 500_000, 2: 250_000, 3: 128_000, 4: 115_200, 5: 57_600,
              6: 38_400, 7: 19_200}
STALL_LOAD_RATE = 2000.0  # [0.1 % per s] Present_Load rise of a stalled servo
LATE_REPLY = 0.045  # [s] after this, lerobot (50 ms timeout) may have given up
BITS_PER_BYTE = 10
GOAL_LOG_LENGTH = 1_000_000  # Goal_Position writes kept (about 30 min of a 100 Hz loop)

INST_PING, INST_READ, INST_WRITE = 0x01, 0x02, 0x03
INST_SYNC_READ, INST_SYNC_WRITE = 0x82, 0x83
BROADCAST_ID = 0xFE
ERR_OVERLOAD = 0x20

# Addresses (lerobot's STS_SMS_SERIES_CONTROL_TABLE).
ADDR = {
    "Firmware_Major_Version": (0, 1), "Firmware_Minor_Version": (1, 1), "Model_Number": (3, 2),
    "ID": (5, 1), "Baud_Rate": (6, 1), "Return_Delay_Time": (7, 1),
    "Response_Status_Level": (8, 1), "Min_Position_Limit": (9, 2), "Max_Position_Limit": (11, 2),
    "Max_Temperature_Limit": (13, 1), "Max_Voltage_Limit": (14, 1), "Min_Voltage_Limit": (15, 1),
    "Max_Torque_Limit": (16, 2), "Phase": (18, 1), "Unloading_Condition": (19, 1),
    "LED_Alarm_Condition": (20, 1), "P_Coefficient": (21, 1), "D_Coefficient": (22, 1),
    "I_Coefficient": (23, 1), "Minimum_Startup_Force": (24, 2), "CW_Dead_Zone": (26, 1),
    "CCW_Dead_Zone": (27, 1), "Protection_Current": (28, 2), "Angular_Resolution": (30, 1),
    "Homing_Offset": (31, 2), "Operating_Mode": (33, 1), "Protective_Torque": (34, 1),
    "Protection_Time": (35, 1), "Overload_Torque": (36, 1), "Torque_Enable": (40, 1),
    "Acceleration": (41, 1), "Goal_Position": (42, 2), "Goal_Time": (44, 2),
    "Goal_Velocity": (46, 2), "Torque_Limit": (48, 2), "Lock": (55, 1),
    "Present_Position": (56, 2), "Present_Velocity": (58, 2), "Present_Load": (60, 2),
    "Present_Voltage": (62, 1), "Present_Temperature": (63, 1), "Status": (65, 1),
    "Moving": (66, 1), "Present_Current": (69, 2), "Maximum_Acceleration": (85, 1),
}
SIGN_BITS = {"Homing_Offset": 11, "Goal_Position": 15, "Goal_Velocity": 15,
             "Present_Position": 15, "Present_Velocity": 15, "Present_Load": 10}
EEPROM_END = 40  # addresses below are EEPROM (saved when Lock = 0)
READ_ONLY = set(range(0, 5)) | set(range(56, 80))
FACTORY = {  # factory values; Return_Delay_Time as lerobot leaves it (see module docstring)
    "Firmware_Major_Version": FIRMWARE[0], "Firmware_Minor_Version": FIRMWARE[1],
    "Model_Number": MODEL_NUMBER, "Baud_Rate": 0, "Return_Delay_Time": 0,
    "Response_Status_Level": 1, "Min_Position_Limit": 0, "Max_Position_Limit": 4095,
    "Max_Temperature_Limit": 70, "Max_Voltage_Limit": 140, "Min_Voltage_Limit": 40,
    "Max_Torque_Limit": 1000, "Phase": 12, "Unloading_Condition": 44, "LED_Alarm_Condition": 47,
    "P_Coefficient": 32, "D_Coefficient": 32, "I_Coefficient": 0, "Minimum_Startup_Force": 16,
    "CW_Dead_Zone": 1, "CCW_Dead_Zone": 1, "Protection_Current": 500, "Angular_Resolution": 1,
    "Homing_Offset": 0, "Operating_Mode": 0, "Protective_Torque": 20, "Protection_Time": 200,
    "Overload_Torque": 80, "Torque_Enable": 0, "Acceleration": 0, "Torque_Limit": 1000,
    "Lock": 1, "Present_Voltage": 120, "Present_Temperature": 30, "Maximum_Acceleration": 0,
}
# Plausible encoder offsets of the virtual arm's servo horns (any |value| <= 2047 works).
DEFAULT_HOMING_OFFSETS = {"shoulder_pan": 143, "shoulder_lift": -612, "elbow_flex": 488,
                          "wrist_flex": -251, "wrist_roll": 97, "gripper": -705}
FULL_TURN_JOINTS = ("wrist_roll",)  # recorded as 0..4095 by lerobot-calibrate
JOINT_IDS = {"shoulder_pan": 1, "shoulder_lift": 2, "elbow_flex": 3, "wrist_flex": 4,
             "wrist_roll": 5, "gripper": 6}
CALIBRATION_KEYS = ("id", "drive_mode", "homing_offset", "range_min", "range_max")


class VirtualSO101Error(RuntimeError):
    """The virtual arm could not start or answer."""


class CalibrationError(ValueError):
    """A calibration file or dict is not usable for the virtual arm."""


class FaultSpecError(ValueError):
    """A fault specification does not follow the grammar."""


# --- sign-magnitude and packets --------------------------------------------------------------
def encode_sign_magnitude(value: int, sign_bit: int) -> int:
    """Signed integer -> sign-magnitude register value (sign at ``sign_bit``)."""
    return (-value) | (1 << sign_bit) if value < 0 else value


def decode_sign_magnitude(raw: int, sign_bit: int) -> int:
    """Sign-magnitude register value -> signed integer."""
    return -(raw & ~(1 << sign_bit)) if raw & (1 << sign_bit) else raw


def checksum(body: bytes | bytearray) -> int:
    """Feetech checksum of ID, LEN, INST/ERR and parameters: low byte of the bitwise not."""
    return ~sum(body) & 0xFF


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A status packet ``FF FF ID LEN ERR P.. CHK``."""
    body = bytes((servo_id, len(params) + 2, error)) + params
    return b"\xff\xff" + body + bytes((checksum(body),))


def instruction_packet(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """An instruction packet ``FF FF ID LEN INST P.. CHK`` (for tests and tools)."""
    body = bytes((servo_id, len(params) + 2, instruction)) + params
    return b"\xff\xff" + body + bytes((checksum(body),))


# --- calibration ------------------------------------------------------------------------------
def make_default_calibration(m) -> dict[str, dict[str, int]]:
    """The virtual arm's calibration, derived from the model's joint ranges.

    Arm joints: range centred on 2047 (the model's zero), half-width = the
    joint's largest |limit| in ticks rounded up; full-turn joints (wrist_roll):
    0..4095. Gripper: 2047.5 +/- half its range, so 0..100 spans it.

    Args:
        m: the MuJoCo model (``so101_mujoco_utils.load_model()``).

    Returns:
        Joint name -> {id, drive_mode, homing_offset, range_min, range_max}.
    """
    calibration = {}
    for name, servo_id in JOINT_IDS.items():
        lower, upper = (float(x) for x in m.joint(name).range)
        if name in FULL_TURN_JOINTS:
            range_min, range_max = 0, RESOLUTION - 1
        elif name == "gripper":
            span = round((upper - lower) * TICKS_PER_RAD)
            range_min, range_max = 2048 - (span + 1) // 2, 2048 - (span + 1) // 2 + span
        else:
            half = math.ceil(max(abs(lower), abs(upper)) * TICKS_PER_RAD - 1e-9)
            range_min, range_max = 2047 - half, 2047 + half
        calibration[name] = {"id": servo_id, "drive_mode": 0,
                             "homing_offset": DEFAULT_HOMING_OFFSETS[name],
                             "range_min": range_min, "range_max": range_max}
    return calibration


def load_calibration(calibration: str | Path | Mapping) -> dict[str, dict[str, int]]:
    """Read and check a lerobot calibration (JSON path or dict) for the virtual arm.

    Args:
        calibration: path to a ``lerobot-calibrate`` JSON file, or the dict
            joint name -> {id, drive_mode, homing_offset, range_min, range_max}
            (values may also be objects with those attributes).

    Returns:
        Joint name -> dict of ints, in the six SO-101 joints' order.

    Raises:
        CalibrationError: missing joints or keys, bad values; the message says what to fix.
    """
    source = "calibration"
    if isinstance(calibration, (str, Path)):
        source = str(calibration)
        try:
            calibration = json.loads(Path(calibration).read_text())
        except FileNotFoundError as exc:
            raise CalibrationError(
                f"Calibration file {source} not found. Fix: pass an existing lerobot calibration "
                f"JSON, e.g. {DEFAULT_CALIBRATION_PATH}.") from exc
        except json.JSONDecodeError as exc:
            raise CalibrationError(f"Calibration file {source} is not valid JSON: {exc}.") from exc
    out = {}
    missing = [name for name in JOINT_IDS if name not in calibration]
    if missing:
        raise CalibrationError(f"{source}: joints {missing} are missing; the virtual SO-101 needs "
                               f"all of {list(JOINT_IDS)}.")
    for name in JOINT_IDS:
        entry = calibration[name]
        get = entry.get if isinstance(entry, Mapping) else lambda k, e=entry: getattr(e, k, None)
        values = {key: get(key) for key in CALIBRATION_KEYS}
        for key, value in values.items():
            if isinstance(value, bool) or not isinstance(value, int):
                raise CalibrationError(f"{source}: {name}.{key} = {value!r} must be an integer.")
        if values["drive_mode"] != 0:
            raise CalibrationError(f"{source}: {name}.drive_mode = {values['drive_mode']}; the "
                                   "virtual arm's servos are not inverted. Fix: use drive_mode 0.")
        if not 0 <= values["range_min"] < values["range_max"] <= RESOLUTION - 1:
            raise CalibrationError(
                f"{source}: {name} range [{values['range_min']}, {values['range_max']}] must "
                f"satisfy 0 <= range_min < range_max <= {RESOLUTION - 1}.")
        if abs(values["homing_offset"]) > 2047:
            raise CalibrationError(f"{source}: {name}.homing_offset = {values['homing_offset']} "
                                   "is beyond +/-2047 (the register's sign-magnitude range).")
        if not 0 < values["id"] < BROADCAST_ID:
            raise CalibrationError(f"{source}: {name}.id = {values['id']} must be in 1..253.")
        out[name] = values
    ids = [v["id"] for v in out.values()]
    if len(set(ids)) != len(ids):
        raise CalibrationError(f"{source}: servo ids {ids} are not unique.")
    return out


def present_to_radians(cal: Mapping[str, int], joint: str, present: float,
                       joint_range: tuple[float, float]) -> float:
    """Present_Position [ticks] -> joint angle [rad] through the calibration (lerobot's mapping).

    Args:
        cal: the joint's calibration entry.
        joint: joint name ("gripper" uses RANGE_0_100 over ``joint_range``).
        present: position in the calibration's frame [ticks].
        joint_range: the model joint's (lower, upper) [rad].
    """
    lo, hi = cal["range_min"], cal["range_max"]
    if joint == "gripper":
        return joint_range[0] + (present - lo) / (hi - lo) * (joint_range[1] - joint_range[0])
    return (present - (lo + hi) / 2.0) / TICKS_PER_RAD


def radians_to_present(cal: Mapping[str, int], joint: str, angle: float,
                       joint_range: tuple[float, float]) -> float:
    """Joint angle [rad] -> Present_Position [ticks, not rounded]; see present_to_radians."""
    lo, hi = cal["range_min"], cal["range_max"]
    if joint == "gripper":
        return lo + (angle - joint_range[0]) / (joint_range[1] - joint_range[0]) * (hi - lo)
    return (lo + hi) / 2.0 + angle * TICKS_PER_RAD


# --- faults -----------------------------------------------------------------------------------
FAULT_KINDS = ("drop", "corrupt", "remove", "stall", "firmware")


def parse_faults(spec: str | None, calibration: Mapping[str, Mapping[str, int]]) -> list[tuple]:
    """Parse a fault specification (grammar in the module docstring).

    Returns:
        A list of (kind, servo_id, argument) tuples.

    Raises:
        FaultSpecError: naming the bad item and the grammar.
    """
    grammar = ("drop:SERVO[:N], corrupt:SERVO[:N], remove:SERVO, stall:SERVO, "
               "firmware:[SERVO:]MAJOR.MINOR (SERVO = id or joint name), comma-separated")
    ids = {name: int(entry["id"]) for name, entry in calibration.items()}

    def servo(token: str, item: str) -> int:
        if token in ids:
            return ids[token]
        if token.isdigit() and int(token) in ids.values():
            return int(token)
        raise FaultSpecError(f"Fault '{item}': unknown servo '{token}'; use an id in "
                             f"{sorted(ids.values())} or a joint in {list(ids)}.")

    faults = []
    for item in (s.strip() for s in (spec or "").split(",")):
        if not item:
            continue
        kind, *args = item.split(":")
        if kind not in FAULT_KINDS:
            raise FaultSpecError(f"Unknown fault '{item}'. Grammar: {grammar}.")
        try:
            if kind == "firmware":
                if len(args) == 1:
                    args = [str(min(ids.values())), args[0]]
                major, minor = (int(x) for x in args[1].split("."))
                if not (0 <= major <= 255 and 0 <= minor <= 255) or len(args) != 2:
                    raise ValueError
                faults.append((kind, servo(args[0], item), (major, minor)))
            elif kind in ("drop", "corrupt"):
                count = int(args[1]) if len(args) == 2 else 1
                if len(args) not in (1, 2) or count < 1:
                    raise ValueError
                faults.append((kind, servo(args[0], item), count))
            else:
                if len(args) != 1:
                    raise ValueError
                faults.append((kind, servo(args[0], item), None))
        except FaultSpecError:
            raise
        except (ValueError, IndexError):
            raise FaultSpecError(f"Bad fault '{item}'. Grammar: {grammar}.") from None
    return faults


# =============================================================================================
# Emulator process
# =============================================================================================
class _Servo:
    """One STS3215: its register memory and its link to a simulated joint.

    The registers live in ``regs`` (256 bytes); the values the hot paths need
    (torque, limits, offsets, the tick <-> radian affine map) are cached as
    attributes and refreshed by :meth:`sync_cache` after every generic write.
    """

    def __init__(self, joint: str, cal: Mapping[str, int], m):
        self.joint = joint
        self.cal = dict(cal)
        self.range = tuple(float(x) for x in m.joint(joint).range)
        self.qadr = int(m.joint(joint).qposadr[0])
        self.dofadr = int(m.joint(joint).dofadr[0])
        self.act = int(m.actuator(joint).id)
        self.kp = float(m.actuator_gainprm[self.act, 0])
        self.kv = float(-m.actuator_biasprm[self.act, 2])
        self.max_force = float(m.actuator_forcerange[self.act, 1])  # [N m] = Present_Load 1000
        # present = base + scale * angle (calibration frame), exactly lerobot's mapping
        self.base = radians_to_present(self.cal, joint, 0.0, self.range)
        self.scale = radians_to_present(self.cal, joint, 1.0, self.range) - self.base
        self.regs = bytearray(256)
        for name, value in FACTORY.items():
            self.set(name, value)
        self.set("ID", cal["id"])
        self.set("Homing_Offset", cal["homing_offset"])
        self.set("Min_Position_Limit", cal["range_min"])
        self.set("Max_Position_Limit", cal["range_max"])
        self.saved = bytes(self.regs[:EEPROM_END])
        # faults
        self.drop = 0
        self.corrupt = 0
        self.removed = False
        self.stalled_at: float | None = None  # [rad]
        self.load = 0.0  # stall load [0.1 %]
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

    def get(self, name: str) -> int:
        addr, size = ADDR[name]
        raw = self.regs[addr] if size == 1 else self.regs[addr] | self.regs[addr + 1] << 8
        return decode_sign_magnitude(raw, SIGN_BITS[name]) if name in SIGN_BITS else raw

    def set(self, name: str, value: int) -> None:
        addr, size = ADDR[name]
        if name in SIGN_BITS:
            value = encode_sign_magnitude(int(value), SIGN_BITS[name])
        value = int(value) & (0xFF if size == 1 else 0xFFFF)
        self.regs[addr] = value & 0xFF
        if size == 2:
            self.regs[addr + 1] = value >> 8

    def angle_to_present(self, angle: float) -> int:
        """Joint angle [rad] -> Present_Position with the current Homing_Offset register."""
        return round(self.base + self.scale * angle + self.delta) % RESOLUTION

    def goal_to_angle(self, goal: int) -> float:
        """Goal_Position (clamped to the limit registers) -> actuator target [rad]."""
        if self.limits is not None:
            goal = min(self.limits[1], max(self.limits[0], goal))
        return (goal - self.delta - self.base) / self.scale


class _Emulator:
    """The event loop of the emulator process: pty + registers + physics."""

    def __init__(self, conn, options: dict):
        import mujoco

        import so101_mujoco_utils as smu

        self.mujoco, self.smu = mujoco, smu
        self.conn = conn
        self.m = smu.load_model()
        self.d = mujoco.MjData(self.m)
        self.dt = float(self.m.opt.timestep)
        self.servos: dict[int, _Servo] = {}
        for joint, cal in options["calibration"].items():
            servo = _Servo(joint, cal, self.m)
            self.servos[servo.id] = servo
        self.by_joint = {s.joint: s for s in self.servos.values()}
        self.wire_timing = bool(options["wire_timing"])
        self.goal_log: deque[tuple[float, int, int]] = deque(maxlen=GOAL_LOG_LENGTH)
        self.lateness = deque(maxlen=20000)
        self.replies = 0
        self.late = 0
        self.max_gap = 0.0
        self.rx = bytearray()
        self.rx_partial_since = 0.0
        self.wire_free = 0.0
        self.host_baud = 1_000_000
        self.listening: dict[int, _Servo] = {}
        if options["initial"] is None:
            mujoco.mj_resetDataKeyframe(self.m, self.d, self.m.key("home").id)
            mujoco.mj_forward(self.m, self.d)
        else:
            smu.set_initial_pose(self.d, options["initial"])
        for servo in self.servos.values():
            servo.set("Torque_Enable", 1 if options["torque_on_start"] else 0)
            servo.sync_cache()
            self._apply_torque(servo)
            self._hold(servo)
        self.update_listening()
        self.inject(options["faults"])
        self.viewer = None
        if options["viewer"]:
            import mujoco.viewer

            self.viewer = mujoco.viewer.launch_passive(self.m, self.d)
        self.next_view = 0.0
        # The pty: keep the slave open (else the master reads EIO in a busy loop).
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.port = os.ttyname(self.slave)
        self.speeds = {getattr(termios, f"B{b}"): b for b in BAUD_RATES.values()
                       if hasattr(termios, f"B{b}")}
        self.t0 = time.perf_counter()
        self.steps = 0

    # --- physics --------------------------------------------------------------------------
    def _apply_torque(self, servo: _Servo) -> None:
        on = servo.torque
        m, act = self.m, servo.act
        m.actuator_gainprm[act, 0] = servo.kp if on else 0.0
        m.actuator_biasprm[act, 1] = -servo.kp if on else 0.0
        m.actuator_biasprm[act, 2] = -servo.kv if on else 0.0
        force = servo.max_force * min(1000, servo.get("Max_Torque_Limit")) / 1000.0
        m.actuator_forcerange[act] = (-force, force)

    def _hold(self, servo: _Servo) -> None:
        """Goal_Position := Present_Position, actuator target := measured angle."""
        angle = float(self.d.qpos[servo.qadr])
        servo.set("Goal_Position", servo.angle_to_present(angle))
        self.d.ctrl[servo.act] = angle

    def step_physics(self) -> None:
        due = int((time.perf_counter() - self.t0) / self.dt) - self.steps
        if due <= 0:
            return
        if due > 25:  # fell behind (busy machine): let simulated time slip
            self.steps += due - 25
            due = 25
        m, d, step = self.m, self.d, self.mujoco.mj_step
        stalled = [s for s in self.servos.values() if s.stalled_at is not None]
        for _ in range(due):
            step(m, d)
            for s in stalled:
                d.qpos[s.qadr] = s.stalled_at
                d.qvel[s.dofadr] = 0.0
        self.steps += due
        for s in stalled:
            err = s.get("Goal_Position") - s.angle_to_present(s.stalled_at)
            rate = STALL_LOAD_RATE * due * self.dt
            if abs(err) > 3 and s.torque:
                s.load = math.copysign(min(1000.0, abs(s.load) + rate), err)
            else:
                s.load = math.copysign(max(0.0, abs(s.load) - rate), s.load)
        if self.viewer is not None and time.perf_counter() >= self.next_view:
            if not self.viewer.is_running():
                raise KeyboardInterrupt("viewer closed")
            self.viewer.sync()
            self.next_view = time.perf_counter() + 1 / 60

    def refresh(self, servo: _Servo, lo: int = 56, hi: int = 71) -> None:
        """Update the servo's Present_* registers overlapping [lo, hi) from the simulation."""
        d, regs = self.d, servo.regs
        angle = servo.stalled_at if servo.stalled_at is not None else float(d.qpos[servo.qadr])
        present = round(servo.base + servo.scale * angle + servo.delta) % RESOLUTION
        regs[56] = present & 0xFF
        regs[57] = present >> 8
        if not servo.torque:  # the STS keeps Goal_Position on Present_Position while limp
            regs[42], regs[43] = regs[56], regs[57]
        if hi <= 58:
            return
        velocity = float(d.qvel[servo.dofadr]) * TICKS_PER_RAD
        if servo.stalled_at is not None:
            load = servo.load
        else:
            load = float(d.actuator_force[servo.act]) / servo.max_force * 1000.0
        load = max(-1000, min(1000, round(load)))
        servo.set("Present_Velocity", max(-32767, min(32767, round(velocity))))
        servo.set("Present_Load", load)
        servo.set("Present_Current", abs(load) * 2)
        regs[66] = int(abs(velocity) > 20)
        regs[65] = self.error_byte(servo)

    def error_byte(self, servo: _Servo) -> int:
        if servo.stalled_at is not None and abs(servo.load) >= 10 * servo.regs[36]:
            return ERR_OVERLOAD
        return 0

    # --- registers ------------------------------------------------------------------------
    def write_goal(self, servo: _Servo, low: int, high: int) -> None:
        """Fast path: a Goal_Position write (the hot path of a control loop)."""
        regs = servo.regs
        regs[42] = low
        regs[43] = high
        goal = low | high << 8
        if goal & 0x8000:
            goal = -(goal & 0x7FFF)
        if servo.torque and servo.position_mode:
            self.d.ctrl[servo.act] = servo.goal_to_angle(goal)
        self.goal_log.append((time.time(), servo.id, goal))

    def write(self, servo: _Servo, addr: int, data: bytes) -> None:
        if addr == 42 and len(data) == 2:
            self.write_goal(servo, data[0], data[1])
            return
        regs = servo.regs
        old_id, was_on = servo.id, servo.torque
        for i, byte in enumerate(data):
            if addr + i not in READ_ONLY and addr + i < 256:
                regs[addr + i] = byte
        if addr < EEPROM_END and regs[55] == 0:
            servo.saved = bytes(regs[:EEPROM_END])
        servo.sync_cache()
        touched = set(range(addr, addr + len(data)))
        if servo.id != old_id or touched & {6}:
            self.servos = {s.id: s for s in self.by_joint.values()}
            self.update_listening()
        if touched & {40, 16, 17}:
            self._apply_torque(servo)
            if servo.torque and not was_on:
                self._hold(servo)
        if touched & {42, 43, 31, 32, 9, 10, 11, 12, 33}:
            if servo.torque and servo.position_mode:
                self.d.ctrl[servo.act] = servo.goal_to_angle(servo.get("Goal_Position"))
            if touched & {42, 43}:
                self.goal_log.append((time.time(), servo.id, servo.get("Goal_Position")))

    def read(self, servo: _Servo, addr: int, size: int) -> bytes:
        end = addr + size
        if (end > 56 and addr < 71) or (not servo.torque and addr <= 43 and end > 42):
            self.refresh(servo, addr, end)
        return bytes(servo.regs[addr:end]).ljust(size, b"\0")

    def update_listening(self) -> None:
        """The servos that hear the host: present, and at the host's baud rate."""
        self.listening = {i: s for i, s in self.servos.items()
                          if not s.removed and s.baud == self.host_baud}

    # --- protocol -------------------------------------------------------------------------
    def on_serial(self) -> None:
        try:
            chunk = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # EIO: no slave open (cannot happen while we hold one)
            time.sleep(0.001)
            return
        now = time.perf_counter()
        baud = self.speeds.get(termios.tcgetattr(self.master)[5], self.host_baud)
        if baud != self.host_baud:
            self.host_baud = baud
            self.update_listening()
        rx = self.rx
        if rx and now - self.rx_partial_since > 0.01:
            del rx[:2]  # a stale partial packet: a servo's byte timeout would discard it
        rx += chunk
        while True:
            start = rx.find(b"\xff\xff")
            if start < 0:
                del rx[:-1 if rx.endswith(b"\xff") else len(rx)]
                break
            del rx[:start]
            if len(rx) >= 3 and rx[2] == 0xFF:
                del rx[0]
                continue
            if len(rx) < 4:
                break
            total = rx[3] + 4
            if rx[3] < 2:
                del rx[:2]
                continue
            if len(rx) < total:
                break
            packet = bytes(rx[:total])
            if packet[-1] != checksum(packet[2:-1]):
                del rx[:2]  # corrupt instruction: ignored, as a servo does
                continue
            del rx[:total]
            self.handle(packet, now)
        if rx:
            self.rx_partial_since = now

    def handle(self, packet: bytes, t_seen: float) -> None:
        target, inst, params = packet[2], packet[4], packet[5:-1]
        tpb = BITS_PER_BYTE / self.host_baud
        if self.wire_timing:  # the request ends on the wire after its bytes (queued behind others)
            t_end = max(t_seen, self.wire_free) + len(packet) * tpb
            self.wire_free = t_end
        else:
            t_end = t_seen
        listening = self.listening
        replies: list[tuple[_Servo, bytes]] = []
        if inst == INST_PING:
            if target == BROADCAST_ID:
                replies = [(s, b"") for _, s in sorted(listening.items())]
            elif target in listening:
                replies = [(listening[target], b"")]
        elif inst == INST_READ and len(params) == 2 and target in listening:
            servo = listening[target]
            replies = [(servo, self.read(servo, params[0], params[1]))]
        elif inst == INST_WRITE and len(params) >= 2:
            addr, data = params[0], params[1:]
            targets = list(listening.values()) if target == BROADCAST_ID else (
                [listening[target]] if target in listening else [])
            for servo in targets:
                self.write(servo, addr, data)
            if target != BROADCAST_ID and targets:
                servo = targets[0]
                if servo.regs[8] != 0:
                    replies = [(servo, b"")]
        elif inst == INST_SYNC_READ and target == BROADCAST_ID and len(params) >= 2:
            addr, size = params[0], params[1]
            for servo_id in params[2:]:
                servo = listening.get(servo_id)
                if servo is not None:
                    replies.append((servo, self.read(servo, addr, size)))
        elif inst == INST_SYNC_WRITE and target == BROADCAST_ID and len(params) >= 2:
            addr, size = params[0], params[1]
            body = params[2:]
            for i in range(0, len(body) - size, size + 1):
                servo = listening.get(body[i])
                if servo is not None:
                    self.write(servo, addr, body[i + 1:i + 1 + size])
        if replies:
            self.send(replies, t_end, tpb)

    def send(self, replies: list[tuple[_Servo, bytes]], t_end: float, tpb: float) -> None:
        t_ready = t_end
        out = []
        for servo, params in replies:
            if servo.drop:
                servo.drop -= 1
                continue
            if servo.removed:
                continue
            packet = status_packet(servo.id, self.error_byte(servo), params)
            if servo.corrupt:
                servo.corrupt -= 1
                packet = packet[:-1] + bytes(((packet[-1] + 1) & 0xFF,))
            t_ready += servo.return_delay + len(packet) * tpb
            out.append((t_ready, packet))
        if not out:
            return
        if self.wire_timing:
            self.wire_free = t_ready
            for deadline, packet in out:
                _wait_until(deadline)
                self._emit(packet, deadline, t_end)
        else:
            now = time.perf_counter()
            self._emit(b"".join(p for _, p in out), t_end, t_end, now)
            self.replies += len(out) - 1

    def _emit(self, data: bytes, deadline: float, t_end: float, now: float | None = None) -> None:
        try:
            os.write(self.master, data)
        except BlockingIOError:  # nobody reads the port: the bytes are lost on the wire
            pass
        now = time.perf_counter() if now is None else now
        self.replies += 1
        self.lateness.append(time.perf_counter() - deadline)
        if now - t_end > LATE_REPLY:
            self.late += 1

    # --- faults and commands --------------------------------------------------------------
    def inject(self, faults: list[tuple]) -> None:
        for kind, servo_id, arg in faults:
            servo = next(s for s in self.by_joint.values() if s.cal["id"] == servo_id)
            if kind == "drop":
                servo.drop += arg
            elif kind == "corrupt":
                servo.corrupt += arg
            elif kind == "remove":
                servo.removed = True
            elif kind == "stall":
                servo.stalled_at = float(self.d.qpos[servo.qadr])
                servo.load = 0.0
            elif kind == "firmware":
                servo.regs[0], servo.regs[1] = arg
            self.update_listening()
            logger.info("fault injected: %s on servo %d (%s)", kind, servo_id, servo.joint)

    def clear_faults(self) -> None:
        for servo in self.servos.values():
            servo.drop = servo.corrupt = 0
            servo.removed = False
            servo.stalled_at = None
            servo.load = 0.0
            servo.regs[0], servo.regs[1] = FIRMWARE
        self.update_listening()

    def command(self, name: str, args: tuple):
        smu = self.smu
        if name == "joint_positions":
            return smu.get_configuration(self.m, self.d)
        if name == "commanded_positions":
            return smu.get_command(self.m, self.d)
        if name == "goal_log":
            return list(self.goal_log)
        if name == "clear_goal_log":
            self.goal_log.clear()
            return None
        if name == "torque_enabled":
            return {s.joint: s.torque for s in self.by_joint.values()}
        if name == "inject":
            return self.inject(args[0])
        if name == "clear_faults":
            return self.clear_faults()
        if name == "set_pose":
            smu.set_initial_pose(self.d, args[0])
            for servo in self.servos.values():
                if servo.stalled_at is not None:
                    servo.stalled_at = float(self.d.qpos[servo.qadr])
                self._hold(servo)
            return None
        if name == "set_torque":
            for servo in self.by_joint.values():
                if args[1] is None or servo.joint in args[1]:
                    self.write(servo, 40, bytes((int(args[0]),)))
            return None
        if name == "set_wire_timing":
            self.wire_timing = bool(args[0])
            return None
        if name == "registers":
            servo = self.by_joint[args[0]]
            self.refresh(servo)
            return {reg: servo.get(reg) for reg in ADDR}
        if name == "power_cycle":
            for servo in self.servos.values():
                eeprom = servo.saved
                gains = servo.kp, servo.kv, servo.max_force  # the model's, before any torque change
                servo.__init__(servo.joint, servo.cal, self.m)
                servo.kp, servo.kv, servo.max_force = gains
                servo.regs[:EEPROM_END] = eeprom
                servo.saved = eeprom
                servo.sync_cache()
                self._apply_torque(servo)
            self.servos = {s.id: s for s in self.by_joint.values()}
            self.update_listening()
            return None
        if name == "reply_stats":
            lateness = sorted(self.lateness)
            p99 = lateness[int(0.99 * (len(lateness) - 1))] if lateness else 0.0
            return {
                "replies": self.replies, "late_replies": self.late,
                "lateness_median_ms": 1e3 * statistics.median(lateness) if lateness else 0.0,
                "lateness_p99_ms": 1e3 * p99,
                "lateness_max_ms": 1e3 * lateness[-1] if lateness else 0.0,
                "max_loop_delay_ms": 1e3 * self.max_gap,
                "sim_time_s": self.d.time, "wall_time_s": time.perf_counter() - self.t0,
            }
        if name == "clear_stats":
            self.lateness.clear()
            self.replies = self.late = 0
            self.max_gap = 0.0
            return None
        raise ValueError(f"unknown command {name!r}")

    def run(self) -> None:
        self.conn.send(("ready", self.port))
        master, conn = self.master, self.conn
        while True:
            now = time.perf_counter()
            wake = max(now, self.t0 + (self.steps + 1) * self.dt)
            ready, _, _ = select.select([master, conn], [], [], wake - now)
            # How long past its wake-up time the loop got the CPU back (descheduled).
            self.max_gap = max(self.max_gap, time.perf_counter() - wake)
            if master in ready:
                self.on_serial()
            if conn in ready:
                try:
                    name, args = conn.recv()
                except (EOFError, OSError):
                    return
                if name == "close":
                    conn.send(("ok", None))
                    return
                try:
                    conn.send(("ok", self.command(name, args)))
                except Exception as exc:  # noqa: BLE001 - handed to the caller
                    conn.send(("err", exc))
            self.step_physics()


SPIN_S = float(os.environ.get("VIRTUAL_SO101_SPIN_S", "1e-4"))  # [s] busy-wait before a reply


def _wait_until(deadline: float) -> None:
    """Sleep, then spin the last ``SPIN_S``, until ``time.perf_counter() >= deadline``.

    The process runs with a 1 us timer slack (:func:`_tighten_timer_slack`),
    so a short sleep wakes within tens of microseconds; sleeping rather than
    spinning keeps the emulator a light, interactive task for the scheduler,
    which then wakes it promptly on a busy machine.
    """
    remaining = deadline - time.perf_counter()
    if remaining > SPIN_S:
        time.sleep(remaining - SPIN_S)
    while time.perf_counter() < deadline:
        pass


def _raise_priority() -> None:
    """Ask for a higher CPU priority (nice -5) where allowed.

    The emulator sleeps most of the time but must answer within lerobot's
    50 ms timeout even on a machine busy with other work; a real servo does
    not share the host's CPU. Without the privilege this does nothing.
    """
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -5)
    except (OSError, AttributeError):
        pass


def _tighten_timer_slack() -> None:
    """Ask Linux for 1 us timer slack (default 50 us) so short sleeps are precise."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(29, 1000, 0, 0, 0)  # PR_SET_TIMERSLACK
    except (OSError, AttributeError):
        pass


def _emulator_main(fd: int) -> None:
    """Entry point of the emulator process: ``fd`` is its end of the socket pair."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    _tighten_timer_slack()
    _raise_priority()
    conn = Connection(fd)
    options = conn.recv()
    logging.basicConfig(level=options.get("log_level", logging.WARNING),
                        format="%(asctime)s virtual_so101: %(message)s")
    sys.path.insert(0, str(_HERE))
    try:
        emulator = _Emulator(conn, options)
    except Exception as exc:  # noqa: BLE001 - reported to the parent
        conn.send(("err", exc))
        return
    try:
        emulator.run()
    except KeyboardInterrupt:
        pass
    finally:
        if emulator.viewer is not None:
            emulator.viewer.close()
        os.close(emulator.master)
        os.close(emulator.slave)


# =============================================================================================
# Parent side
# =============================================================================================
class VirtualSO101:
    """A virtual SO-101 on a pseudo-terminal (see the module docstring).

    The emulator process starts in the constructor; use it as a context manager
    (or call :meth:`close`) to stop it.

    Args:
        calibration: lerobot calibration JSON path or dict (default: the shipped one).
        wire_timing: delay replies by their byte time at the host's baud rate
            (10 bits a byte) plus Return_Delay_Time (2 us a unit).
        faults: fault specification to apply from power-up (module docstring).
        viewer: show the arm in MuJoCo's passive viewer (needs a display).
        initial: user-units configuration ([deg], gripper [0, 100]) to start
            at; default the model's "home" keyframe.
        torque_on_start: servos hold the initial pose from power-up (default;
            a real STS3215 starts limp).
        log_level: logging level of the emulator process.
        startup_timeout: [s] to wait for the emulator to come up.

    Raises:
        CalibrationError: the calibration is unusable.
        FaultSpecError: ``faults`` does not parse.
        VirtualSO101Error: no display for the viewer, or the emulator failed to start.
        so101_motion.JointLimitError: ``initial`` is outside the joint limits.
    """

    def __init__(self, calibration: str | Path | Mapping = DEFAULT_CALIBRATION_PATH,
                 wire_timing: bool = False, faults: str | None = None, viewer: bool = False,
                 initial: Mapping[str, float] | None = None, torque_on_start: bool = True,
                 log_level: int = logging.WARNING, startup_timeout: float = 60.0):
        self.calibration = load_calibration(calibration)
        self._ids = {name: entry["id"] for name, entry in self.calibration.items()}
        parsed = parse_faults(faults, self.calibration)
        if viewer and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise VirtualSO101Error("--viewer needs a display (DISPLAY or WAYLAND_DISPLAY is "
                                    "not set). Fix: run without the viewer, or on a desktop.")
        options = {"calibration": self.calibration, "wire_timing": wire_timing,
                   "faults": parsed, "viewer": viewer,
                   "initial": dict(initial) if initial is not None else None,
                   "torque_on_start": torque_on_start, "log_level": log_level}
        # A fresh interpreter (as multiprocessing's "spawn", but without re-running
        # the caller's __main__, so scripts without a __main__ guard work too).
        parent_sock, child_sock = socket.socketpair()
        self._lock = threading.Lock()
        code = (f"import sys; sys.path.insert(0, {str(_HERE)!r}); import virtual_so101; "
                f"virtual_so101._emulator_main({child_sock.fileno()})")
        self._process = subprocess.Popen([sys.executable, "-c", code],
                                         pass_fds=(child_sock.fileno(),), stdin=subprocess.DEVNULL)
        child_sock.close()
        self._conn = Connection(parent_sock.detach())
        self._conn.send(options)
        if not self._conn.poll(startup_timeout):
            self._process.kill()
            self._process.wait()
            raise VirtualSO101Error(f"The emulator did not start within {startup_timeout} s.")
        try:
            status, value = self._conn.recv()
        except EOFError:
            raise VirtualSO101Error("The emulator process died while starting.") from None
        if status == "err":
            self._process.wait(5)
            raise value
        self.port: str = value
        logger.info("virtual SO-101 on %s (pid %d)", self.port, self._process.pid)

    @property
    def pid(self) -> int:
        """Process id of the emulator process."""
        return self._process.pid

    # --- lifecycle ------------------------------------------------------------------------
    def __enter__(self) -> VirtualSO101:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop the emulator process (idempotent)."""
        if self._process is None:
            return
        try:
            with self._lock:
                self._conn.send(("close", ()))
                if self._conn.poll(5):
                    self._conn.recv()
        except (OSError, EOFError, BrokenPipeError):
            pass
        try:
            self._process.wait(5)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait(5)
        self._conn.close()
        self._process = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001, S110 - interpreter shutdown
            pass

    def _call(self, name: str, *args):
        if self._process is None:
            raise VirtualSO101Error("The virtual SO-101 is closed.")
        with self._lock:
            try:
                self._conn.send((name, args))
                status, value = self._conn.recv()
            except (EOFError, OSError) as exc:
                raise VirtualSO101Error("The emulator process is gone.") from exc
        if status == "err":
            raise value
        return value

    # --- public API -----------------------------------------------------------------------
    def joint_positions(self) -> dict[str, float]:
        """Measured joint positions in the simulation: [deg], gripper [0, 100]."""
        return self._call("joint_positions")

    def commanded_positions(self) -> dict[str, float]:
        """The position actuators' targets (from the goals received): [deg], gripper [0, 100]."""
        return self._call("commanded_positions")

    def goal_log(self) -> list[tuple[float, int, int]]:
        """Every Goal_Position write received, in order: (time.time() [s], servo id, raw ticks).

        The last ``GOAL_LOG_LENGTH`` writes are kept.
        """
        return self._call("goal_log")

    def clear_goal_log(self) -> None:
        """Forget the Goal_Position writes logged so far."""
        self._call("clear_goal_log")

    def torque_enabled(self) -> dict[str, bool]:
        """Joint name -> whether its servo's Torque_Enable is set."""
        return self._call("torque_enabled")

    def inject(self, spec: str) -> None:
        """Inject faults (grammar in the module docstring), e.g. ``"drop:3:5,corrupt:2"``."""
        self._call("inject", parse_faults(spec, self.calibration))

    def clear_faults(self) -> None:
        """Remove every fault (removed servos return, firmware back to 3.10, stalls released)."""
        self._call("clear_faults")

    def set_pose(self, cfg: Mapping[str, float]) -> None:
        """Teleport the arm to ``cfg`` ([deg], gripper [0, 100]) at rest; goals follow.

        Raises:
            so101_motion.JointLimitError: a value is outside the joint limits.
        """
        self._call("set_pose", dict(cfg))

    def set_torque(self, enabled: bool, joints: list[str] | None = None) -> None:
        """Set Torque_Enable as the host would (test setup); ``joints`` default: all.

        Enabling holds each joint where it is (Goal_Position := Present_Position).
        """
        unknown = [j for j in joints or () if j not in self._ids]
        if unknown:
            raise KeyError(f"Unknown joints {unknown}; joints are {list(self._ids)}.")
        self._call("set_torque", bool(enabled), list(joints) if joints else None)

    def set_wire_timing(self, enabled: bool) -> None:
        """Switch wire timing on or off while running."""
        self._call("set_wire_timing", enabled)

    def registers(self, joint: str) -> dict[str, int]:
        """The named registers of a joint's servo (decoded, for tests and debugging)."""
        if joint not in self._ids:
            raise KeyError(f"Unknown joint '{joint}'; joints are {list(self._ids)}.")
        return self._call("registers", joint)

    def power_cycle(self) -> None:
        """Cut the servos' power: RAM to factory values, EEPROM to what was saved (Lock = 0)."""
        self._call("power_cycle")

    def reply_stats(self) -> dict[str, float]:
        """Emulator health: replies sent, late ones, timing [ms].

        Keys: ``replies``; ``late_replies`` (sent > 45 ms after the request:
        lerobot may have given up); ``lateness_median_ms`` / ``_p99_ms`` /
        ``_max_ms`` (behind each reply's due time: the wire time with wire
        timing, else the request's arrival); ``max_loop_delay_ms`` (longest the
        emulator process was kept off the CPU past a wake-up); ``sim_time_s``,
        ``wall_time_s`` (the simulation keeps real time when they agree).
        """
        return self._call("reply_stats")

    def clear_stats(self) -> None:
        """Reset :meth:`reply_stats`."""
        self._call("clear_stats")


# =============================================================================================
# Measurement and command line
# =============================================================================================
SO101_MOTORS = {name: ("sts3215", ("range_0_100" if name == "gripper" else "degrees"))
                for name in JOINT_IDS}


def make_bus(arm: VirtualSO101, degrees: bool = True):
    """A lerobot ``FeetechMotorsBus`` for the arm with its calibration (needs lerobot).

    Args:
        arm: the virtual arm.
        degrees: arm joints in DEGREES (else RANGE_M100_100); the gripper is RANGE_0_100.
    """
    from lerobot.motors import Motor, MotorCalibration, MotorNormMode
    from lerobot.motors.feetech import FeetechMotorsBus

    body = MotorNormMode.DEGREES if degrees else MotorNormMode.RANGE_M100_100
    motors = {name: Motor(entry["id"], "sts3215",
                          MotorNormMode.RANGE_0_100 if name == "gripper" else body)
              for name, entry in arm.calibration.items()}
    calibration = {name: MotorCalibration(**entry) for name, entry in arm.calibration.items()}
    return FeetechMotorsBus(port=arm.port, motors=motors, calibration=calibration)


def cycle_wire_bytes(n_motors: int = 6) -> int:
    """Bytes on the wire for one sync_read(Present_Position) + sync_write(Goal_Position) cycle."""
    sync_read = (8 + n_motors) + n_motors * (6 + 2)
    sync_write = 8 + n_motors * (1 + 2)
    return sync_read + sync_write


class _LoopbackSerial:
    """A stand-in for the bus's pyserial port that answers SYNC_READs instantly, in-process.

    Timing lerobot against it gives the host's own cost of a cycle (packing,
    parsing, decoding), which a real arm costs too.
    """

    def __init__(self, replies: bytes):
        self.replies = replies
        self.buffer = bytearray()
        self.is_open = True

    def write(self, data) -> int:
        if len(data) > 4 and data[4] == INST_SYNC_READ:
            self.buffer += self.replies
        return len(data)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self.buffer[:size])
        del self.buffer[:size]
        return out

    @property
    def in_waiting(self) -> int:
        return len(self.buffer)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self.buffer.clear()

    def close(self) -> None:
        self.is_open = False


def _time_cycles(bus, n: int, warmup: int, on_warm=None) -> list[float]:
    """Durations [s] of n sync_read(Present_Position) + sync_write(Goal_Position) cycles."""
    times = []
    for i in range(n + warmup):
        t0 = time.perf_counter()
        present = bus.sync_read("Present_Position", normalize=False)
        bus.sync_write("Goal_Position", present, normalize=False)
        if i == warmup - 1 and on_warm is not None:
            on_warm()
        if i >= warmup:
            times.append(time.perf_counter() - t0)
    return sorted(times)


def measure_cycle(n: int = 1000, wire_timing: bool = True, arm: VirtualSO101 | None = None,
                  warmup: int = 50) -> dict[str, float]:
    """Time lerobot's 6-motor sync_read + sync_write cycle against the virtual arm (needs lerobot).

    Each cycle reads Present_Position and writes it back as Goal_Position (raw
    ticks), as a teleoperation loop does. The same cycles are then timed
    against an in-process loopback port, which gives lerobot's own (host) cost;
    what remains of the cycle after the wire time and the host cost is what
    the emulator adds (its wake-up and processing).

    Args:
        n: cycles to time.
        wire_timing: emulate the wire's byte time.
        arm: an existing virtual arm (else one is started and closed).
        warmup: cycles run before timing.

    Returns:
        ``cycle_median_ms`` / ``cycle_p99_ms`` (client side); ``wire_ms``
        (88 bytes x 10 bits at the bus's baud rate, 0 without wire timing);
        ``overhead_median_ms`` / ``_p99_ms`` (cycle - wire); ``host_median_ms``
        (lerobot's cost, loopback); ``emulator_added_median_ms`` (cycle median -
        wire - host median: without wire timing, the emulator's whole share,
        i.e. wake-ups, processing and the pty; with wire timing the host's work
        partly overlaps the sync_write's wire time, so it reads lower); the
        emulator's lateness behind each reply's due time
        (``emulator_lateness_median_ms`` / ``_p99_ms``) and ``late_replies``.
    """
    own = arm is None
    arm = arm or VirtualSO101(wire_timing=wire_timing)
    bus = None
    try:
        arm.set_wire_timing(wire_timing)
        bus = make_bus(arm)
        bus.connect()
        times = _time_cycles(bus, n, warmup, on_warm=arm.clear_stats)
        stats = arm.reply_stats()
        wire_ms = cycle_wire_bytes() * BITS_PER_BYTE / bus.port_handler.getBaudRate() * 1e3
        wire_ms = wire_ms if wire_timing else 0.0
        present = bus.sync_read("Present_Position", normalize=False)
        replies = b"".join(status_packet(bus.motors[name].id, 0, value.to_bytes(2, "little"))
                           for name, value in present.items())
        serial_port = bus.port_handler.ser
        bus.port_handler.ser = _LoopbackSerial(replies)
        try:
            host = _time_cycles(bus, n, warmup)
        finally:
            bus.port_handler.ser = serial_port
        median, p99 = 1e3 * statistics.median(times), 1e3 * times[int(0.99 * (len(times) - 1))]
        host_median = 1e3 * statistics.median(host)
        return {
            "cycles": n, "wire_timing": wire_timing, "wire_ms": wire_ms,
            "cycle_median_ms": median, "cycle_p99_ms": p99,
            "overhead_median_ms": median - wire_ms, "overhead_p99_ms": p99 - wire_ms,
            "host_median_ms": host_median,
            "emulator_added_median_ms": median - wire_ms - host_median,
            "emulator_lateness_median_ms": stats["lateness_median_ms"],
            "emulator_lateness_p99_ms": stats["lateness_p99_ms"],
            "late_replies": stats["late_replies"],
        }
    finally:
        if bus is not None:
            bus.disconnect(disable_torque=False)
        if own:
            arm.close()


def main(argv: list[str] | None = None) -> int:
    """Serve a virtual SO-101 until Ctrl-C."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", default=str(DEFAULT_CALIBRATION_PATH),
                        help="lerobot calibration JSON (default: %(default)s)")
    parser.add_argument("--viewer", action="store_true", help="show the arm (needs a display)")
    parser.add_argument("--wire-timing", action="store_true",
                        help="delay replies by their byte time at the host's baud rate")
    parser.add_argument("--faults", default=None,
                        help="faults from power-up, e.g. 'drop:3:5,stall:elbow_flex'")
    parser.add_argument("--write-default-calibration", metavar="PATH",
                        help="write the calibration derived from the model to PATH and exit")
    parser.add_argument("-v", "--verbose", action="store_true", help="log every fault and start-up")
    args = parser.parse_args(argv)
    level = logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=level, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    if args.write_default_calibration:
        import so101_mujoco_utils

        calibration = make_default_calibration(so101_mujoco_utils.load_model())
        Path(args.write_default_calibration).write_text(json.dumps(calibration, indent=4) + "\n")
        return 0
    if args.viewer and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print("error: --viewer needs a display (DISPLAY or WAYLAND_DISPLAY is not set); "
              "run without --viewer.", file=sys.stderr)
        return 2
    try:
        arm = VirtualSO101(calibration=args.calibration, wire_timing=args.wire_timing,
                           faults=args.faults, viewer=args.viewer, log_level=level)
    except (CalibrationError, FaultSpecError, VirtualSO101Error) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with arm:
        print(arm.port, flush=True)
        logger.warning("virtual SO-101 serving on %s (wire timing %s); Ctrl-C to stop",
                       arm.port, "on" if args.wire_timing else "off")
        try:
            arm._process.wait()
        except KeyboardInterrupt:
            logger.warning("stopping")
    return 0


if __name__ == "__main__":
    sys.exit(main())
