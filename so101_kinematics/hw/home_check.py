"""The course's calibration check (``pick_place_hw.py --home-check``) and its trims option.

Assignment 8 checks a calibration by commanding the all-zero "home"
configuration and looking where the gripper is. :func:`home_check` does it
as a hardware run like any other (the same confirmations, limits, speed caps
and endings): it moves slowly to home (at most ``HOME_CHECK_SPEED_DEG_S``),
holds ``HOME_CHECK_HOLD_S``, and returns to the starting pose, released there.
It prints where the FK puts the object frame at home (where the gripper's
centre should be over the grid) and where the measured joints put it: a
joint that is off by a few degrees there is what a trim (``--trims FILE``,
``so101_kinematics.trims``) corrects; a bigger error wants a recalibration.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from so101_kinematics.cli import add_gravity_ff_argument
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.bus import format_pose
from so101_kinematics.hw.run import MotionAborted, ending, run_on_arm
from so101_kinematics.inputs import Configuration
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.trims import TRIM_LIMIT_DEG, as_trims

__all__ = ["HOME_CHECK_SPEED_DEG_S", "add_calibration_check_arguments", "home_check"]

HOME_CONFIGURATION = dict.fromkeys(JOINTS, 0.0)  # the course's home: every joint 0, gripper 0
HOME_CHECK_SPEED_DEG_S = 30.0  # "slowly": the speed cap of the home check [deg/s]
HOME_CHECK_MOVE_S = 6.0        # the move there and back: 90 deg at 30 deg/s, min-jerk [s]
HOME_CHECK_HOLD_S = 5.0        # how long the arm holds at home [s]
SETTLE_WINDOW_S = 0.5          # the measured home pose: mean over the hold's last [s]


def add_calibration_check_arguments(parser: argparse.ArgumentParser, mode) -> None:
    """Add ``--trims FILE``, ``--gravity-ff`` and, to the modes ``mode``, ``--home-check``."""
    parser.add_argument("--trims", type=Path, metavar="FILE",
                        help="per-joint trims [deg] added to every goal (the course's "
                             "offset_config), JSON or TOML, e.g. {\"shoulder_lift\": 2.0}; at most "
                             f"{TRIM_LIMIT_DEG:g} deg each (beyond that, recalibrate). With the "
                             "gravity feed-forward on, a trim is what remains after it")
    add_gravity_ff_argument(parser)
    mode.add_argument("--home-check", action="store_true",
                      help="the course's calibration check: move slowly to the all-zero "
                           "configuration, hold, print where the FK puts the gripper, return")


def home_plan() -> Plan:
    """Home and back: one step to the all-zero configuration, its hold, the return to the start."""
    return Plan([Step("home", dict(HOME_CONFIGURATION), HOME_CHECK_MOVE_S, HOME_CHECK_HOLD_S)],
                return_to_start=True, return_duration=HOME_CHECK_MOVE_S)


def object_position_mm(cfg: Mapping[str, float]) -> np.ndarray:
    """Where the FK puts the object frame for ``cfg`` [mm], in the base frame."""
    return forward_kinematics({j: cfg[j] for j in ARM_JOINTS})[0] * 1000.0


def settled_pose(cycles, step: str = "home") -> Configuration | None:
    """The mean measured pose over the last ``SETTLE_WINDOW_S`` of ``step`` (None if unseen)."""
    seen = [c for c in cycles if c.step == step and c.measured]
    if not seen:
        return None
    last = [c for c in seen if c.t_s >= seen[-1].t_s - SETTLE_WINDOW_S]
    return {j: float(np.mean([c.measured[j] for c in last])) for j in JOINTS}


def _xyz(v) -> str:
    return ", ".join(f"{c:.1f}" for c in v)


def home_check(args: argparse.Namespace, calibration: Mapping[str, Any], source, release: str,
               confirm: Callable[[str], bool]) -> int:
    """Run the home check with ``pick_place_hw.py``'s settings; returns the exit status.

    Raises:
        what ``run_on_arm`` raises before anything moved (the caller refuses, exit 2).
    """
    trims = as_trims(args.trims)
    predicted = object_position_mm(HOME_CONFIGURATION)
    speed = min(args.max_speed, HOME_CHECK_SPEED_DEG_S)
    print(f"Home check: every joint to 0 deg (gripper 0) at up to {speed:g} deg/s, hold "
          f"{HOME_CHECK_HOLD_S:g} s, then back to the starting pose. Trims: {trims.describe()}.")
    print(f"At home the FK puts the object frame at x, y, z = {_xyz(predicted)} mm (base "
          "frame): the centre between the jaws should be there.")
    try:
        result = run_on_arm(
            args.port, calibration, home_plan(), robot_id=args.robot_id, source=str(source),
            rate_hz=args.rate, profile=args.profile, max_joint_speed=speed,
            tracking_tolerance=args.tracking_tolerance, confirm=confirm,
            write_calibration=args.write_calibration, trims=trims,
            gravity_ff=getattr(args, "gravity_ff", True))
        status = 0
    except MotionAborted as error:
        print(f"ABORTED: {error}", file=sys.stderr)
        result, status = error.result, 1
    measured = settled_pose(result.cycles)
    if measured is not None:
        seen = object_position_mm(measured)
        print(f"Measured at home: {format_pose(measured)}.")
        print(f"The measured joints put the object frame at x, y, z = {_xyz(seen)} mm, "
              f"{float(np.linalg.norm(seen - predicted)):.1f} mm from the FK's home (the servos' "
              "tracking error). A calibration error does not show in these numbers (each servo "
              "reaches what its own encoder calls 0): it shows as the jaws off that point on the "
              f"grid. A joint off by up to {TRIM_LIMIT_DEG:g} deg: --trims FILE corrects it; "
              "more: recalibrate.")
    print(ending(result, release), file=sys.stderr if status else sys.stdout)
    return status
