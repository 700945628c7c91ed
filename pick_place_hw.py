"""Pick-and-place on a real SO-101 follower through lerobot's FeetechMotorsBus, safe by default."""

from __future__ import annotations

import argparse
import csv
import gc
import json
import logging
import math
import os
import signal
import sys
import threading
import time
import weakref
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache, lru_cache
from pathlib import Path
from typing import Any, NamedTuple

from so101_forward_kinematics import ARM_JOINTS, JOINTS, get_forward_kinematics
from so101_inverse_kinematics import add_cartesian_arguments, plan_from_arguments
from so101_motion import (
    PROFILES,
    Configuration,
    JointLimitError,
    Limits,
    Plan,
    PlanError,
    Step,
    Trajectory,
    check_configuration,
    default_plan,
    load_plan,
    pick_and_place_steps,
    run_plan,
    unit,
    validate_plan,
)

logger = logging.getLogger("pick_place_hw")

# --- Settings ---------------------------------------------------------------
DEFAULT_RATE_HZ = 100.0            # control loop rate [Hz]
MAX_RATE_HZ = 1000.0               # the bus cannot do a 6-motor cycle much faster
MAX_JOINT_SPEED_DEG_S = 100.0      # speed cap of each arm joint [deg/s] (peak of the profile)
MAX_GRIPPER_SPEED_PCT_S = 100.0    # speed cap of the gripper [%/s]
RETURN_SPEED_DEG_S = 20.0          # "slowly": return after an abort [deg/s] (gripper [%/s])
RETURN_MIN_DURATION_S = 1.0        # the return after an abort never takes less [s]
TRACKING_TOLERANCE_DEG = 15.0      # measured vs commanded, arm joints [deg] ...
TRACKING_TIMEOUT_S = 0.3           # ... beyond it for this long [s] is a stall or a collision
MAX_MISSED_READS = 2               # consecutive failed Present_Position reads tolerated
SPIN_S = 0.0005                    # busy-wait this last part of each period [s]
IDLE_RESTART_S = 0.25              # a loop idle for longer starts a fresh deadline grid [s]
PORT_SETTLE_S = 0.06               # a late reply dies out within the SDK's 50 ms timeout [s]
TEACH_RATE_HZ = 5.0                # live pose printing in --teach [Hz]
LIMIT_SLACK_DEG = 2.0              # a start this far outside the calibration is clamped [deg]

ROBOT_TYPE = "so101_follower"
# lerobot 0.4.x files SO-100/SO-101 calibrations under the robot class name
# "so_follower"; lerobot 0.2-0.3 used the type name "so101_follower".
CALIBRATION_SUBDIRS = ("so_follower", "so101_follower")
MOTOR_IDS = {"shoulder_pan": 1, "shoulder_lift": 2, "elbow_flex": 3, "wrist_flex": 4,
             "wrist_roll": 5, "gripper": 6}
"""Servo id of each joint on the SO-101 follower (lerobot's SOFollower)."""
MOTOR_MODEL = "sts3215"
TICKS_PER_TURN = 4095  # lerobot's max_res for the sts3215: 4096 positions - 1
INSTALL_HINT = "pip install -e '.[hw]'  (from the so101-kinematics folder)"
FIND_PORT_HINT = "lerobot-find-port"
CALIBRATE_HINT = (f"lerobot-calibrate --robot.type={ROBOT_TYPE} --robot.port={{port}} "
                  "--robot.id={robot_id}")


# --- Errors -----------------------------------------------------------------
class HardwareError(RuntimeError):
    """The arm cannot be used as asked; the message says what to do."""


class LerobotMissing(HardwareError):
    """lerobot (the ``hw`` extra) is not installed."""


class CalibrationError(HardwareError):
    """The calibration file is missing, malformed, or does not match the servos."""


class ConnectionFailed(HardwareError):
    """The port cannot be opened or a servo does not answer."""


class NotConfirmed(HardwareError):
    """The user did not confirm (or could not be asked)."""


class TrackingError(HardwareError):
    """A joint stayed too far from its command for too long: a stall or a collision."""


class BusError(HardwareError):
    """The bus failed during motion (a servo stopped answering, the port closed)."""


class StopRequested(HardwareError):
    """A stop was requested (Ctrl-C) and honoured at the next control cycle."""


class MotionAborted(HardwareError):
    """The motion was aborted; ``result`` tells whether the arm returned and torque is off."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result


# --- lerobot, imported lazily ------------------------------------------------
def import_lerobot() -> Any:
    """Import lerobot's Feetech bus (slow: it imports PyTorch) or explain how to install it.

    Returns:
        A namespace with ``FeetechMotorsBus``, ``Motor``, ``MotorCalibration``,
        ``MotorNormMode`` and ``OperatingMode``.

    Raises:
        LerobotMissing: lerobot or its Feetech SDK is not installed.
    """
    try:
        from lerobot.motors import Motor, MotorCalibration, MotorNormMode
        from lerobot.motors.feetech import FeetechMotorsBus, OperatingMode
    except ImportError as error:
        raise LerobotMissing(
            f"lerobot with its Feetech SDK is needed to talk to the arm ({error}). "
            f"Install it with: {INSTALL_HINT}"
        ) from None
    import types

    return types.SimpleNamespace(FeetechMotorsBus=FeetechMotorsBus, Motor=Motor,
                                 MotorCalibration=MotorCalibration, MotorNormMode=MotorNormMode,
                                 OperatingMode=OperatingMode)


# --- Calibration -------------------------------------------------------------
@dataclass(frozen=True)
class ServoCalibration:
    """One joint's entry of a lerobot calibration file (raw encoder ticks)."""

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int


def lerobot_calibration_root() -> Path:
    """Where lerobot keeps calibrations, resolved as lerobot does (without importing it).

    ``HF_LEROBOT_CALIBRATION``, else ``HF_LEROBOT_HOME/calibration``, else
    ``HF_HOME/lerobot/calibration`` (``HF_HOME`` defaults to
    ``$XDG_CACHE_HOME/huggingface`` or ``~/.cache/huggingface``).
    """
    if os.environ.get("HF_LEROBOT_CALIBRATION"):
        return Path(os.environ["HF_LEROBOT_CALIBRATION"]).expanduser()
    if os.environ.get("HF_LEROBOT_HOME"):
        return Path(os.environ["HF_LEROBOT_HOME"]).expanduser() / "calibration"
    hf_home = os.environ.get("HF_HOME")
    if not hf_home:
        cache = os.environ.get("XDG_CACHE_HOME") or str(Path("~/.cache").expanduser())
        hf_home = os.path.join(cache, "huggingface")
    return Path(hf_home).expanduser() / "lerobot" / "calibration"


def calibration_candidates(robot_id: str) -> list[Path]:
    """The files lerobot would use for a follower with this id, newest layout first."""
    root = lerobot_calibration_root() / "robots"
    return [root / sub / f"{robot_id}.json" for sub in CALIBRATION_SUBDIRS]


def find_calibration(robot_id: str, port: str | None = None) -> Path:
    """Locate the calibration file ``lerobot-calibrate`` wrote for ``robot_id``.

    Raises:
        CalibrationError: no file, naming the places searched and the command that writes one.
    """
    candidates = calibration_candidates(robot_id)
    for path in candidates:
        if path.is_file():
            return path
    searched = "\n  ".join(str(p) for p in candidates)
    fix = CALIBRATE_HINT.format(port=port or "PORT", robot_id=robot_id)
    raise CalibrationError(
        f"No calibration for robot id '{robot_id}'. Searched:\n  {searched}\n"
        f"Fix: calibrate the arm with `{fix}`, or pass the file with --calibration PATH."
    )


