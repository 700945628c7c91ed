"""Is a student's IK wrong, or the student's own FK beside it? (``so101-check-ik``).

When the IK's answers miss by this package's FK, the student's own FK (evaluated
at the same answers by the probe) tells the two apart: an FK that agrees with
this package's leaves the mistake in the IK; an FK that disagrees, and by which
the answers do reach the targets, is the mistake.
"""

from __future__ import annotations

import math

import numpy as np

from so101_kinematics.checker.diagnose import rotation_angle_deg
from so101_kinematics.fast_fk import forward_kinematics_batch

__all__ = ["own_fk_note"]


def _wrap_deg(angle: float, period: float) -> float:
    return (angle + period / 2) % period - period / 2


def own_fk_note(results: dict, targets: np.ndarray, angles: np.ndarray, failing: np.ndarray,
                tolerance, match_fraction: float = 0.9) -> str:
    """Whether the failing answers are right by the student's own FK (then the FK is off).

    The student's FK is first compared with this package's at those answers: where
    they agree, the FK is not to blame and the mistake is the IK's. Only an FK
    that disagrees with this package's, and by which the answers reach the
    targets (position and yaw), is named.

    Args:
        results: the probe's results (``own_fk``: the student's FK at each answer).
        targets: (n, 4) x, y, z [m], yaw [rad].
        angles: (n, 5) the answers [deg].
        failing: (n,) the answers outside the tolerance.
        tolerance: (mm, deg).
        match_fraction: the share of failing answers a finding must hold for.

    Returns:
        The note, or "" when the FK is not to blame (or cannot be told).
    """
    own = results.get("own_fk")
    if not own or not failing.any():
        return ""
    rows = np.flatnonzero(failing)
    package_p, package_r = forward_kinematics_batch(np.nan_to_num(angles[rows]))
    errors, agree = [], []
    for k, i in enumerate(rows):
        parts = (own[i] or {}).get("parts") or []
        if len(parts) < 1 or "error" in parts[0] or np.size(parts[0]["value"]) != 3:
            return ""
        position = np.ravel(parts[0]["value"])
        rotation = np.asarray(parts[1]["value"], dtype=float) if len(parts) > 1 and \
            "error" not in parts[1] and np.shape(parts[1]["value"]) == (3, 3) else None
        same = np.linalg.norm(position - package_p[k]) * 1000 <= tolerance[0]
        if rotation is not None:
            same &= rotation_angle_deg(rotation.T @ package_r[k]) <= tolerance[1]
            yaw = math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))
            off = abs(_wrap_deg(yaw - math.degrees(targets[i, 3]), 90.0))
        else:
            off = 0.0
        agree.append(same)
        errors.append(max(np.linalg.norm(position - targets[i, :3]) * 1000,
                          off * tolerance[0] / max(tolerance[1], 1e-9)))
    if np.mean(agree) >= match_fraction:
        return ""  # the student's FK agrees with this package's: the IK is wrong
    if np.mean(np.array(errors) <= tolerance[0]) >= match_fraction:
        return (f"your IK inverts your own FK (with your so101_forward_kinematics the answers "
                f"land within {max(errors):.2f} mm of the targets): the difference is in your "
                "FK; check it with so101-check-fk")
    return ""
