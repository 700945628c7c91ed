"""What the IK checker asks a student's IK: reachable top-down targets, and the fallback FK.

Targets are top-down grasps of a cube (the object frame ``Rz(yaw)``, z up) at the course's
cube height (z = 0.014 m, its examples) and above, with the course's yaws in [0, pi/2].
Every target is reachable: those on the table are kept only when this package's IK solves
them, those above are this package's FK of random top-down configurations
(:func:`so101_kinematics.ik.solver.sample_top_down_targets`). Neither may need a joint
within :data:`LIMIT_MARGIN_DEG` of its limit, so that a correct IK is never failed for
rounding at the edge of the workspace.

A student's IK may import its own ``so101_forward_kinematics`` from beside it (assignment 7
builds the wrist's position from the FK's factors). When there is none, the checker's
fallback is found instead: :func:`reference_fk_source`, a numpy-only module with the
course's function names (angles in degrees) and this package's factors, generated from
``frames.FIXED_TRANSFORMS`` so that its numbers are written in one place.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from so101_kinematics.errors import UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINT_LIMITS, joint_transform
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.ik.geometry import PAN_AXIS_POINT
from so101_kinematics.ik.solver import sample_top_down_targets

__all__ = [
    "OUT_OF_REACH", "TARGET_COUNT", "build_targets", "out_of_reach_answers",
    "reference_fk_source", "region",
]

TABLE_HEIGHT = 0.014
"""The course's cube height [m]: the object frame of a cube on the table (its examples)."""

TARGET_COUNT = 400
"""Targets per check: half on the table, half above it."""

TARGET_SEED = 7
LIMIT_MARGIN_DEG = 0.5
"""Distance [deg] from every joint limit that the reference solution of a target keeps."""

COURSE_TARGETS = {
    "the course's IK test target (0.2, 0.2, 0.014) m, yaw 0": (0.2, 0.2, 0.014, 0.0),
    "straight ahead (0.2, 0, 0.014) m, yaw 0": (0.2, 0.0, 0.014, 0.0),
    "(0.2, 0.1, 0.014) m, yaw pi/4": (0.2, 0.1, 0.014, math.pi / 4),
}
"""Named targets (x, y, z [m], yaw [rad]), checked first."""

OUT_OF_REACH = {
    "beyond the reach (0.45, 0, 0.014) m": (0.45, 0.0, 0.014, 0.0),
    "too high for a top-down grasp (0.2, 0, 0.25) m": (0.2, 0.0, 0.25, 0.0),
    "behind the base (-0.2, 0, 0.014) m, shoulder_pan beyond its limit": (-0.2, 0.0, 0.014, 0.0),
}
"""Targets no configuration within the limits reaches (x, y, z [m], yaw [rad]), asked after
the others: what the IK says there is reported, not graded (the course expects NaN)."""

REACH_ZONES = ((0.12, "near the base"), (0.2, "mid reach"), (math.inf, "far reach"))
"""Horizontal distance from the pan axis [m] (upper bound) -> the zone's name."""

HEIGHT_ZONES = ((0.02, "on the table"), (0.05, "low (z < 0.05 m)"),
                (math.inf, "raised (z >= 0.05 m)"))
"""Target height z [m] (upper bound) -> the zone's name (top-down grasps reach ~0.08 m)."""


def _rotation_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _within_margin(angles) -> bool:
    """Whether arm angles [deg] (``ARM_JOINTS`` order) keep the margin from every limit."""
    return all(JOINT_LIMITS[joint][0] + LIMIT_MARGIN_DEG <= angle
               <= JOINT_LIMITS[joint][1] - LIMIT_MARGIN_DEG
               for joint, angle in zip(ARM_JOINTS, angles, strict=True))


def _reference(x: float, y: float, z: float, yaw: float) -> list[float] | None:
    """This package's solution [deg] of a target, or None if unreachable or near a limit."""
    try:
        config = get_inverse_kinematics([x, y, z], _rotation_z(yaw))
    except UnreachableError:
        return None
    angles = [config[joint] for joint in ARM_JOINTS]
    return angles if _within_margin(angles) else None


@functools.lru_cache(maxsize=4)
def build_targets(count: int = TARGET_COUNT, seed: int = TARGET_SEED) -> tuple:
    """The targets: the named ones, ``count // 2`` on the table, the rest above it.

    Cached (a class shares them).

    Returns:
        ``(names, targets, references)``: a name per target ("" for random ones),
        (n, 4) x, y, z [m] and yaw [rad] in [0, pi/2), (n, 5) a reachable solution [deg].
    """
    rng = np.random.default_rng(seed)
    names, rows, references = [], [], []
    for name, target in COURSE_TARGETS.items():
        reference = _reference(*target)
        if reference is not None:
            names.append(name)
            rows.append(target)
            references.append(reference)
    on_table = count // 2
    while len(rows) < len(COURSE_TARGETS) + on_table:
        radius = math.sqrt(rng.uniform(0.04 ** 2, 0.3 ** 2))
        azimuth, yaw = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, math.pi / 2)
        x = PAN_AXIS_POINT[0] + radius * math.cos(azimuth)
        y = PAN_AXIS_POINT[1] + radius * math.sin(azimuth)
        reference = _reference(x, y, TABLE_HEIGHT, yaw)
        if reference is not None:
            names.append("")
            rows.append((x, y, TABLE_HEIGHT, yaw))
            references.append(reference)
    above = count - on_table
    draws = 20 * above
    while True:
        angles, positions, yaws = sample_top_down_targets(draws, seed=seed,
                                                          min_height=TABLE_HEIGHT + 0.006)
        keep = [i for i, row in enumerate(angles) if _within_margin(row)]
        if len(keep) >= above:
            break
        draws *= 2
    for i in keep[:above]:
        names.append("")
        rows.append((*positions[i], math.radians(yaws[i] % 90.0)))
        references.append(list(angles[i]))
    return tuple(names), np.array(rows, dtype=float), np.array(references, dtype=float)