def load_calibration(path: str | Path, robot_id: str | None = None) -> dict[str, ServoCalibration]:
    """Read and check a lerobot calibration file (the JSON ``lerobot-calibrate`` writes).

    Args:
        path: the JSON file.
        robot_id: only for the fix suggested in error messages.

    Returns:
        joint name -> :class:`ServoCalibration`, in ``JOINTS`` order.

    Raises:
        CalibrationError: missing file, invalid JSON, missing or unknown joints,
            wrong servo ids, non-integer fields, an empty or out-of-encoder range.
    """
    path = Path(path)
    command = CALIBRATE_HINT.format(port="PORT", robot_id=robot_id or path.stem)
    fix = f"Fix: recalibrate with `{command}` or pass the right file with --calibration."
    name = f"Calibration file '{path}'"
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise CalibrationError(f"{name} does not exist. {fix}") from None
    except OSError as error:
        raise CalibrationError(f"Cannot read {name}: {error.strerror}.") from None
    except ValueError as error:
        raise CalibrationError(f"{name} is not valid JSON ({error}). {fix}") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{name} must map joint names to calibrations. {fix}")
    unknown = sorted(set(data) - set(JOINTS))
    missing = [j for j in JOINTS if j not in data]
    if unknown or missing:
        raise CalibrationError(
            f"{name} is not an SO-101 follower calibration: "
            + (f"missing {missing}" if missing else "")
            + ("; " if missing and unknown else "")
            + (f"unknown {unknown}" if unknown else "")
            + f". Expected exactly: {', '.join(JOINTS)}. {fix}"
        )
    out = {}
    for joint in JOINTS:
        entry = data[joint]
        fields = ("id", "drive_mode", "homing_offset", "range_min", "range_max")
        if not isinstance(entry, dict) or any(k not in entry for k in fields):
            raise CalibrationError(f"{name}: {joint} needs the fields "
                                   f"{', '.join(fields)}. {fix}")
        for key in fields:
            value = entry[key]
            if isinstance(value, bool) or not isinstance(value, int):
                raise CalibrationError(f"{name}: {joint}.{key} must be an integer, got "
                                       f"{value!r}. {fix}")
        cal = ServoCalibration(*(entry[k] for k in fields))
        if cal.id != MOTOR_IDS[joint]:
            raise CalibrationError(f"{name}: {joint} has servo id {cal.id}; the "
                                   f"SO-101 follower uses id {MOTOR_IDS[joint]} for it. {fix}")
        if cal.drive_mode not in (0, 1):
            raise CalibrationError(f"{name}: {joint}.drive_mode = {cal.drive_mode}; it must be "
                                   f"0 or 1. {fix}")
        if abs(cal.homing_offset) > 2047:
            raise CalibrationError(f"{name}: {joint}.homing_offset = "
                                   f"{cal.homing_offset} is beyond +-2047 ticks. {fix}")
        if not 0 <= cal.range_min < cal.range_max <= TICKS_PER_TURN:
            raise CalibrationError(
                f"{name}: {joint} range [{cal.range_min}, {cal.range_max}] ticks must satisfy "
                f"0 <= range_min < range_max <= {TICKS_PER_TURN} (an empty range means the joint "
                f"was not moved through its range during calibration). {fix}")
        out[joint] = cal
    return out


def ticks_to_user(joint: str, raw: float, cal) -> float:
    """Raw Present/Goal_Position ticks -> [deg] (gripper [0, 100]), exactly as lerobot normalises.

    Args:
        joint: joint name (the gripper uses RANGE_0_100, the others DEGREES).
        raw: encoder ticks.
        cal: the joint's calibration (anything with ``range_min``, ``range_max``, ``drive_mode``).
    """
    lo, hi = cal.range_min, cal.range_max
    if joint == "gripper":
        value = (min(hi, max(lo, raw)) - lo) / (hi - lo) * 100.0
        return 100.0 - value if cal.drive_mode else value
    return (raw - (lo + hi) / 2.0) * 360.0 / TICKS_PER_TURN


