"""The SO-101 follower through lerobot's FeetechMotorsBus: connect, configure, torque, recovery.

The bus side of the hardware backend (the control loop that drives it is
``hw/control.py``):
  - lerobot, imported lazily (it imports PyTorch): :func:`import_lerobot`;
  - the bus: :func:`make_bus`, :func:`connect` (takes the port for this
    program alone, checks servos and calibration, nothing moves),
    :func:`configure`, :func:`enable_torque_in_place`, :func:`release_torque`,
    :func:`disconnect`;
  - what a Feetech bus needs after a fault: dropping late replies
    (:func:`discard_stale_input`, :func:`recover_port`), finding the servos
    that stopped answering (:func:`silent_servos`), telling a vanished port
    (:func:`port_lost`) from a silent arm, and lerobot's exceptions turned into
    errors with a fix (:func:`bus_errors`);
  - a block read from another device on the bus (:func:`read_block`: the
    virtual lab's cube sensor, ``so101_kinematics/sensors/``).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Mapping
from contextlib import contextmanager
from typing import Any

from so101_kinematics.calibration import CALIBRATE_HINT, MOTOR_IDS, ServoCalibration
from so101_kinematics.errors import (
    CalibrationError,
    ConnectionFailed,
    HardwareError,
    LerobotMissing,
)
from so101_kinematics.frames import JOINTS
from so101_kinematics.hw.port import FIND_PORT_HINT, claim_port
from so101_kinematics.inputs import Configuration, Limits, unit

__all__ = [
    "PORT_SETTLE_S", "SETUP_ATTEMPTS", "bus_errors", "calibration_mismatch", "clamp_to_limits",
    "configure", "connect", "connect_with_retries", "discard_stale_input", "disconnect",
    "enable_torque_in_place", "format_pose", "make_bus", "port_lost", "read_block",
    "read_pose", "recover_port", "release_torque", "silent_servos",
    "with_retries",
]

logger = logging.getLogger(__name__)

# --- Settings ---------------------------------------------------------------
SETUP_ATTEMPTS = 3  # a setup step (connect, configure, torque on) is tried this often
PORT_SETTLE_S = 0.06               # a late reply dies out within the SDK's 50 ms timeout [s]
MOTOR_MODEL = "sts3215"
INSTALL_HINT = "pip install -e '.[hw]'  (from the so101-kinematics folder)"


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
            write_calibration: bool = False, check_calibration: bool = True):
    """Open the port, check every servo answers and holds this calibration; nothing moves.

    Args:
        port: serial port (``lerobot-find-port`` tells which).
        calibration: from :func:`load_calibration`.
        robot_id: for the messages.
        write_calibration: if the servos' calibration registers differ from the
            file, write the file into them (as ``lerobot-calibrate`` offers) instead of refusing.
        check_calibration: compare the servos' calibration with the file (False
            only to release the torque, which needs no calibration).

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
    lock = claim_port(port)
    bus = make_bus(port, calibration)
    bus.so101_port_lock = lock
    try:
        connect_with_retries(bus)
    except ConnectionError as error:
        os.close(lock)
        raise ConnectionFailed(f"Cannot open port '{port}': {str(error).strip()} "
                               f"Find the port with `{FIND_PORT_HINT}`.") from None
    except RuntimeError as error:
        os.close(lock)
        raise ConnectionFailed(
            f"The servos on '{port}' did not pass lerobot's check:\n{error}\n"
            "Fix: switch on the arm's power supply, check the cables between the servos, and make "
            "sure the ids were set with `lerobot-setup-motors --robot.type=so101_follower`."
        ) from None
    try:
        with bus_errors("reading the servos' calibration"):
            mismatch = (with_retries(lambda b: calibration_mismatch(b, calibration), bus)
                        if check_calibration else [])
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


def connect_with_retries(bus) -> None:
    """Lerobot's connect (open, ping every servo), tried ``SETUP_ATTEMPTS`` times.

    Its handshake pings each servo once: one reply lost on a glitching bus (or
    a busy host) would refuse an arm that is all there. A servo that stays
    silent is still refused, after about 0.3 s.
    """
    for attempt in range(1, SETUP_ATTEMPTS + 1):
        try:
            bus.connect()
            return
        except (ConnectionError, RuntimeError) as error:
            if attempt == SETUP_ATTEMPTS:
                raise
            logger.warning("Connecting failed (%s); trying again.", str(error).strip()[:80])
            try:
                bus.port_handler.closePort()
            except Exception:  # noqa: BLE001 - best effort before the next try
                logger.debug("could not close the port", exc_info=True)
            time.sleep(PORT_SETTLE_S)


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


