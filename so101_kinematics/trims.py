"""Trims: the course's "offset_config", a per-joint offset added to every goal sent to the arm.

Assignment 8 fixes a residual calibration error by adding a constant per
joint to each configuration before ``sync_write``: if commanding
``shoulder_lift = c`` leaves the joint at ``c - 2`` deg, the trim is +2 deg.
Here a :class:`Trims` says it once, and the hardware backend applies it in
one place (``hw/control.py``, ``ArmSession``): every goal written is
``command + trim``, and every position read is ``reading - trim``, so the
loop's commands, measurements, limits, logs and the sim-vs-arm report are all
in the model's angles (what the FK takes), and the return to the starting
pose lands where the arm stood.

A trim file (``--trims FILE``) is JSON or TOML, joint -> [deg] (gripper
[%]), joints left out are 0::

    {"shoulder_lift": 2.0, "elbow_flex": -4.0}

A trim is refused beyond ``TRIM_LIMIT_DEG`` = 5 deg: the course's own
example needs 2 and 4 deg, and 5 deg on shoulder_pan or shoulder_lift moves
the object frame by about 23 mm at the course's start configuration (a
whole cube's width). An error that big is a calibration problem (a joint
over- or under-extended during ``lerobot-calibrate`` shifts its zero):
recalibrate rather than trim it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

from so101_kinematics.errors import TrimError
from so101_kinematics.frames import JOINTS
from so101_kinematics.inputs import Configuration, Limits, describe_value, is_finite_number, unit
from so101_kinematics.planning.plans import data_kind, parse_data, read_text_file

__all__ = ["TRIM_LIMIT_DEG", "Trims", "as_trims", "load_trims"]

TRIM_LIMIT_DEG = 5.0  # the largest trim accepted [deg] (gripper [%]); beyond it, recalibrate
RECALIBRATE_FIX = ("Fix: an error this big is a calibration problem: recalibrate with "
                   "lerobot-calibrate, moving each joint slowly to both of its limits, then "
                   "check with `python pick_place_hw.py --home-check`.")


class Trims:
    """Per-joint offsets added to every goal written to the arm (the course's ``offset_config``).

    Args:
        offsets: joint -> trim ([deg]; gripper [%]); joints left out are 0.
            Checked: known joints, finite numbers, at most ``TRIM_LIMIT_DEG``.
        source: where they came from, for messages ("the trim file 'x.json'").

    Example::

        >>> trims = Trims({"shoulder_lift": 2.0, "elbow_flex": -4.0})
        >>> trims.to_wire({"shoulder_lift": 10.0, "elbow_flex": 20.0})
        {'shoulder_lift': 12.0, 'elbow_flex': 16.0}
        >>> trims.describe()
        'shoulder_lift +2.0 deg, elbow_flex -4.0 deg'
    """

    def __init__(self, offsets: Mapping[str, float] | None = None, source: str = "Trims"):
        self.source = source
        self.offsets = check_trims(offsets or {}, source)

    def __bool__(self) -> bool:
        return any(value != 0.0 for value in self.offsets.values())

    def __repr__(self) -> str:
        return f"Trims({self.offsets!r})"

    def to_wire(self, cfg: Mapping[str, float]) -> Configuration:
        """The goal to write for command ``cfg``: each joint plus its trim."""
        return {joint: value + self.offsets[joint] for joint, value in cfg.items()}

    def from_wire(self, pose: Mapping[str, float]) -> Configuration:
        """The model's angles of a position read from the arm: each joint minus its trim."""
        return {joint: value - self.offsets[joint] for joint, value in pose.items()}

    def limits(self, calibrated: Limits) -> Limits:
        """The commands whose goal (command + trim) stays inside the ``calibrated`` range."""
        return {j: (low - self.offsets[j], high - self.offsets[j])
                for j, (low, high) in calibrated.items()}

    def describe(self) -> str:
        """The non-zero trims in one line, e.g. "shoulder_lift +2.0 deg", or "none"."""
        return ", ".join(f"{j} {v:+.1f} {unit(j)}" for j, v in self.offsets.items() if v) or "none"


def check_trims(offsets: Mapping[str, float], source: str = "Trims") -> Configuration:
    """Every joint's trim as a float (0 where left out), in ``JOINTS`` order.

    Raises:
        TrimError: not a mapping, an unknown joint, not a finite number, or
            beyond ``TRIM_LIMIT_DEG`` (the message says to recalibrate).
    """
    if not isinstance(offsets, Mapping):
        raise TrimError(f"{source} must map joint names to offsets [deg], got "
                        f"{describe_value(offsets)}. Fix: e.g. {{\"shoulder_lift\": 2.0}}.")
    unknown = [name for name in offsets if name not in JOINTS]
    if unknown:
        raise TrimError(f"{source}: unknown joint '{unknown[0]}'. Joints are: "
                        f"{', '.join(JOINTS)}. Fix: use those names.")
    out = {}
    for joint in JOINTS:
        value = offsets.get(joint, 0.0)
        if not is_finite_number(value):
            raise TrimError(f"{source}: {joint} must be a finite number of {unit(joint)}, got "
                            f"{describe_value(value)}. Fix: give a number.")
        if abs(value) > TRIM_LIMIT_DEG:
            raise TrimError(f"{source}: {joint} = {value:g} {unit(joint)} is beyond the "
                            f"{TRIM_LIMIT_DEG:g} {unit(joint)} a trim may correct. "
                            + RECALIBRATE_FIX)
        out[joint] = float(value) + 0.0  # -0.0 -> 0.0
    return out


def load_trims(path: str | Path) -> Trims:
    """Read a trim file: JSON or TOML (by its suffix), joint -> [deg] (gripper [%]).

    Raises:
        TrimError: unreadable, not valid JSON/TOML, or a bad trim (see :func:`check_trims`).
    """
    path = Path(path)
    text = read_text_file(path, "Trim file", TrimError)
    kind = data_kind(path)
    try:
        data = parse_data(text, kind)
    except (ValueError, RecursionError) as error:
        message = " ".join(str(error).split())
        raise TrimError(f"Trim file '{path}' is not valid {kind}: {message}. Fix: write it as "
                        "{\"shoulder_lift\": 2.0} (JSON) or shoulder_lift = 2.0 (TOML).") from None
    return Trims(data, f"Trim file '{path}'")


def as_trims(value: Trims | Mapping[str, float] | str | Path | Callable | None) -> Trims:
    """Trims from what a caller has: None (no trims), a mapping, a trim file, or Trims.

    Also the course's own ``offset_config(config) -> config`` function: its
    offsets are what it adds to an all-zero configuration, and it must add
    the same at another configuration (a constant per-joint offset).

    Raises:
        TrimError: a bad mapping or file, or a function that is not a constant offset.
    """
    if value is None or isinstance(value, Trims):
        return value or Trims()
    if isinstance(value, (str, Path)):
        return load_trims(value)
    if callable(value) and not isinstance(value, Mapping):
        name = getattr(value, "__name__", "offset_config")
        try:
            offsets = {j: float(value(dict.fromkeys(JOINTS, 0.0))[j]) for j in JOINTS}
            moved = {j: float(value(dict.fromkeys(JOINTS, 10.0))[j]) - 10.0 for j in JOINTS}
        except (KeyError, TypeError, ValueError) as error:
            raise TrimError(f"{name}(config) failed on an all-zero configuration ({error!r}). "
                            "Fix: return the configuration with each joint's offset added.") \
                from None
        if any(not math.isclose(moved[j], offsets[j], abs_tol=1e-9) for j in JOINTS):
            raise TrimError(f"{name}(config) does not add a constant offset per joint. Fix: "
                            "add a fixed number of degrees to each joint, or give a dict "
                            "joint -> [deg].")
        return Trims(offsets, name)
    return Trims(value, "offset_config")