def out_of_reach_answers(calls: list[dict]) -> list[dict]:
    """What the IK answered at each :data:`OUT_OF_REACH` target: {name, answer} (text)."""
    answers = []
    for name, call in zip(OUT_OF_REACH, calls, strict=False):
        target = OUT_OF_REACH[name]
        if "error" in call:
            text = f"raised {call['error']} (the course's way is NaN)"
        elif any(joint not in call["value"] for joint in ARM_JOINTS):
            text = f"returned keys {sorted(call['value'])}"
        elif any(math.isnan(call["value"][joint]) for joint in ARM_JOINTS):
            text = "NaN (unreachable, as the course says it)"
        else:
            config = {joint: call["value"][joint] for joint in ARM_JOINTS}
            beyond = [joint for joint in ARM_JOINTS if not JOINT_LIMITS[joint][0] - 0.01
                      <= config[joint] <= JOINT_LIMITS[joint][1] + 0.01]
            position, _ = forward_kinematics(config)
            miss = float(np.linalg.norm(position - np.array(target[:3]))) * 1000
            text = (f"a configuration, {miss:.1f} mm from the target"
                    + (f", {', '.join(beyond)} beyond the limit" if beyond else "")
                    + ", without saying it is out of reach")
        answers.append({"name": name, "answer": text})
    return answers


def region(x: float, y: float, z: float) -> tuple[str, str, str]:
    """(reach, side, height) names of where a target is, seen from the pan axis.

    Side: "front" (+x, within 45 deg), "left (+y)", "right (-y)", "behind" (the base's back).
    """
    dx, dy = x - PAN_AXIS_POINT[0], y - PAN_AXIS_POINT[1]
    radius, azimuth = math.hypot(dx, dy), math.degrees(math.atan2(dy, dx))
    reach = next(name for bound, name in REACH_ZONES if radius < bound)
    height = next(name for bound, name in HEIGHT_ZONES if z < bound)
    side = ("front" if abs(azimuth) <= 45.0 else "behind" if abs(azimuth) > 135.0
            else "left (+y)" if azimuth > 0 else "right (-y)")
    return reach, side, height


def reference_fk_source() -> str:
    """A student-style ``so101_forward_kinematics`` module with this package's factors.

    Numpy only, the course's names: ``get_gw1(theta1_deg)`` ... ``get_g45``, ``get_g5t()``,
    ``get_forward_kinematics(position_dict)`` -> (position, rotation), and ``Rx``, ``Ry``,
    ``Rz`` in degrees.
    """
    lines = ['"""The IK checker\'s fallback FK: so101_kinematics\' factors (degrees)."""',
             "import numpy as np", "", "",
             "def Rx(deg):", "    a = np.deg2rad(deg)",
             "    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], "
             "[0, np.sin(a), np.cos(a)]])", "", "",
             "def Ry(deg):", "    a = np.deg2rad(deg)",
             "    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], "
             "[-np.sin(a), 0, np.cos(a)]])", "", "",
             "def Rz(deg):", "    a = np.deg2rad(deg)",
             "    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], "
             "[0, 0, 1]])", "", "",
             "def _factor(g0, theta_deg):", "    g = np.array(g0, dtype=float)",
             "    g[0:3, 0:3] = g[0:3, 0:3] @ Rz(theta_deg)", "    return g", ""]
    for name in ("w1", "12", "23", "34", "45"):
        fixed = joint_transform(name, 0.0).tolist()
        lines += ["", f"def get_g{name}(theta_deg):", f"    return _factor({fixed!r}, theta_deg)",
                  ""]
    lines += ["", "def get_g5t():", f"    return np.array({joint_transform('5t', 0.0).tolist()!r})",
              "", "", "def get_forward_kinematics(position_dict):",
              "    g = (get_gw1(position_dict['shoulder_pan']) @ "
              "get_g12(position_dict['shoulder_lift'])",
              "         @ get_g23(position_dict['elbow_flex']) @ "
              "get_g34(position_dict['wrist_flex'])",
              "         @ get_g45(position_dict['wrist_roll']) @ get_g5t())",
              "    return g[0:3, 3], g[0:3, 0:3]", ""]
    return "\n".join(lines)
