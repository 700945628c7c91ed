"""What a hardware run checks before the port opens: the plan (limits, table) and the settings.

Split from ``hw/run.py`` (the run and its endings): nothing here talks to the
arm, so ``pick_place_hw.py --dry-run`` and the real run refuse the same plans
in the same words before anything is connected.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from so101_kinematics.calibration import calibrated_limits
from so101_kinematics.errors import JointLimitError
from so101_kinematics.frames import JOINT_LIMITS
from so101_kinematics.hw.control import TRACKING_TOLERANCE_LIMIT_DEG
from so101_kinematics.hw.timing import SPEED_CAP_LIMIT_DEG_S, check_rate
from so101_kinematics.inputs import check_number
from so101_kinematics.planning.motion import Plan
from so101_kinematics.planning.plans import validate_plan
from so101_kinematics.trims import Trims, as_trims

__all__ = ["check_run_settings", "validate_plan_for_arm"]


def validate_plan_for_arm(plan: Plan, calibration: Mapping[str, Any] | None,
                          source: str = "the calibration", trims: Trims | None = None,
                          base_height: float = 0.0) -> Plan:
    """Check every waypoint against the model's limits, the arm's calibrated limits and the table.

    Args:
        plan: the plan.
        calibration: the arm's lerobot calibration (None: the model's limits only).
        source: where the calibration came from (for messages).
        trims: per-joint trims, taken off the calibrated range.
        base_height: the table is this far below the base frame [m] (``--base-height``):
            the path through the waypoints stays clear of it (``clearance.py``).

    Raises:
        PlanError: bad structure; JointLimitError naming joint, value, limit,
            which limits (model or calibration) and the fix; ClearanceError naming
            the waypoint, the joint values, the depth and the fix.
    """
    try:
        validate_plan(plan, JOINT_LIMITS, base_height=base_height)
    except JointLimitError as error:
        raise JointLimitError(f"{error} (joint limits of the SO-101 model, as in the simulator)") \
            from None
    if calibration is not None:
        try:
            validate_plan(plan, as_trims(trims).limits(calibrated_limits(calibration)),
                          base_height=base_height)
        except JointLimitError as error:
            raise JointLimitError(f"{error} (calibrated range of this arm, from {source}, less "
                                  "any trim; if the range looks too small, recalibrate)") from None
    return plan


def check_run_settings(rate_hz: float, max_joint_speed: float, tracking_tolerance: float) -> None:
    """Refuse a setting outside its documented range (PlanError naming it), before connecting."""
    check_rate(rate_hz)
    check_number(max_joint_speed, "--max-speed", 0.0, SPEED_CAP_LIMIT_DEG_S, "deg/s",
                 low_open=True)
    check_number(tracking_tolerance, "--tracking-tolerance", 0.0, TRACKING_TOLERANCE_LIMIT_DEG,
                 "deg", low_open=True)