def calibrated_limits(calibration: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """The calibrated range of each joint: [deg] for the arm, (0, 100) for the gripper."""
    limits = {}
    for joint in JOINTS:
        cal = calibration[joint]
        if joint == "gripper":
            limits[joint] = (0.0, 100.0)
        else:
            limits[joint] = (ticks_to_user(joint, cal.range_min, cal),
                             ticks_to_user(joint, cal.range_max, cal))
    return limits


@lru_cache(maxsize=1)
def model_limits() -> dict[str, tuple[float, float]]:
    """The MuJoCo model's joint limits in user units (the simulator's, so sim and hw agree)."""
    import so101_mujoco_utils

    return so101_mujoco_utils.joint_limits(so101_mujoco_utils.load_model())


def validate_plan_for_arm(plan: Plan, calibration: Mapping[str, Any] | None,
                          source: str = "the calibration") -> Plan:
    """Check every waypoint against the model's limits and the arm's calibrated limits.

    Args:
        plan: the plan.
        calibration: joint -> calibration, or None to check the model's limits only.
        source: where the calibration came from (for messages).

    Returns:
        The plan, configurations normalised to floats.

    Raises:
        PlanError: bad structure; JointLimitError naming joint, value, limit,
            which limits (model or calibration) and the fix.
    """
    try:
        validate_plan(plan, model_limits())
    except JointLimitError as error:
        raise JointLimitError(f"{error} (joint limits of the SO-101 model, as in the simulator)") \
            from None
    if calibration is not None:
        try:
            validate_plan(plan, calibrated_limits(calibration))
        except JointLimitError as error:
            raise JointLimitError(f"{error} (calibrated range of this arm, from {source}; if the "
                                  "range looks too small, recalibrate)") from None
    for label, value in (("return_duration", plan.return_duration),):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value < 0:
            raise PlanError(f"The plan's {label} must be a number of seconds >= 0, got {value!r}.")
    return plan


# --- Speed cap ---------------------------------------------------------------
@cache
def peak_speed_factor(profile: str) -> float:
    """Peak of d(fraction)/ds for a time-scaling profile (1 for linear, 1.875 for minimum jerk)."""
    scaling = PROFILES[profile]
    n = 4000
    return max((scaling((i + 1) / n) - scaling(i / n)) * n for i in range(n))


def speed_caps(max_joint_speed: float = MAX_JOINT_SPEED_DEG_S,
               max_gripper_speed: float = MAX_GRIPPER_SPEED_PCT_S) -> dict[str, float]:
    """Joint -> speed cap ([deg/s]; gripper [%/s])."""
    return {j: (max_gripper_speed if j == "gripper" else max_joint_speed) for j in JOINTS}


def tracking_tolerances(arm_tolerance: float = TRACKING_TOLERANCE_DEG) -> dict[str, float | None]:
    """Joint -> tracking tolerance [deg].

    The gripper is not checked: it squeezes the cube by design, and lerobot's
    configuration limits its torque and current instead.
    """
    return {j: (None if j == "gripper" else arm_tolerance) for j in JOINTS}


def capped_duration(start: Mapping[str, float], goal: Mapping[str, float], duration: float,
                    profile: str, max_speed: Mapping[str, float]) -> float:
    """The shortest duration >= ``duration`` [s] that keeps every joint under its speed cap.

    Args:
        start: configuration at the start ([deg], gripper [0, 100]).
        goal: configuration at the end.
        duration: the requested duration [s].
        profile: time scaling of the move ("minimum_jerk" or "linear").
        max_speed: joint -> cap ([deg/s]; gripper [%/s]).

    Example:
        >>> capped_duration({"shoulder_pan": 0.0}, {"shoulder_pan": 90.0}, 1.0, "linear",
        ...                 {"shoulder_pan": 45.0})
        2.0
    """
    factor = peak_speed_factor(profile)
    needed = max((abs(goal[j] - start[j]) * factor / max_speed[j] for j in goal), default=0.0)
    return max(float(duration), needed)


# --- Deadline scheduler ----------------------------------------------------------
class RateLoop:
    """Fixed-rate, deadline-scheduled loop: ``next_deadline += period``, sleep, spin the last bit.

    A late cycle is counted as an overrun and the loop runs on at once; when
    more than a whole period late, the missed deadlines are skipped (never
    replayed in a burst).

    Args:
        rate_hz: loop rate [Hz].
        clock: monotonic clock [s].
        sleep: sleep function [s].
        spin: busy-wait this last part of each wait [s].
    """

    def __init__(self, rate_hz: float, clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep, spin: float = SPIN_S):
        if not (isinstance(rate_hz, (int, float)) and 0 < rate_hz <= MAX_RATE_HZ):
            raise ValueError(f"rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}.")
        self.period = 1.0 / float(rate_hz)
        self.clock, self.sleep, self.spin = clock, sleep, spin
        self.deadline: float | None = None
        self.woke = 0.0  # when the last wait returned [s]
        self.cycles = self.overruns = self.skipped = 0

    def start(self) -> float:
        """Make now the current deadline; returns it [s]."""
        self.deadline = self.woke = self.clock()
        return self.deadline

    def resume(self) -> float:
        """The grid point a new segment starts from: the latest deadline not in the future.

        Continues the grid (skipping missed deadlines) when the loop was busy
        until now; starts afresh after an idle gap longer than ``IDLE_RESTART_S``.
        """
        if self.deadline is None:
            return self.start()
        behind = self.clock() - self.deadline
        if behind > IDLE_RESTART_S:
            return self.start()
        if behind >= self.period:
            missed = int(behind // self.period)
            self.skipped += missed
            self.deadline += missed * self.period
        return self.deadline

    def wait(self) -> float:
        """Wait for the next deadline and return it (the cycle's scheduled time [s])."""
        if self.deadline is None:
            self.start()
        self.deadline += self.period
        now = self.clock()
        late = now - self.deadline
        if late > 0.0:
            self.overruns += 1
            if late >= self.period:
                missed = int(late // self.period)
                self.skipped += missed
                self.deadline += missed * self.period
        else:
            remaining = -late
            if remaining > self.spin:
                self.sleep(remaining - self.spin)
            while self.clock() < self.deadline:
                pass
        self.cycles += 1
        self.woke = self.clock()
        return self.deadline


def loop_timing_stats(wake_times: list[float], rate_hz: float) -> dict[str, float]:
    """Period statistics of a loop from the times its cycles started [s].

    Returns:
        ``achieved_hz``, ``period_p50_ms``, ``period_p99_error_ms`` (99th percentile
        of |period - nominal|), ``period_max_error_ms`` and ``cycles``.
    """
    import numpy as np

    times = np.asarray(wake_times, dtype=float)
    if times.size < 3:
        raise ValueError("need at least 3 cycles for timing statistics")
    periods = np.diff(times)
    error = np.abs(periods - 1.0 / rate_hz)
    return {
        "rate_hz": float(rate_hz),
        "achieved_hz": float((times.size - 1) / (times[-1] - times[0])),
        "period_p50_ms": float(np.median(periods) * 1e3),
        "period_p99_error_ms": float(np.percentile(error, 99) * 1e3),
        "period_max_error_ms": float(error.max() * 1e3),
        "cycles": int(times.size),
    }


# --- The bus -----------------------------------------------------------------
def make_bus(port: str, calibration: Mapping[str, ServoCalibration]):
    """A lerobot FeetechMotorsBus with the SO-101 follower's motors (not connected yet).

    Arm joints are normalised in DEGREES and the gripper in RANGE_0_100, as
    lerobot's SO-101 follower does (``use_degrees=True``).
    """
    lr = import_lerobot()
    norm = {j: lr.MotorNormMode.RANGE_0_100 if j == "gripper" else lr.MotorNormMode.DEGREES
            for j in JOINTS}
    motors = {joint: lr.Motor(MOTOR_IDS[joint], MOTOR_MODEL, norm[joint]) for joint in JOINTS}
    cal = {j: lr.MotorCalibration(c.id, c.drive_mode, c.homing_offset, c.range_min, c.range_max)
           for j, c in calibration.items()}
    return lr.FeetechMotorsBus(port=port, motors=motors, calibration=cal)


def connect(port: str, calibration: Mapping[str, ServoCalibration], *, robot_id: str | None = None,
            write_calibration: bool = False):
    """Open the port, check every servo answers and holds this calibration; nothing moves.

    Args:
        port: serial port (``lerobot-find-port`` tells which).
        calibration: from :func:`load_calibration`.
        robot_id: for the messages.
        write_calibration: if the servos' calibration registers differ from the
            file, write the file into them (as ``lerobot-calibrate`` offers) instead of refusing.

    Returns:
        The connected bus (torque untouched).

    Raises:
        ConnectionFailed: no such port, or a servo missing / of the wrong model or firmware.
        CalibrationError: the servos hold another calibration.
        LerobotMissing: lerobot is not installed.
    """
    import_lerobot()  # first: without lerobot nothing else matters
    if not port:
        raise ConnectionFailed(f"No port given. Find the arm's port with `{FIND_PORT_HINT}` "
                               "and pass it with --port.")
    if port.startswith("/") and not os.path.exists(port):
        raise ConnectionFailed(f"Port '{port}' does not exist. Is the arm's USB cable plugged in? "
                               f"Find the port with `{FIND_PORT_HINT}`.")
    bus = make_bus(port, calibration)
    try:
        bus.connect()
    except ConnectionError as error:
        raise ConnectionFailed(f"Cannot open port '{port}': {str(error).strip()} "
                               f"Find the port with `{FIND_PORT_HINT}`.") from None
    except RuntimeError as error:
        raise ConnectionFailed(
            f"The servos on '{port}' did not pass lerobot's check:\n{error}\n"
            "Fix: switch on the arm's power supply, check the cables between the servos, and make "
            "sure the ids were set with `lerobot-setup-motors --robot.type=so101_follower`."
        ) from None
    try:
        with bus_errors("reading the servos' calibration"):
            mismatch = calibration_mismatch(bus, calibration)
        if mismatch:
            if not write_calibration:
                fix = CALIBRATE_HINT.format(port=port, robot_id=robot_id or "ID")
                raise CalibrationError(
                    "The servos hold a different calibration than the file ("
                    + "; ".join(mismatch) + "). The file may belong to another arm (check --id), "
                    f"or the arm was recalibrated. Fix: `{fix}`, or pass --write-calibration to "
                    "write the file into the servos.")
            logger.warning("Writing the calibration file into the servos (%s).",
                           "; ".join(mismatch))
            bus.disable_torque()
            bus.write_calibration(bus.calibration)
    except BaseException:
        disconnect(bus)
        raise
    return bus


def calibration_mismatch(bus, calibration: Mapping[str, ServoCalibration]) -> list[str]:
    """Differences between the servos' Homing_Offset / Min / Max_Position_Limit and the file."""
    differences = []
    for joint, servo in bus.read_calibration().items():
        ours = calibration[joint]
        for key in ("homing_offset", "range_min", "range_max"):
            theirs, mine = getattr(servo, key), getattr(ours, key)
            if theirs != mine:
                differences.append(f"{joint} {key}: servo {theirs}, file {mine}")
    return differences


def configure(bus) -> None:
    """Configure the servos as lerobot's SO-101 follower does, leaving torque OFF.

    Position mode, P = 16, I = 0, D = 32 on every joint; the gripper's torque
    and current limited (50 % torque, 250 protection current, 25 % overload torque).
    """
    lr = import_lerobot()
    bus.disable_torque()
    bus.configure_motors()
    for motor in bus.motors:
        bus.write("Operating_Mode", motor, lr.OperatingMode.POSITION.value)
        bus.write("P_Coefficient", motor, 16)
        bus.write("I_Coefficient", motor, 0)
        bus.write("D_Coefficient", motor, 32)
        if motor == "gripper":
            bus.write("Max_Torque_Limit", motor, 500)
            bus.write("Protection_Current", motor, 250)
            bus.write("Overload_Torque", motor, 25)


def enable_torque_in_place(bus) -> None:
    """Set each Goal_Position to the present position (inside the calibrated range), then torque on.

    A servo holds whatever its goal register contains when torque comes on;
    writing the present position first means nothing jumps.
    """
    raw = bus.sync_read("Present_Position", normalize=False)
    goal = {}
    for joint, ticks in raw.items():
        cal = bus.calibration[joint]
        goal[joint] = min(cal.range_max, max(cal.range_min, int(ticks)))
    bus.sync_write("Goal_Position", goal, normalize=False)
    bus.enable_torque()


def discard_stale_input(bus) -> int:
    """Drop bytes waiting on the port before a request: late replies that would poison it.

    The Feetech SDK matches replies by servo id only, so a reply that arrived
    after its transaction timed out is taken for the next transaction's (the
    read then returns values one cycle old, silently). lerobot flushes input
    only when opening the port (its clearPort() flushes output). Returns the
    number of bytes dropped.
    """
    serial_port = getattr(bus.port_handler, "ser", None)
    waiting = getattr(serial_port, "in_waiting", 0)
    if waiting:
        serial_port.reset_input_buffer()
    return waiting


def _recover_port(bus) -> None:
    """After an interrupted transaction: let late replies arrive, drop them, free the port."""
    try:
        time.sleep(PORT_SETTLE_S)
        discard_stale_input(bus)
        bus.port_handler.is_using = False
    except Exception:  # noqa: BLE001 - best effort on a failing port
        logger.debug("could not flush the port", exc_info=True)


@contextmanager
def bus_errors(what: str):
    """Turn lerobot's bus exceptions during ``what`` into a ConnectionFailed with the fix."""
    try:
        yield
    except (ConnectionError, RuntimeError, OSError) as error:
        if isinstance(error, HardwareError):
            raise
        raise ConnectionFailed(
            f"The arm stopped answering while {what}: {str(error).strip()} Fix: check the arm's "
            "power supply and the cables between the servos, then run again.") from error


def release_torque(bus) -> list[str]:
    """Torque off on every servo, each tried on its own; returns the joints that did not answer.

    A servo that answers with an error flag (e.g. overload after a stall) has
    still executed the write: lerobot raises RuntimeError for the flag, and
    that counts as released. No answer at all (ConnectionError) does not.
    """
    _recover_port(bus)
    failed = []
    for joint in bus.motors:
        try:
            for register in ("Torque_Enable", "Lock"):
                try:
                    bus.write(register, joint, 0, num_retry=2)
                except RuntimeError as error:  # answered, with an error flag (not ConnectionError)
                    logger.warning("%s answered with an error flag: %s", joint, error)
        except Exception:  # noqa: BLE001 - keep releasing the others
            failed.append(joint)
    return failed


def silent_servos(bus) -> list[str]:
    """The joints whose servo does not answer a ping now."""
    _recover_port(bus)
    silent = []
    for joint in bus.motors:
        try:
            if bus.ping(joint, num_retry=1) is None:
                silent.append(joint)
        except Exception:  # noqa: BLE001
            silent.append(joint)
    return silent


def disconnect(bus) -> None:
    """Close the port, leaving torque as it is (release it first: :func:`release_torque`)."""
    try:
        if bus.is_connected:
            bus.disconnect(disable_torque=False)
    except Exception:  # noqa: BLE001
        logger.debug("disconnect failed", exc_info=True)


# --- The control loop ------------------------------------------------------------
class Cycle(NamedTuple):
    """One control cycle: scheduled and wake time since start [s], step, command, measurement."""

    t_s: float
    wall_s: float
    step: str
    command: Configuration
    measured: Configuration | None


@dataclass
class Segment:
    """A move or a hold as executed, on the session's timeline."""

    kind: str  # "move" or "hold"
    step: str
    t_start_s: float  # [s] since the session's first cycle was scheduled
    start: Configuration
    goal: Configuration
    duration: float  # [s], after the speed cap
    requested: float  # [s], as asked


_SESSIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class ArmSession:
    """A connected arm plus the state of its control loop.

    Created for a bus, it is found again by :func:`move_to_pose` and
    :func:`hold_position`, so the course's ``move_to_pose(bus, cfg, 2.0)`` works.

    Args:
        bus: a connected lerobot ``FeetechMotorsBus`` (calibration set).
        rate_hz: control loop rate [Hz].
        profile: "minimum_jerk" (default, as the simulator) or "linear".
        max_speed: joint -> speed cap ([deg/s]; gripper [%/s]).
        tracking_tolerance: joint -> |measured - commanded| allowed [deg]
            (None: not checked; the gripper by default, as it squeezes the cube).
        tracking_timeout: how long a joint may stay beyond it [s].
        max_missed_reads: consecutive failed reads tolerated before a bus error.
        on_cycle: called with (session, cycle) after each cycle (tests, monitors).
        clock, sleep: time sources (tests).
    """

    def __init__(self, bus, *, rate_hz: float = DEFAULT_RATE_HZ, profile: str = "minimum_jerk",
                 max_speed: Mapping[str, float] | None = None,
                 tracking_tolerance: Mapping[str, float | None] | None = None,
                 tracking_timeout: float = TRACKING_TIMEOUT_S,
                 max_missed_reads: int = MAX_MISSED_READS,
                 on_cycle: Callable[[ArmSession, Cycle], None] | None = None,
                 clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep):
        if profile not in PROFILES:
            raise PlanError(f"Unknown profile '{profile}'; use one of {', '.join(PROFILES)}.")
        self.bus = bus
        self.limits = calibrated_limits(bus.calibration)
        self.loop = RateLoop(rate_hz, clock, sleep)
        self.profile = profile
        self.max_speed = dict(max_speed or speed_caps())
        if tracking_tolerance is None:
            tracking_tolerance = tracking_tolerances(TRACKING_TOLERANCE_DEG)
        self.tracking_tolerance = dict(tracking_tolerance)
        self.tracking_timeout = tracking_timeout
        self.max_missed_reads = max_missed_reads
        self.on_cycle = on_cycle
        self.cycles: list[Cycle] = []
        self.segments: list[Segment] = []
        self.stretched: list[str] = []
        self.command: Configuration | None = None  # last command sent
        self.step = ""
        self.stop_reason: str | None = None
        self._t0: float | None = None
        self._beyond: dict[str, float] = {}
        self._missed = 0
        self.stale_bytes = 0  # late-reply bytes dropped before reads
        _SESSIONS[bus] = self

    # measurement and command
    def read_pose(self) -> Configuration:
        """Present_Position of every joint ([deg]; gripper [0, 100]); raises BusError."""
        try:
            pose = self.bus.sync_read("Present_Position")
        except Exception as error:  # noqa: BLE001 - lerobot raises ConnectionError/RuntimeError
            raise BusError(f"Cannot read the arm's position: {error}") from error
        return {j: float(pose[j]) for j in JOINTS}

    def _guard(self, command: Mapping[str, float]) -> Configuration:
        """Last line of defence: refuse a command outside the calibrated range."""
        out = {}
        for joint in JOINTS:
            lower, upper = self.limits[joint]
            value = command[joint]
            if not (lower - 1e-6 <= value <= upper + 1e-6):
                raise JointLimitError(
                    f"Command {joint} = {value:g} {unit(joint)} is outside the calibrated range "
                    f"[{lower:g}, {upper:g}] {unit(joint)}; nothing was sent.")
            out[joint] = min(upper, max(lower, value))
        return out

    def _cycle(self, command_at: Callable[[float], Mapping[str, float]]) -> float:
        """Wait for the next deadline, command, measure, check, log; returns the deadline [s]."""
        deadline = self.loop.wait()
        if self.stop_reason is not None:
            raise StopRequested(self.stop_reason)
        previous = self.command
        command = self._guard(command_at(deadline))
        try:
            self.bus.sync_write("Goal_Position", command)
        except Exception as error:  # noqa: BLE001
            raise BusError(f"Cannot send Goal_Position: {error}") from error
        self.command = command
        try:
            stale = discard_stale_input(self.bus)
            if stale:
                self.stale_bytes += stale
                logger.debug("dropped %d stale bytes (a late reply)", stale)
            raw = self.bus.sync_read("Present_Position")
            measured = {j: float(raw[j]) for j in JOINTS}
            self._missed = 0
        except Exception as error:  # noqa: BLE001
            self._missed += 1
            measured = None
            logger.warning("Present_Position read failed (%d in a row): %s", self._missed, error)
            if self._missed > self.max_missed_reads:
                raise BusError(f"{self._missed} Present_Position reads in a row failed: {error}") \
                    from error
        if measured is not None and previous is not None:
            self._check_tracking(previous, measured, deadline)
        cycle = Cycle(deadline - self._t0, self.loop.woke - self._t0, self.step, command, measured)
        self.cycles.append(cycle)
        if self.on_cycle is not None:
            self.on_cycle(self, cycle)
        return deadline

    def _check_tracking(self, commanded: Configuration, measured: Configuration,
                        now: float) -> None:
        for joint, tolerance in self.tracking_tolerance.items():
            if tolerance is None:
                continue
            error = abs(measured[joint] - commanded[joint])
            if error <= tolerance:
                self._beyond.pop(joint, None)
                continue
            since = self._beyond.setdefault(joint, now)
            if now - since >= self.tracking_timeout:
                raise TrackingError(
                    f"{joint} does not follow its command: measured {measured[joint]:.1f} "
                    f"{unit(joint)}, commanded {commanded[joint]:.1f} {unit(joint)} (error "
                    f"{error:.1f} > tolerance {tolerance:g} {unit(joint)} for "
                    f"{now - since:.2f} s). Something blocks the arm (the table, an object, a "
                    "cable) or the servo is overloaded: clear the way and check the power supply; "
                    "--tracking-tolerance changes the tolerance.")

    # motion
    def _begin(self) -> float:
        """Start (or continue) the loop for a new segment; returns its start time [s]."""
        t_start = self.loop.resume()
        if self._t0 is None:
            self._t0 = t_start
        return t_start

    def move(self, cfg: Mapping[str, float], duration: float, step: str | None = None,
             max_speed: Mapping[str, float] | None = None) -> Segment:
        """Move from the last command (the measured pose at first) to ``cfg`` in ``duration`` [s].

        The duration is stretched (with a warning) if a joint would exceed its speed cap.

        Raises:
            JointLimitError: ``cfg`` is outside the calibrated range (nothing sent).
            TrackingError, BusError, StopRequested: see :class:`ArmSession`.
        """
        goal = check_configuration(cfg, self.limits, "move_to_pose target (calibrated range)")
        if step is not None:
            self.step = step
        if self.command is None:
            self.command = self.read_pose()  # the first move ramps from where the arm is
        start = dict(self.command)
        requested = float(duration)
        caps = max_speed or self.max_speed
        duration = capped_duration(start, goal, requested, self.profile, caps)
        if duration > requested + 1e-9:
            fastest = max(goal, key=lambda j: abs(goal[j] - start[j]) / caps[j])
            distance = abs(goal[fastest] - start[fastest])
            message = (f"'{self.step}': {requested:.2f} s is too fast for the speed cap "
                       f"({fastest} moves {distance:.1f} {unit(fastest)}); "
                       f"stretched to {duration:.2f} s.")
            if max_speed is None:
                logger.warning(message)
                self.stretched.append(message)
        path = Trajectory(start, goal, duration, self.profile)
        t_start = self._begin()
        segment = Segment("move", self.step, t_start - self._t0, start, goal, duration, requested)
        self.segments.append(segment)
        while True:
            deadline = self._cycle(lambda now: path.at(now - t_start))
            if deadline - t_start >= duration - 1e-9:
                break
        return segment

    def hold(self, duration: float, step: str | None = None) -> None:
        """Keep the last command for ``duration`` [s], still reading and checking every cycle."""
        if step is not None:
            self.step = step
        if self.command is None:
            self.command = self.read_pose()
        command = dict(self.command)
        t_start = self._begin()
        self.segments.append(Segment("hold", self.step, t_start - self._t0, command, command,
                                     float(duration), float(duration)))
        while True:
            deadline = self._cycle(lambda now: command)
            if deadline - t_start >= float(duration) - 1e-9:
                break

    def return_slowly(self, target: Mapping[str, float]) -> Segment:
        """Stop where the arm is, then go to ``target`` at the slow return speed."""
        self._beyond.clear()
        self.command = self.read_pose()
        slow = speed_caps(RETURN_SPEED_DEG_S, RETURN_SPEED_DEG_S)
        return self.move(target, RETURN_MIN_DURATION_S, step="abort_return", max_speed=slow)

    def timing(self) -> dict[str, float]:
        """Loop timing of the cycles so far (see :func:`loop_timing_stats`), plus overruns."""
        stats = loop_timing_stats([c.wall_s for c in self.cycles], 1.0 / self.loop.period)
        stats.update(overruns=self.loop.overruns, skipped=self.loop.skipped)
        return stats


def session_for(bus) -> ArmSession:
    """The :class:`ArmSession` of a bus (created with default settings the first time)."""
    if isinstance(bus, ArmSession):
        return bus
    session = _SESSIONS.get(bus)
    return session if session is not None else ArmSession(bus)


def move_to_pose(bus, cfg: Mapping[str, float], duration: float) -> None:
    """Move the arm to ``cfg`` ([deg], gripper [0, 100]) in ``duration`` [s], as in the simulator.

    Deadline-scheduled at the session's rate, Present_Position read each
    cycle; the first call ramps from the measured pose.

    Args:
        bus: a connected lerobot FeetechMotorsBus (or its :class:`ArmSession`).
        cfg: target configuration.
        duration: [s]; stretched if too fast for the speed cap.
    """
    session_for(bus).move(cfg, duration)


def hold_position(bus, duration: float) -> None:
    """Hold the last commanded pose for ``duration`` [s], reading and checking the arm each cycle.

    Args:
        bus: a connected lerobot FeetechMotorsBus (or its :class:`ArmSession`).
        duration: [s].
    """
    session_for(bus).hold(duration)


@contextmanager
def gc_frozen():
    """Collect garbage once, then freeze: no 0.2 s full collection in the middle of a motion.

    With lerobot (and PyTorch) imported, a full collection of the cyclic
    garbage collector walks about 250 000 objects: about 0.2 s on this
    machine, long enough to stall the arm mid-move. Frozen objects are
    skipped; reference counting still frees everything the loop creates.
    """
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@contextmanager
def stop_on_sigint(session: ArmSession):
    """Turn Ctrl-C into a stop at the next cycle boundary (never inside a bus transaction).

    A second Ctrl-C raises KeyboardInterrupt at once. Only in the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        if session.stop_reason is None:
            session.stop_reason = "Ctrl-C"
            print("\nStopping (Ctrl-C again to release the torque at once) ...", file=sys.stderr)
        else:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


# --- The pick-and-place ----------------------------------------------------------
@dataclass
class RunResult:
    """What happened on the arm."""

    start_pose: Configuration
    cycles: list[Cycle] = field(default_factory=list)
    segments: list[Segment] = field(default_factory=list)
    stretched: list[str] = field(default_factory=list)
    final_pose: Configuration | None = None
    aborted: str | None = None
    returned_to_start: bool = False
    unreleased: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)
    stale_bytes: int = 0  # late-reply bytes dropped before reads (see discard_stale_input)


def _describe(error: BaseException, step: str) -> str:
    where = f" (during '{step}')" if step else ""
    if isinstance(error, (KeyboardInterrupt, StopRequested)):
        return f"stopped by Ctrl-C{where}"
    text = str(error).rstrip(".")
    if isinstance(error, HardwareError):
        return f"{text}{where}"
    return f"{type(error).__name__}: {text}{where}"


def clamp_to_limits(cfg: Mapping[str, float], limits: Limits) -> Configuration:
    """``cfg`` with each joint clamped into its limits."""
    return {j: min(limits[j][1], max(limits[j][0], cfg[j])) for j in JOINTS}


def execute(session: ArmSession, plan: Plan, start_pose: Configuration,
            return_on_abort: bool = True) -> RunResult:
    """Run a validated plan on a torqued arm; on any failure stop, return slowly if safe, release.

    Args:
        session: the armed session (torque on).
        plan: validated plan.
        start_pose: the measured starting pose (inside the calibrated range);
            the plan ends there.
        return_on_abort: move slowly back to ``start_pose`` after an abort
            when the bus still answers.

    Returns:
        The result (torque released on success too).

    Raises:
        MotionAborted: after stopping and releasing; ``.result`` has the details.
    """
    result = RunResult(dict(start_pose))
    bus = session.bus

    def on_step(step: Step) -> None:
        session.step = step.name
        logger.info("-> %s (%.2f s, hold %.2f s)", step.name, step.duration, step.hold)

    try:
        with gc_frozen(), stop_on_sigint(session):
            run_plan(plan, session.move, session.hold, initial=start_pose, on_step=on_step)
    except (Exception, KeyboardInterrupt) as error:
        step = session.step
        result.aborted = _describe(error, step)
        logger.error("Aborting: %s", result.aborted)
        if isinstance(error, KeyboardInterrupt):
            _recover_port(bus)  # Ctrl-C may have cut a transaction in half
        bus_failed = isinstance(error, BusError)
        if bus_failed:
            silent = silent_servos(bus)
            if silent:
                names = ", ".join(f"{j} (id {MOTOR_IDS[j]})" for j in silent)
                result.aborted += f". Not answering: {names}"
        if return_on_abort and not bus_failed:
            session.stop_reason = None
            try:
                with stop_on_sigint(session):
                    session.return_slowly(start_pose)
                result.returned_to_start = True
            except (Exception, KeyboardInterrupt) as second:
                logger.error("The return to the starting pose stopped: %s",
                             _describe(second, "abort_return"))
                if isinstance(second, KeyboardInterrupt):
                    _recover_port(bus)
    finally:
        try:
            result.final_pose = session.read_pose()
        except (Exception, KeyboardInterrupt):
            result.final_pose = None
        result.unreleased = release_torque(bus)
        result.cycles, result.segments = session.cycles, session.segments
        result.stretched = session.stretched
        result.stale_bytes = session.stale_bytes
        if len(session.cycles) >= 3:
            result.timing = session.timing()
    if result.aborted is not None:
        if result.returned_to_start:
            after = "The arm moved slowly back to its starting pose"
        elif result.aborted.startswith("stopped") or not return_on_abort:
            after = "The arm stopped where it was"
        else:
            after = "The arm was NOT moved back (the bus failed or the return stopped)"
        if result.unreleased:
            after += ("; torque could NOT be released on " + ", ".join(result.unreleased)
                      + ": support the arm and switch off its power supply.")
        else:
            after += "; torque is off on every servo."
        raise MotionAborted(f"Pick-and-place aborted: {result.aborted}. {after}", result)
    return result


def run_on_arm(port: str, calibration_path: str | Path, plan: Plan, *, robot_id: str | None = None,
               rate_hz: float = DEFAULT_RATE_HZ, profile: str = "minimum_jerk",
               max_joint_speed: float = MAX_JOINT_SPEED_DEG_S,
               tracking_tolerance: float = TRACKING_TOLERANCE_DEG,
               confirm: Callable[[str], bool] | None = None, write_calibration: bool = False,
               return_on_abort: bool = True,
               on_cycle: Callable[[ArmSession, Cycle], None] | None = None) -> RunResult:
    """The whole hardware run: check, connect, confirm, torque on, run, return, torque off.

    Nothing is sent to the servos' goal registers and torque stays off until
    the plan has passed both limit checks, the servos answered, their
    calibration matched the file and ``confirm`` (if given) said yes.

    Args:
        port: serial port of the arm.
        calibration_path: lerobot calibration JSON of this arm.
        plan: the plan (validated here against model and calibrated limits).
        robot_id: for messages.
        rate_hz: control loop rate [Hz].
        profile: "minimum_jerk" or "linear".
        max_joint_speed: speed cap of the arm joints [deg/s].
        tracking_tolerance: stall/collision tolerance of the arm joints [deg].
        confirm: asked with a summary before torque on; False refuses.
        write_calibration: write the file into the servos if they differ.
        return_on_abort: move back slowly after an abort when the bus answers.
        on_cycle: hook called after each control cycle.

    Returns:
        The run's result.

    Raises:
        CalibrationError, PlanError, ConnectionFailed, LerobotMissing, NotConfirmed:
            refused before anything moved.
        MotionAborted: aborted during motion (stopped, returned if safe, released).
    """
    calibration = load_calibration(calibration_path, robot_id)
    validate_plan_for_arm(plan, calibration, str(calibration_path))
    RateLoop(rate_hz)  # validates the rate before connecting
    if not (isinstance(max_joint_speed, (int, float)) and max_joint_speed > 0):
        raise PlanError(f"The speed cap must be > 0 deg/s, got {max_joint_speed!r}.")
    if not (isinstance(tracking_tolerance, (int, float)) and tracking_tolerance > 0):
        raise PlanError(f"The tracking tolerance must be > 0 deg, got {tracking_tolerance!r}.")
    bus = connect(port, calibration, robot_id=robot_id, write_calibration=write_calibration)
    armed = False
    try:
        limits = calibrated_limits(calibration)
        with bus_errors("reading the starting pose"):
            measured = {j: float(v) for j, v in bus.sync_read("Present_Position").items()}
        start = clamp_to_limits(measured, limits)
        for joint in JOINTS:
            if abs(start[joint] - measured[joint]) > LIMIT_SLACK_DEG:
                raise CalibrationError(
                    f"The arm's {joint} reads {measured[joint]:.1f} {unit(joint)}, outside its "
                    f"calibrated range [{limits[joint][0]:.1f}, {limits[joint][1]:.1f}]: the "
                    "calibration does not fit this arm. Fix: `"
                    + CALIBRATE_HINT.format(port=port, robot_id=robot_id or "ID") + "`.")
        bounds = model_limits()
        outside_model = [j for j in JOINTS if not bounds[j][0] <= start[j] <= bounds[j][1]]
        if outside_model:
            logger.warning("The starting pose is outside the model's limits on %s; the arm will "
                           "return there at the end anyway (it is where it stood).",
                           ", ".join(outside_model))
        session = ArmSession(
            bus, rate_hz=rate_hz, profile=profile, max_speed=speed_caps(max_joint_speed),
            tracking_tolerance=tracking_tolerances(tracking_tolerance),
            on_cycle=on_cycle)
        session.command = dict(start)
        first = plan.steps[0]
        first_duration = capped_duration(start, first.configuration, first.duration, profile,
                                         session.max_speed)
        print("Starting pose (returned to at the end): " + format_configuration(start))
        print(f"First move: to '{first.name}' in {first_duration:.2f} s, ramping from this pose.")
        if confirm is not None and not confirm("Enable torque and run the pick-and-place?"):
            raise NotConfirmed("Not confirmed: nothing moved.")
        armed = True
        with bus_errors("configuring the servos and enabling torque"):
            configure(bus)
            enable_torque_in_place(bus)
        return execute(session, plan, start, return_on_abort=return_on_abort)
    except MotionAborted:
        raise  # execute() stopped, returned if safe and released already
    except BaseException:
        if armed:
            unreleased = release_torque(bus)
            if unreleased:
                logger.error("Torque could NOT be released on %s: support the arm and switch off "
                             "its power supply.", ", ".join(unreleased))
        raise
    finally:
        disconnect(bus)


# --- Output: plan, FK, log, plot ------------------------------------------------
def format_configuration(cfg: Mapping[str, float], digits: int = 1) -> str:
    """A configuration as a JSON object (valid Python and waypoint-file syntax)."""
    return json.dumps({j: round(float(cfg[j]), digits) for j in JOINTS if j in cfg})


def object_position_cm(cfg: Mapping[str, float]) -> tuple[float, float, float]:
    """FK object-frame position in the base frame [cm]."""
    position, _ = get_forward_kinematics({j: cfg[j] for j in ARM_JOINTS})
    return tuple(float(v) * 100.0 for v in position)


def format_plan(plan: Plan, *, rate_hz: float, profile: str, max_speed: Mapping[str, float],
                start: Configuration | None = None) -> str:
    """The plan as a table (durations after the speed cap) and the cube positions to place [cm]."""
    lines = [f"Plan: {len(plan.steps)} waypoints, {rate_hz:g} Hz, profile {profile}, speed cap "
             f"{max_speed['shoulder_pan']:g} deg/s (gripper {max_speed['gripper']:g} %/s)"]
    header = f"  {'#':>2} {'waypoint':<16}{'move':>7}{'hold':>6}" + "".join(
        f"{j[:13]:>14}" for j in JOINTS) + "    object x, y, z [cm]"
    lines.append(header)
    previous = start
    for i, step in enumerate(plan.steps, 1):
        if previous is None:
            move = f"{step.duration:>6.2f}*"
        else:
            capped = capped_duration(previous, step.configuration, step.duration, profile,
                                     max_speed)
            move = f"{capped:>7.2f}"
        x, y, z = object_position_cm(step.configuration)
        lines.append(f"  {i:>2} {step.name[:15]:<16}{move}{step.hold:>6.2f}" + "".join(
            f"{step.configuration[j]:>14.1f}" for j in JOINTS) + f"    {x:6.1f} {y:6.1f} {z:5.1f}")
        previous = step.configuration
    if plan.return_to_start:
        lines.append(f"  {len(plan.steps) + 1:>2} {'return_to_start':<16}"
                     f"{plan.return_duration:>6.2f}*     back to the measured starting pose")
    if start is None:
        lines.append("  * ramps from (or to) the arm's measured pose; stretched if the speed cap "
                     "needs it.")
    pick, place = pick_and_place_steps(plan)
    lines.append("Place the cubes here (FK of the object frame, base frame, rounded to the grid):")
    for label, step in (("pick ", pick), ("place", place)):
        x, y, z = object_position_cm(step.configuration)
        lines.append(f"  {label} ({step.name}): x = {x:.1f} cm, y = {y:.1f} cm  (cube centre "
                     f"z = {z:.1f} cm)")
    return "\n".join(lines)


def write_log_csv(cycles: list[Cycle], path: str | Path) -> Path:
    """CSV: t_s (scheduled), wall_s (actual cycle start), step, cmd_<joint>, meas_<joint>."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["t_s", "wall_s", "step"] + [f"cmd_{j}" for j in JOINTS]
                        + [f"meas_{j}" for j in JOINTS])
        for c in cycles:
            measured = [f"{c.measured[j]:.4f}" if c.measured else "" for j in JOINTS]
            writer.writerow([f"{c.t_s:.6f}", f"{c.wall_s:.6f}", c.step]
                            + [f"{c.command[j]:.4f}" for j in JOINTS] + measured)
    return path


def plot_log(cycles: list[Cycle], path: str | Path,
             title: str = "SO-101: commanded vs measured") -> Path:
    """PNG with one panel per joint: commanded and measured against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    t = [c.t_s for c in cycles]
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    measured = [c for c in cycles if c.measured]
    for ax, joint in zip(axes.flat, JOINTS, strict=True):
        ax.plot(t, [c.command[joint] for c in cycles], label="commanded", lw=1.5)
        ax.plot([c.t_s for c in measured], [c.measured[joint] for c in measured],
                label="measured", lw=1.0, ls="--")
        worst = max((abs(c.command[joint] - c.measured[joint]) for c in measured), default=0.0)
        ax.set_title(f"{joint}  (max |commanded - measured| = {worst:.2f} {unit(joint)})",
                     fontsize=10)
        ax.set_ylabel("[%]" if joint == "gripper" else "[deg]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes.flat[0].legend(loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# --- Teach mode ------------------------------------------------------------------
def teach(bus, *, rate_hz: float = TEACH_RATE_HZ, duration: float | None = None,
          out=None) -> Configuration | None:
    """Torque off; print the pose live (configuration dict + FK object position) until Ctrl-C.

    Args:
        bus: connected bus.
        rate_hz: print rate [Hz].
        duration: stop after this long [s] (None: until Ctrl-C).
        out: text stream (default stdout); a terminal gets one updating line.

    Returns:
        The last pose read.
    """
    out = out or sys.stdout
    bus.disable_torque()
    live = hasattr(out, "isatty") and out.isatty()
    print("Torque is off: move the arm by hand. Ctrl-C to stop.", file=out)
    loop = RateLoop(rate_hz)
    started = loop.start()
    pose = None
    try:
        while duration is None or loop.deadline - started < duration - 1e-9:
            raw = bus.sync_read("Present_Position")
            pose = {j: float(raw[j]) for j in JOINTS}
            x, y, z = object_position_cm(pose)
            line = f"{format_configuration(pose)}  object x={x:.1f} y={y:.1f} z={z:.1f} cm"
            print(("\r" + line) if live else line, end="" if live else "\n", file=out, flush=True)
            loop.wait()
    except KeyboardInterrupt:
        pass
    if live:
        print(file=out)
    if pose is not None:
        print("Last pose (paste into a waypoint file): " + format_configuration(pose), file=out)
    return pose


# --- Loop timing, for the benchmarks ------------------------------------------------
def measure_loop_timing(rates_hz=(100.0, 200.0), seconds: float = 3.0, wire_timing: bool = True,
                        calibration_path: str | Path | None = None,
                        ) -> dict[float, dict[str, float]]:
    """Run the control loop against the virtual SO-101 and measure its timing at each rate.

    The arm swings wrist_flex by +-10 deg so each cycle does the full work
    (interpolate, sync_write, sync_read, check, log).

    Args:
        rates_hz: loop rates to measure [Hz].
        seconds: run time per rate [s].
        wire_timing: the virtual arm delays replies by the 1 Mbaud byte time.
        calibration_path: the virtual arm's calibration (default: the shipped one).

    Returns:
        rate -> ``achieved_hz``, ``period_p50_ms``, ``period_p99_error_ms``,
        ``period_max_error_ms``, ``cycles``, ``overruns``, ``skipped``.
    """
    from virtual_so101 import DEFAULT_CALIBRATION_PATH, VirtualSO101

    calibration_path = calibration_path or DEFAULT_CALIBRATION_PATH
    calibration = load_calibration(calibration_path)
    results = {}
    with VirtualSO101(calibration=calibration_path, wire_timing=wire_timing) as arm:
        bus = connect(arm.port, calibration)
        try:
            configure(bus)
            enable_torque_in_place(bus)
            for rate in rates_hz:
                with gc_frozen():
                    results[rate] = _swing_wrist(ArmSession(bus, rate_hz=rate), seconds)
        finally:
            release_torque(bus)
            disconnect(bus)
    return results


def _swing_wrist(session: ArmSession, seconds: float) -> dict[str, float]:
    """Swing wrist_flex +-10 deg for ``seconds`` [s]; returns the session's loop timing."""
    home = session.read_pose()
    session.command = dict(home)
    swings, elapsed = 0, 0.0
    while elapsed < seconds:
        sign = 1.0 if swings % 2 == 0 else -1.0
        session.move(dict(home, wrist_flex=home["wrist_flex"] + sign * 10.0), 0.5)
        session.hold(0.25)
        swings += 1
        elapsed = session.cycles[-1].wall_s
    session.move(home, 0.5)
    return session.timing()


# --- Command line ------------------------------------------------------------------
def ask(question: str, assume_yes: bool, stdin=None) -> bool:
    """Ask yes/no on a terminal; ``assume_yes`` answers yes; never blocks on a non-terminal.

    Raises:
        NotConfirmed: stdin is not a terminal and ``assume_yes`` is False.
    """
    if assume_yes:
        return True
    stdin = stdin or sys.stdin
    if not (hasattr(stdin, "isatty") and stdin.isatty()):
        raise NotConfirmed(f"{question} - cannot ask: stdin is not a terminal. Pass --yes to run "
                           "without confirmation.")
    print(f"{question} [y/N] ", end="", flush=True)
    answer = stdin.readline()
    return answer.strip().lower() in ("y", "yes")


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        description="The course's pick-and-place on a real SO-101 follower (lerobot Feetech bus). "
                    "Validates the whole plan against the model's and the arm's calibrated limits "
                    "before torque on; ramps from the measured pose; caps joint speed; runs a "
                    "deadline-scheduled loop reading the arm every cycle; aborts on a stall, a bus "
                    "error or Ctrl-C by moving slowly back to the start and releasing torque.",
        epilog="Examples:\n  python pick_place_hw.py --calibration my_arm.json --dry-run\n"
               "  python pick_place_hw.py --port /dev/ttyACM0 --id my_arm --log run.csv "
               "--plot run.png\n"
               "  python pick_place_hw.py --port /dev/ttyACM0 --id my_arm --teach",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--port", help=f"serial port of the arm (find it with `{FIND_PORT_HINT}`)")
    who = parser.add_mutually_exclusive_group()
    who.add_argument("--id", dest="robot_id",
                     help="robot id given to lerobot-calibrate; the calibration is read from "
                          "$HF_LEROBOT_CALIBRATION/robots/so_follower/ID.json (or so101_follower/)")
    who.add_argument("--calibration", type=Path, help="lerobot calibration JSON file of this arm")
    parser.add_argument("--plan", type=Path, help="waypoint file (JSON or TOML) instead of the "
                        "course's plan")
    parser.add_argument("--move-duration", type=float, default=2.0,
                        help="duration of each move of the built-in plan [s] (default 2)")
    parser.add_argument("--hold", type=float, default=0.5,
                        help="pause after each move of the built-in plan [s] (default 0.5)")
    parser.add_argument("--profile", choices=sorted(PROFILES), default="minimum_jerk",
                        help="time scaling of each move (default minimum_jerk, as the simulator)")
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ,
                        help=f"control loop rate [Hz] (default {DEFAULT_RATE_HZ:g})")
    parser.add_argument("--max-speed", type=float, default=MAX_JOINT_SPEED_DEG_S,
                        help="speed cap of each arm joint [deg/s] (default "
                             f"{MAX_JOINT_SPEED_DEG_S:g}); too-short moves are stretched")
    parser.add_argument("--tracking-tolerance", type=float, default=TRACKING_TOLERANCE_DEG,
                        help=f"abort when a joint is this far from its command [deg] for "
                             f"{TRACKING_TIMEOUT_S:g} s (default {TRACKING_TOLERANCE_DEG:g})")
    parser.add_argument("--dry-run", action="store_true",
                        help="validate and print the plan and cube positions; send nothing")
    parser.add_argument("--teach", action="store_true",
                        help="torque off; print the pose live as a configuration and its FK "
                             "object position")
    parser.add_argument("--yes", "-y", action="store_true",
                        help="do not ask before enabling torque")
    parser.add_argument("--write-calibration", action="store_true",
                        help="if the servos hold another calibration, write the file into them")
    parser.add_argument("--no-return-on-abort", action="store_true",
                        help="after an abort, release torque where the arm is instead of returning")
    parser.add_argument("--log", type=Path,
                        help="CSV of time, commanded and measured joints per cycle")
    parser.add_argument("--plot", type=Path, help="PNG of commanded vs measured per joint")
    parser.add_argument("--verbose", "-v", action="store_true", help="debug logging")
    add_cartesian_arguments(parser)
    return parser


def _dry_run(args, plan: Plan, calibration) -> int:
    caps = speed_caps(args.max_speed)
    start = None
    if args.port:
        try:
            bus = connect(args.port, calibration, robot_id=args.robot_id)
        except LerobotMissing as error:
            logger.warning("%s Showing the plan without reading the arm.", error)
        else:
            try:
                measured = {j: float(v) for j, v in bus.sync_read("Present_Position").items()}
                start = clamp_to_limits(measured, calibrated_limits(calibration))
                print("Measured starting pose: " + format_configuration(measured))
            finally:
                disconnect(bus)
    print(format_plan(plan, rate_hz=args.rate, profile=args.profile, max_speed=caps, start=start))
    print("Dry run: the plan is valid; nothing was sent to the arm.")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 1 aborted, 2 refused)."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s: %(message)s")
    try:
        plan = plan_from_arguments(args) or (
            load_plan(args.plan) if args.plan else default_plan(args.move_duration, args.hold))
        calibration, source = None, None
        if args.calibration:
            source = args.calibration
        elif args.robot_id:
            source = find_calibration(args.robot_id, args.port)
        if source is not None:
            calibration = load_calibration(source, args.robot_id)
            logger.info("Calibration: %s", source)
        elif not args.dry_run:
            raise CalibrationError("Tell me which arm: --id ROBOT_ID (the id you gave "
                                   "lerobot-calibrate) or --calibration PATH.")
        validate_plan_for_arm(plan, calibration, str(source))
        RateLoop(args.rate)
        if calibration is None:
            logger.warning("No calibration given: checked against the model's limits only.")
        if args.dry_run:
            return _dry_run(args, plan, calibration)
        if args.teach:
            bus = connect(args.port, calibration, robot_id=args.robot_id)
            try:
                teach(bus)
            finally:
                disconnect(bus)
            return 0
        print(format_plan(plan, rate_hz=args.rate, profile=args.profile,
                          max_speed=speed_caps(args.max_speed)))
        result = run_on_arm(
            args.port, source, plan, robot_id=args.robot_id, rate_hz=args.rate,
            profile=args.profile,
            max_joint_speed=args.max_speed, tracking_tolerance=args.tracking_tolerance,
            confirm=lambda q: ask(q, args.yes), write_calibration=args.write_calibration,
            return_on_abort=not args.no_return_on_abort)
    except MotionAborted as error:
        print(f"ABORTED: {error}", file=sys.stderr)
        _write_outputs(args, error.result)
        return 1
    except (HardwareError, PlanError, ValueError) as error:
        print(f"Refused, nothing moved: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("Interrupted.", file=sys.stderr)
        return 130
    _write_outputs(args, result)
    timing = result.timing
    print("Done: back at the starting pose, torque off. Loop "
          f"{timing.get('achieved_hz', 0):.1f} Hz, "
          f"period p50 {timing.get('period_p50_ms', 0):.2f} ms, p99 error "
          f"{timing.get('period_p99_error_ms', 0):.2f} ms, {timing.get('overruns', 0)} overruns.")
    return 0


def _write_outputs(args, result: RunResult) -> None:
    if args.log and result.cycles:
        print(f"Log: {write_log_csv(result.cycles, args.log)}")
    if args.plot and result.cycles:
        print(f"Plot: {plot_log(result.cycles, args.plot)}")


if __name__ == "__main__":
    sys.exit(main())
