"""What the control loop checks each cycle: tracking (a stall, a collision), servo error bits."""

from __future__ import annotations

from collections.abc import Mapping

from so101_kinematics.errors import ServoFault, TrackingError
from so101_kinematics.hw.bus import discard_stale_input, recover_port
from so101_kinematics.motion import Configuration, unit

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
