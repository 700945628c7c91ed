"""Nothing into the table: the one clearance check of every commanded configuration and path.

The arm's collision boxes (``model/so101.xml``, class ``collision``: the links,
the gripper, both jaws) and the object frame are placed by the closed-form
frame chain (no MuJoCo), and their lowest point is compared with the table
top, ``base_height`` [m] below the base frame (0: the base stands on the
table; the lab's mount lifts it by ``--base-height``). A path is checked
along its interpolation (joint space, a sample every :data:`PATH_STEP_DEG` of
the joint that moves most), not only at its waypoints: the straight line in
joint space between two safe poses can dip.

The rule: every point keeps :data:`CLEARANCE_MARGIN_M` above the table. A
path that starts closer than that (an arm at rest on the table, a pose it
was put in by hand) may move as long as it never goes lower than where it
started: it can always get out of where it is.

Example:
    >>> from so101_kinematics.planning.plans import STARTING_CONFIGURATION
    >>> height, part = lowest_point(STARTING_CONFIGURATION)
    >>> round(height * 1000, 1), part  # the course's grasp: the cube's centre 13 mm up
    (13.0, 'object_frame')
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from so101_kinematics.errors import ClearanceError
from so101_kinematics.frames import ARM_JOINTS, FIXED_ROTATION, FIXED_TRANSFORMS, JOINT_RANGES_RAD

CLEARANCE_MARGIN_M = 0.005
"""[m] every collision box and the object frame stay this far above the table. The course's
grasp puts the object frame (the cube's centre) 13 mm up and the fingertips 16 mm up; 5 mm is
more than the FK's error on a calibrated arm (a degree at the shoulder moves the jaws ~4 mm)
and leaves room for a cube's centre pressed 8 mm lower than the course's."""

PATH_STEP_DEG = 1.0
"""[deg] a path is sampled this often (on the joint that moves most); at the arm's 0.4 m
reach a degree is 7 mm of travel, the boxes' lowest points move less than that between
samples, and the margin covers the rest."""

START_TOLERANCE_M = 0.0005
"""[m] a path that starts lower than the margin may go this much lower than its start
(sampling and rounding), no more."""

# The collision boxes of model/so101.xml: body frame -> (geom name, centre [m], half sizes [m]),
# axis-aligned in the body frame (tests/core/test_clearance.py checks them against the model).
LINK_BOXES = {
    "1": (("shoulder_box", (-0.0192, 0.0012, -0.0091), (0.0314, 0.0276, 0.0553)),),
    "2": (("upper_arm_box", (-0.0591, -0.0003, 0.0202), (0.0711, 0.0122, 0.0337)),
          ("elbow_servo_box", (-0.1126, -0.0155, 0.0183), (0.0124, 0.0227, 0.0198))),
    "3": (("lower_arm_box", (-0.0534, 0.0, 0.0202), (0.0654, 0.012, 0.0322)),
          ("wrist_servo_box", (-0.1179, 0.0035, 0.02), (0.0272, 0.0185, 0.0282))),
    "4": (("wrist_box", (-0.0022, -0.0269, 0.0222), (0.0179, 0.0389, 0.0311)),),
    "5": (("gripper_servo_box", (0.0077, 0.0005, -0.0234), (0.0227, 0.0198, 0.0124)),
          ("gripper_body_box", (-0.0026, -0.002, -0.0475), (0.0326, 0.022, 0.012)),
          ("fixed_jaw_pad", (-0.0121, -0.0002, -0.0982), (0.0042, 0.006, 0.0062)),
          ("fixed_jaw_upper", (-0.0177, -0.0002, -0.0771), (0.0078, 0.0078, 0.0149))),
    "jaw": (("moving_jaw_pad", (-0.00865, -0.0735, 0.019), (0.00365, 0.0085, 0.0065)),
            ("moving_jaw_finger", (-0.00215, -0.0475, 0.019), (0.00615, 0.0175, 0.0075)),
            ("moving_jaw_root", (0.0, -0.01, 0.019), (0.01, 0.02, 0.024))),
}
MOVING_JAW_MOUNT = (0.0202, 0.0188, -0.0234)
"""[m] the moving jaw's body in the gripper frame; its rotation is Rx(90) (quat 0.707 0.707 0 0)."""
_JAW_ROTATION = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # Rx(90)

PARTS = tuple(name for boxes in LINK_BOXES.values() for name, _, _ in boxes) + ("object_frame",)
"""What the check watches, in the order of :func:`lowest_points`' columns."""

_CHAIN = (("1", "w1"), ("2", "12"), ("3", "23"), ("4", "34"), ("5", "45"))
_GRIPPER_LOW, _GRIPPER_HIGH = JOINT_RANGES_RAD["gripper"]
_DEFAULT_GRIPPERS = (0.0, 50.0, 100.0)  # a configuration without a gripper: each of these


def _rz(theta: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about z by ``theta`` [rad]."""
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros((len(theta), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
    out[:, 2, 2] = 1.0
    return out


def lowest_points(angles: np.ndarray) -> np.ndarray:
    """Height [m] above the base frame of each part's lowest point, for many configurations.

    Args:
        angles: (N, 6) [rad]: the five arm joints (``ARM_JOINTS`` order), then the
            gripper joint's angle [rad] (not the 0-100 opening).

    Returns:
        (N, len(PARTS)) heights [m]: each box's lowest corner, then the object frame.
    """
    angles = np.atleast_2d(np.asarray(angles, dtype=float))
    n = len(angles)
    rotation = np.broadcast_to(np.eye(3), (n, 3, 3))
    position = np.zeros((n, 3))
    columns = []
    frames = {}
    for (frame, name), column in zip(_CHAIN, range(5), strict=True):
        offset, fixed = np.asarray(FIXED_TRANSFORMS[name][0]), FIXED_ROTATION[name]
        position = position + rotation @ offset
        rotation = rotation @ fixed @ _rz(angles[:, column])
        frames[frame] = (rotation, position)
    rotation5, position5 = frames["5"]
    frames["jaw"] = (rotation5 @ _JAW_ROTATION @ _rz(angles[:, 5]),
                     position5 + rotation5 @ np.asarray(MOVING_JAW_MOUNT))
    for frame, boxes in LINK_BOXES.items():
        rotation, position = frames[frame]
        row = rotation[:, 2, :]  # the world z of each body axis
        for _, centre, half in boxes:
            z = position[:, 2] + row @ np.asarray(centre)
            columns.append(z - np.abs(row) @ np.asarray(half))
    tool = np.asarray(FIXED_TRANSFORMS["5t"][0])
    columns.append(position5[:, 2] + rotation5[:, 2, :] @ tool)
    return np.stack(columns, axis=1)


def _radians(cfg: Mapping[str, float], gripper: float) -> list[float]:
    """One configuration ([deg], gripper [0, 100]) as lowest_points' row [rad]."""
    row = [math.radians(float(cfg[j])) for j in ARM_JOINTS]
    row.append(_GRIPPER_LOW + (_GRIPPER_HIGH - _GRIPPER_LOW) * float(gripper) / 100.0)
    return row


def _rows(cfgs: Sequence[Mapping[str, float]]) -> tuple[np.ndarray, int]:
    """Rows for ``cfgs`` (each once per gripper opening when it has none); rows per config."""
    grippers = (None,) if all("gripper" in c for c in cfgs) else _DEFAULT_GRIPPERS
    rows = [_radians(c, c["gripper"] if g is None else c.get("gripper", g))
            for c in cfgs for g in grippers]
    return np.array(rows), len(grippers)


def lowest_point(cfg: Mapping[str, float], base_height: float = 0.0) -> tuple[float, str]:
    """(height above the table [m], part) of a configuration's lowest point.

    Args:
        cfg: joint name -> [deg] (gripper [0, 100]; without it the worst of closed,
            half open and open is taken).
        base_height: the table is this far below the base frame [m].
    """
    heights = lowest_points(_rows([cfg])[0]).min(axis=0)
    part = int(np.argmin(heights))
    return float(heights[part]) + base_height, PARTS[part]


def sample_path(a: Mapping[str, float], b: Mapping[str, float],
                step_deg: float = PATH_STEP_DEG) -> list[dict[str, float]]:
    """Configurations along the straight joint-space path from ``a`` to ``b`` (both ends in).

    The joints of ``b`` are interpolated (any profile traces the same path); ``a``
    gives the rest. The number of samples is set by the joint that moves most.
    """
    b = dict(a, **b)
    span = max((abs(b[j] - a[j]) for j in b if j in a), default=0.0)
    n = max(1, math.ceil(span / step_deg))
    return [{j: a.get(j, b[j]) + s * (b[j] - a.get(j, b[j])) for j in b}
            for s in np.linspace(0.0, 1.0, n + 1)]


def check_path(points: Sequence[Mapping[str, float]], names: Sequence[str] | None = None, *,
               base_height: float = 0.0, margin: float = CLEARANCE_MARGIN_M,
               where: str = "", fix: str = "", from_pose: bool = True,
               rest: Mapping[str, float] | None = None,
               between: Callable[[], None] | None = None) -> None:
    """Refuse a path whose interpolation brings a part closer to the table than allowed.

    Args:
        points: configurations ([deg], gripper [0, 100]); the path goes through them in order,
            straight in joint space between two; the first is where the arm is (or will be).
        names: a name for each point after the first (the waypoint the segment goes to).
        base_height: the table is this far below the base frame [m].
        margin: clearance every part keeps [m]; a path starting lower may go no lower.
        where: context for the message, e.g. the plan file.
        fix: what to do, for the message (a default names the usual fixes).
        from_pose: the first point is where the arm stands: a start closer than the margin
            is allowed (the path may not go lower than it). False: the margin holds throughout.
        rest: where the arm stood before the run (its measured start), or None: the path
            may come as low as that pose, no lower. The return to it ends there: a released
            arm slumps onto its rest or the table (the virtual arm's jaw 0.1 mm above it),
            and a run that started there must be able to end there.
        between: called after each segment's check (the virtual arm answers its bus there).

    Raises:
        ClearanceError: naming the waypoint, the joint values there, the part, how deep
            (or how close) it goes, and the fix. Nothing has moved.
    """
    if not points:
        return
    start = lowest_point(points[0], base_height)[0]
    allowed = min(margin, start - START_TOLERANCE_M) if from_pose else margin
    if rest is not None:
        allowed = min(allowed, lowest_point(rest, base_height)[0] - START_TOLERANCE_M)
    for index, (a, b) in enumerate(zip(points, points[1:], strict=False)):
        samples = sample_path(a, b)
        rows, per = _rows(samples)
        heights = lowest_points(rows) + base_height
        worst = heights.min(axis=1).reshape(len(samples), per).min(axis=1)
        bad = np.flatnonzero(worst < allowed)
        if between is not None:
            between()
        if not len(bad):
            continue
        deepest = int(bad[np.argmin(worst[bad])])
        sample = samples[deepest]
        part = PARTS[int(np.argmin(heights[deepest * per: deepest * per + per].min(axis=0)))]
        name = names[index] if names is not None and index < len(names) else f"point {index + 1}"
        at = "at the waypoint" if deepest == len(samples) - 1 else \
            f"{100.0 * deepest / (len(samples) - 1):.0f} % of the way there"
        depth = -worst[deepest]
        how = (f"{depth * 1000:.1f} mm into the table" if depth > 0 else
               f"within {-depth * 1000:.1f} mm of the table (the margin is {margin * 1000:g} mm)")
        pose = ", ".join(f"{j} {v:.1f}" for j, v in sample.items() if j != "gripper")
        table = f" (the table {base_height * 1000:g} mm below the base)" if base_height else ""
        prefix = f"{where}: " if where else ""
        raise ClearanceError(
            f"{prefix}the path to waypoint '{name}' goes into the table{table}: the {part} "
            f"reaches {how}, {at} ({pose} deg). Nothing moved. Fix: "
            + (fix or "raise that waypoint (less shoulder_lift, or a higher IK target), or add "
                      "a waypoint above it so the arm comes down from above."))


def check_plan_clearance(plan, start: Mapping[str, float] | None = None, *,
                         base_height: float = 0.0, where: str = "") -> None:
    """:func:`check_path` over a plan: its steps in order, then the return to ``start``.

    Args:
        plan: a :class:`~so101_kinematics.planning.motion.Plan` (validated configurations).
        start: where the arm stands (measured); None before the port is open: then the
            path is checked from the first waypoint on, every point to the full margin
            (the move from the arm's pose is checked when it starts).
        base_height: the table is this far below the base frame [m].
        where: context for messages (the plan file).
    """
    names = [step.name for step in plan.steps]
    points = [dict(step.configuration) for step in plan.steps]
    if not points or any(j not in points[0] for j in ARM_JOINTS):
        return  # a partial configuration (a joint's own check): nothing to place
    if start is None:
        points.insert(0, points[0])
    else:
        points.insert(0, dict(start))
        if plan.return_to_start:
            points.append(dict(start))
            names.append("return_to_start")
    for i in range(1, len(points)):  # a joint a waypoint leaves out stays where it was
        points[i] = dict(points[i - 1], **points[i])
    check_path(points, names, base_height=base_height, where=where, from_pose=start is not None)