def format_pose(cfg: Mapping[str, float]) -> str:
    """A pose in one short line: name=value pairs, 1 decimal."""
    return ", ".join(f"{j} {cfg[j]:.1f} {unit(j)}" for j in JOINTS if j in cfg)


def clamp_to_limits(cfg: Mapping[str, float], limits: Limits) -> Configuration:
    """``cfg`` with each joint clamped into its limits."""
    return {j: min(limits[j][1], max(limits[j][0], cfg[j])) for j in JOINTS}


def read_pose(bus, retries: int = 0) -> dict[str, float]:
    """Present_Position of every joint ([deg]; gripper [0, 100]), in joint order.

    Args:
        bus: a connected bus.
        retries: failed reads retried within the call (lerobot's ``num_retry``).

    Raises:
        ConnectionError: no answer after the retries (lerobot's exception, as it comes).
    """
    raw = bus.sync_read("Present_Position", num_retry=retries)
    return {joint: float(raw[joint]) for joint in JOINTS}


def read_block(bus, device_id: int, address: int, size: int) -> bytes | None:
    """One protocol-0 READ of ``size`` bytes at ``address`` of a device on the bus; None if silent.

    For a device that is not one of the arm's servos (the virtual lab's cube
    sensor: ``so101_kinematics/sensors/``): the port flushed before and freed after,
    so a timed-out read (50 ms: a real arm has no such device) leaves the next
    servo transaction clean. A failed read, or a reply of another size, is None.
    """
    try:
        discard_stale_input(bus)
        data, comm, _ = bus.packet_handler.readTxRx(bus.port_handler, device_id, address, size)
    except Exception:  # noqa: BLE001 - no device, or a failing port: nothing to report
        return None
    finally:
        recover_port(bus, settle=False)
    if comm != 0 or len(data) != size:
        return None
    return bytes(data)


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


def recover_port(bus, settle: bool = True) -> None:
    """After an interrupted or failed transaction: drop late replies, free the port.

    Args:
        bus: the bus.
        settle: first wait ``PORT_SETTLE_S`` for replies still on the way.
    """
    try:
        if settle:
            time.sleep(PORT_SETTLE_S)
        discard_stale_input(bus)
        bus.port_handler.is_using = False
    except Exception:  # noqa: BLE001 - best effort on a failing port
        logger.debug("could not flush the port", exc_info=True)


def port_lost(bus) -> bool:
    """Whether the bus's port has vanished (the USB cable pulled out, the virtual arm gone)."""
    port = getattr(bus, "port", None) or getattr(bus.port_handler, "port_name", None)
    return isinstance(port, str) and port.startswith("/") and not os.path.exists(port)




def with_retries(step, bus, attempts: int = SETUP_ATTEMPTS):
    """``step(bus)``, tried again (the port flushed) when the bus glitches; torque is not on yet.

    Every setup step here writes registers to fixed values, so repeating one
    is harmless; the last failure is raised as it came.
    """
    for attempt in range(1, attempts + 1):
        try:
            return step(bus)
        except (ConnectionError, RuntimeError) as error:
            if attempt == attempts or isinstance(error, HardwareError):
                raise
            logger.warning("The bus glitched during setup (%s); trying again.", error)
            recover_port(bus)


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
    recover_port(bus)
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
    """The joints whose servo does not answer a ping now (one with an error bit set answers)."""
    recover_port(bus)
    silent = []
    for joint in bus.motors:
        try:
            bus.ping(joint, num_retry=1, raise_on_error=True)
        except Exception as error:  # noqa: BLE001 - RuntimeError: it answered, an error bit set
            if not isinstance(error, RuntimeError):  # (e.g. overload); else no reply
                silent.append(joint)
    return silent


def disconnect(bus) -> None:
    """Close the port, leaving torque as it is (release it first: :func:`release_torque`)."""
    try:
        if bus.is_connected:
            bus.disconnect(disable_torque=False)
    except Exception:  # noqa: BLE001
        logger.debug("disconnect failed", exc_info=True)
    lock = getattr(bus, "so101_port_lock", None)
    if lock is not None:
        bus.so101_port_lock = None
        try:
            os.close(lock)
        except OSError:
            pass
