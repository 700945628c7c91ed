"""What the control loop checks each cycle: tracking, error bits, torque read back.

Tracking catches a stall or a collision; the Status register's error bits an
overload, overheating or a bad voltage; Torque_Enable read back a servo gone limp.
"""

from __future__ import annotations

from collections.abc import Mapping

from so101_kinematics.errors import ServoFault, TorqueLost, TrackingError
from so101_kinematics.hw.bus import discard_stale_input, recover_port
from so101_kinematics.inputs import Configuration, unit

__all__ = [
    "GRIPPER_OVERLOAD", "STATUS_BITS", "check_status", "check_torque", "check_tracking",
    "read_torque",
]

STATUS_BITS = {0x01: "input voltage out of range", 0x04: "overheated", 0x08: "overcurrent",
               0x20: "overloaded"}
"""Status register bits of the STS3215 that stop the motion, and what they mean."""
GRIPPER_OVERLOAD = 0x20  # squeezing the cube is what the gripper's overload protection is for
DEFINED_BITS = 0x01 | 0x02 | 0x04 | 0x08 | 0x20  # voltage, sensor, temperature, current, load


def check_status(bus, known: dict[str, int], pending: dict[str, int] | None = None) -> None:
    """Raise ServoFault on a new error bit in a servo's Status register (gripper overload excepted).

    A bit must be read twice in a row (two status reads, ``STATUS_EVERY`` cycles
    apart) before it counts, and a reading with bits the STS3215 does not
    define is dropped: a late reply taken for the Status byte must not stop a
    run. Late bytes waiting on the port are dropped before the read.

    Args:
        bus: the lerobot bus.
        known: joint -> bits already reported (updated): they do not stop the
            slow return that follows the first report.
        pending: joint -> bits seen once, waiting for their second reading (updated).
    """
    pending = {} if pending is None else pending
    try:
        discard_stale_input(bus)
        status = bus.sync_read("Status", normalize=False)
    except Exception:  # noqa: BLE001 - a missed status read is not a fault; the next one
        recover_port(bus, settle=False)
        return
    if any(int(bits) & ~DEFINED_BITS for bits in status.values()):
        return  # not a Status byte: a garbled or late reply
    for joint, bits in status.items():
        bits = int(bits) & ~known.get(joint, 0)
        if joint == "gripper":
            bits &= ~GRIPPER_OVERLOAD
        confirmed = bits & pending.get(joint, 0)
        pending[joint] = bits
        faults = [text for bit, text in STATUS_BITS.items() if confirmed & bit]
        if faults:
            known[joint] = known.get(joint, 0) | confirmed
            raise ServoFault(f"The {joint} servo reports: {', '.join(faults)} (status "
                             f"0x{int(confirmed):02x}). Fix: check the power supply (voltage), "
                             "let the servo cool down, or free the arm from what it pushes "
                             "against.")


def check_tracking(commanded: Configuration, measured: Configuration, now: float,
                   tolerance: Mapping[str, float | None], timeout: float,
                   beyond: dict[str, float]) -> None:
    """Raise TrackingError when a joint stays beyond its tolerance for ``timeout`` [s].

    Args:
        commanded: the command the arm was following ([deg], gripper [0, 100]).
        measured: where it is.
        now: the cycle's time [s].
        tolerance: joint -> allowed |measured - commanded| [deg] (None: unchecked).
        timeout: how long a joint may stay beyond it [s].
        beyond: joint -> since when it is beyond (updated).
    """
    for joint, allowed in tolerance.items():
        if allowed is None:
            continue
        error = abs(measured[joint] - commanded[joint])
        if error <= allowed:
            beyond.pop(joint, None)
            continue
        since = beyond.setdefault(joint, now)
        if now - since >= timeout:
            raise TrackingError(
                f"{joint} does not follow its command: measured {measured[joint]:.1f} "
                f"{unit(joint)}, commanded {commanded[joint]:.1f} {unit(joint)} (error "
                f"{error:.1f} > tolerance {allowed:g} {unit(joint)} for "
                f"{now - since:.2f} s). Something blocks the arm (the table, an object, a "
                "cable) or the servo is overloaded: clear the way and check the power supply; "
                "--tracking-tolerance changes the tolerance.")


def read_torque(bus) -> dict[str, bool] | None:
    """Each servo's Torque_Enable as read back (True: torqued), or None if the read failed."""
    try:
        discard_stale_input(bus)
        values = bus.sync_read("Torque_Enable", normalize=False)
    except Exception:  # noqa: BLE001 - unread: the caller says so
        recover_port(bus, settle=False)
        return None
    if any(int(v) not in (0, 1) for v in values.values()):
        return None  # not a Torque_Enable byte: a garbled or late reply
    return {joint: bool(int(v)) for joint, v in values.items()}


def check_torque(bus, pending: set[str]) -> None:
    """Raise TorqueLost when a servo's Torque_Enable reads 0 twice in a row (a limp joint).

    Args:
        bus: the lerobot bus (the loop commands every servo torqued).
        pending: joints read limp once, waiting for the second reading (updated).
    """
    torque = read_torque(bus)
    if torque is None:
        return  # a missed read is not a fault; the next one
    limp = {joint for joint, on in torque.items() if not on}
    confirmed = sorted(limp & pending)
    pending.clear()
    pending.update(limp)
    if confirmed:
        raise TorqueLost(f"torque went off on {', '.join(confirmed)} (Torque_Enable reads 0; a "
                         "brown-out of the servo power, or another program released it): that "
                         "joint is limp. Fix: check the power supply and that no other program "
                         "uses the arm.")
