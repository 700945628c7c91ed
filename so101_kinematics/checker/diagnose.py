"""Known FK mistakes, recognised from a factor's matrices: which one, and what to fix.

Each factor of the course's FK is ``g_ab(theta) = [[R_fixed Rz(theta), p], [0, 0, 0, 1]]``
with ``R_fixed`` and ``p`` from the upstream model (``frames.FIXED_TRANSFORMS``).
Its displacement does not depend on the joint angle, so a wrong offset shows directly in
the student's ``p``; the rotation is matched against the rotations that the usual mistakes
produce (a joint turning the wrong way, rotations composed in the other order, degrees used
as radians, the gripper mount's tilt left out), at every test angle.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from so101_kinematics import model_facts
from so101_kinematics.frames import FIXED_TRANSFORMS, GRIPPER_MOUNT_TILT_DEG, Rx, Ry, Rz

__all__ = [
    "diagram_note", "displacement_causes", "rotation_angle_deg", "rotation_causes",
    "tool_convention", "units_note",
]

MATCH_MM = 0.05
"""Two displacements agree when within this [mm] (for recognising a cause, not for grading)."""

MATCH_DEG = 0.02
"""Two rotations agree when within this [deg] (for recognising a cause)."""

UPSTREAM_BODY = {"w1": ("shoulder", "base"), "12": ("upper_arm", "shoulder"),
                 "23": ("lower_arm", "upper_arm"), "34": ("wrist", "lower_arm"),
                 "45": ("gripper", "wrist")}
"""Transform -> (body, its parent) in the upstream model ``so101_new_calib``."""

OFFSET_MEANING = {
    ("w1", 0): "distance from the base origin to the shoulder_pan axis",
    ("w1", 2): "height of the shoulder above the base",
    ("12", 0): "distance from the shoulder_pan axis to the shoulder_lift joint",
    ("12", 1): "sideways offset of the shoulder_lift joint",
    ("12", 2): "height of the shoulder_lift joint above frame 1",
    ("23", 0): "upper-arm length",
    ("23", 1): "elbow offset (the upper arm's bend)",
    ("34", 0): "lower-arm length",
    ("34", 1): "offset of the wrist_flex joint from the lower arm's line",
    ("45", 1): "distance from wrist_flex to the gripper",
    ("45", 2): "sideways offset of the wrist_roll axis",
}
"""What each non-zero displacement component of the model is (transform, axis index)."""

DIAGRAM_DROPS = {("12", 1), ("34", 1), ("45", 2)}
"""Offsets the course's FK diagram rounds away (with the gripper mount's tilt)."""

TOOL_POINTS = {
    "this package's object frame (the centre of a held 26 mm cube, docs/fk.md, 'The object frame')":
        FIXED_TRANSFORMS["5t"][0],
    "the course diagram's tool point (0, 0, -0.1034)": (0.0, 0.0, -0.1034),
    "the upstream model's gripperframe site (the fixed jaw's tip)":
        model_facts.site_position("gripperframe"),
}
"""Tool-frame origins in frame 5 [m] that are conventions, not mistakes."""

_AXIS = {"x": Rx, "y": Ry, "z": Rz}
_TILT_HINT = ("the gripper mount is tilted in the model (GRIPPER_MOUNT_TILT_DEG = "
              f"{GRIPPER_MOUNT_TILT_DEG:.2f} deg, from the upstream quaternion); see the "
              "FK table in docs/fk.md")


def rotation_angle_deg(rotation: np.ndarray) -> float:
    """Angle [deg] of a rotation matrix (0 to 180)."""
    cosine = (np.trace(rotation) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, cosine))))


def rotation_axis(rotation: np.ndarray) -> np.ndarray:
    """Unit axis of a rotation (any sign for a half turn)."""
    skew = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0],
                     rotation[1, 0] - rotation[0, 1]])
    if np.linalg.norm(skew) > 1e-6:
        return skew / np.linalg.norm(skew)
    symmetric = (rotation + np.eye(3)) / 2.0  # a half turn: columns along the axis
    column = symmetric[:, int(np.argmax(np.diag(symmetric)))]
    return column / max(np.linalg.norm(column), 1e-12)


def describe_axis(axis: np.ndarray) -> str:
    """'about z' for a principal axis, else 'about (0.12, 0.99, 0)'."""
    index = int(np.argmax(np.abs(axis)))
    if abs(axis[index]) > 0.999:
        return f"about {'xyz'[index]}"
    return "about (" + ", ".join(f"{value:.2f}" for value in axis) + ")"


def _sequence(steps, scale: float = 1.0) -> np.ndarray:
    rotation = np.eye(3)
    for axis, angle in steps:
        rotation = rotation @ _AXIS[axis](math.remainder(angle * scale, 360.0))
    return rotation


def _fixed_text(steps) -> str:
    return " @ ".join(f"R{axis}({angle:g})" for axis, angle in steps)


def _rotation_hypotheses(name: str):
    """(cause, rotation(theta)) for each known mistake in the rotation of transform ``name``."""
    steps = FIXED_TRANSFORMS[name][1]
    fixed = _sequence(steps)
    reverse = _sequence(steps[::-1])
    deg = 180.0 / math.pi

    def joint(theta):
        return Rz(math.remainder(theta, 360.0))

    hypotheses = [
        ("the joint turns the wrong way: use R_fixed @ Rz(+theta)",
         lambda t: fixed @ joint(-t)),
        (f"the fixed rotation is transposed (R_fixed.T, the inverse): use R_fixed = "
         f"{_fixed_text(steps)}, then @ Rz(theta)", lambda t: fixed.T @ joint(t)),
        ("the rotation is transposed ((R_fixed @ Rz(theta)).T): put R_fixed @ Rz(theta) "
         "itself in the top-left 3x3", lambda t: (fixed @ joint(t)).T),
        ("rotations composed in the wrong order: the joint rotation comes after the fixed "
         f"one, R_fixed @ Rz(theta) with R_fixed = {_fixed_text(steps)}",
         lambda t: joint(t) @ fixed),
        ("degrees passed where radians are expected: the joint angle [deg] goes into "
         "cos/sin as if it were radians; convert it once with np.deg2rad",
         lambda t: fixed @ joint(t * deg)),
        ("the angle is converted to radians twice: Rz(...) already takes degrees",
         lambda t: fixed @ joint(t / deg)),
        ("degrees passed where radians are expected: the rotation helpers use cos/sin of "
         "degrees (fixed rotations too); convert with np.deg2rad inside Rx, Ry, Rz",
         lambda t: _sequence(steps, deg) @ joint(t * deg)),
    ]
    if rotation_angle_deg(reverse.T @ fixed) > MATCH_DEG:
        hypotheses.append(
            (f"rotations composed in the wrong order: the model's fixed rotation is "
             f"{_fixed_text(steps)}, applied left to right", lambda t: reverse @ joint(t)))
    if name == "45":
        untilted = _sequence(steps[:-1])
        tilt = GRIPPER_MOUNT_TILT_DEG
        hypotheses += [
            (f"rotation off by {abs(tilt):.2f} deg about z: the mount tilt is missing; "
             + _TILT_HINT, lambda t: untilted @ joint(t)),
            (f"rotation off by {2 * abs(tilt):.2f} deg about z: the mount tilt has the wrong "
             "sign; " + _TILT_HINT, lambda t: untilted @ Rz(-tilt) @ joint(t)),
            (f"the mount tilt is missing ({abs(tilt):.2f} deg about z; {_TILT_HINT}) and the "
             "joint turns the wrong way", lambda t: untilted @ joint(-t)),
        ]
    return hypotheses


def _matches(function, angles, rotations) -> bool:
    return all(rotation_angle_deg(function(angle).T @ rotation) <= MATCH_DEG
               for angle, rotation in zip(angles, rotations, strict=True))


def rotation_causes(name: str, angles, rotations) -> list[str]:
    """Known causes of a factor's rotation error, or a description of the error.

    Args:
        name: the transform, e.g. "45".
        angles: the joint angles [deg] it was called with.
        rotations: the student's (3, 3) rotations at those angles.

    Returns:
        Sentences for the report; empty when the rotation is right.
    """
    fixed = _sequence(FIXED_TRANSFORMS[name][1])
    if _matches(lambda t: fixed @ Rz(math.remainder(t, 360.0)), angles, rotations):
        return []
    star = elementwise_cause(name, angles, rotations)
    if star:
        return [star]
    for rotation in rotations:
        if abs(np.linalg.det(rotation) - 1.0) > 1e-3 or \
                np.abs(rotation.T @ rotation - np.eye(3)).max() > 1e-3:
            return [f"the 3x3 part is not a rotation matrix (determinant "
                    f"{np.linalg.det(rotation):.3f}): check the signs in Rx/Ry/Rz"]
    for cause, function in _rotation_hypotheses(name):
        if _matches(function, angles, rotations):
            return [cause]
    # Not a known mistake: a constant extra rotation? Describe it.
    extras = [fixed.T @ rotation @ Rz(-math.remainder(angle, 360.0))
              for angle, rotation in zip(angles, rotations, strict=True)]
    if all(rotation_angle_deg(extra.T @ extras[0]) <= MATCH_DEG for extra in extras):
        extra = extras[0]
        angle = rotation_angle_deg(extra)
        axis = describe_axis(rotation_axis(extra))
        return [f"a constant rotation error of {angle:.2f} deg {axis}"
                f" (in frame {name[0]} after the fixed rotation): the model's fixed rotation is "
                f"{_fixed_text(FIXED_TRANSFORMS[name][1])}"]
    return ["the rotation error changes with the joint angle and matches no known mistake: "
            "check which axis the joint turns about (the model's joints all turn about their "
            "own z) and the fixed rotation " + _fixed_text(FIXED_TRANSFORMS[name][1])]


def elementwise_cause(name: str, angles, rotations) -> str:
    """The rotations multiplied element by element (``*`` for ``@``), or ''.

    Tried: every product ``*`` (the fixed rotations and the joint's), and only the
    joint's (``R_fixed * Rz(theta)``).
    """
    steps = FIXED_TRANSFORMS[name][1]
    matrices = [_AXIS[axis](angle) for axis, angle in steps]
    every = functools.reduce(np.multiply, matrices)
    fixed = _sequence(steps)
    for product, where in ((every, "every product"), (fixed, "the joint's rotation")):
        if all(np.abs(product * Rz(math.remainder(angle, 360.0)) - rotation).max() <= 1e-6
               for angle, rotation in zip(angles, rotations, strict=True)):
            return (f"the rotations are multiplied element by element (* in {where}): "
                    f"numpy's * is not the matrix product. Fix: use @, R_fixed @ Rz(theta) with "
                    f"R_fixed = {_fixed_text(steps)}")
    return ""


def _offset_name(name: str, index: int) -> str:
    axis = "xyz"[index]
    meaning = OFFSET_MEANING.get((name, index), f"{axis} displacement")
    value = FIXED_TRANSFORMS[name][0][index]
    if name in UPSTREAM_BODY:
        body, parent = UPSTREAM_BODY[name]
        where = f"upstream so101_new_calib: body '{body}' at {axis} = {value:g} m in '{parent}'"
    else:
        where = f"{axis} = {value:g} m"
    return f"{abs(value) * 1000:.1f} mm {meaning} ({where})"


def displacement_causes(name: str, angles, rotations, displacements) -> list[str]:
    """Known causes of a factor's displacement error (see :func:`rotation_causes`).

    Args:
        name: the transform, e.g. "12".
        angles: the joint angles [deg].
        rotations: the student's (3, 3) rotations.
        displacements: the student's (3,) displacements [m].

    Returns:
        Sentences for the report; empty when the displacement is right.
    """
    reference = np.asarray(FIXED_TRANSFORMS[name][0], dtype=float)
    points = np.asarray(displacements, dtype=float)
    if np.abs(points - points[0]).max() * 1000 > MATCH_MM:
        rotated = np.array([rotation @ reference for rotation in rotations])
        if np.abs(points - rotated).max() * 1000 <= MATCH_MM:
            return ["the displacement is turned by the rotation (R @ p): in g_ab the fixed "
                    "displacement p goes into the last column as it is"]
        return ["the displacement changes with the joint angle: it should be the fixed p of "
                "the model, the same at every angle"]
    point = points[0]
    if np.abs(point - reference).max() * 1000 <= MATCH_MM:
        return []
    if np.allclose(point, 1000.0 * reference, rtol=1e-3, atol=1e-3):
        return ["the displacement is in millimetres; the FK works in metres"]
    causes = []
    order = np.argsort(np.abs(reference))
    if np.allclose(np.sort(np.abs(point)), np.abs(reference)[order], atol=MATCH_MM / 1000) \
            and not np.allclose(np.abs(point), np.abs(reference), atol=MATCH_MM / 1000):
        return [f"the displacement's components are in the wrong order: you have "
                f"{_vector(point)}, the model {_vector(reference)}"]
    for index in range(3):
        mine, model = point[index], reference[index]
        difference_mm = abs(mine - model) * 1000
        if difference_mm <= MATCH_MM:
            continue
        axis = "xyz"[index]
        if abs(mine) < 1e-7 and abs(model) > 1e-3:
            causes.append(f"the {_offset_name(name, index)} is missing")
        elif abs(mine + model) * 1000 <= MATCH_MM:
            causes.append(f"the {_offset_name(name, index)} has the wrong sign")
        elif difference_mm < 0.5:
            causes.append(f"{axis} is rounded: {mine:g} m, the model {model:g} m "
                          f"({difference_mm:.2f} mm)")
        else:
            causes.append(f"{axis} is {mine:g} m, the model {model:g} m "
                          f"({difference_mm:.1f} mm off)")
    return causes


def _vector(values) -> str:
    return "(" + ", ".join(f"{value:g}" for value in values) + ")"


def tool_convention(matrix: np.ndarray) -> dict:
    """How a student's ``g_5t`` differs from this package's, and whether that is a convention.

    Args:
        matrix: the student's (4, 4) ``get_g5t()``.

    Returns:
        ``{"accepted": bool, "text": str}``: accepted when the origin is a known tool point
        (this package's, the course diagram's, the fixed jaw's tip) and the axes differ
        from this package's by nothing or by a half or quarter turn about one axis.
    """
    reference_rotation = _sequence(FIXED_TRANSFORMS["5t"][1])
    point, rotation = matrix[:3, 3], matrix[:3, :3]
    distance_mm = np.linalg.norm(point - np.asarray(FIXED_TRANSFORMS["5t"][0])) * 1000
    named = [label for label, origin in TOOL_POINTS.items()
             if np.linalg.norm(point - np.asarray(origin)) * 1000 <= 0.5]
    if named:
        where = f"the origin is {named[0]}"
    else:
        where = f"the origin {_vector(point)} m is no known tool point"
    if distance_mm > MATCH_MM:
        where += f", {distance_mm:.1f} mm from this package's"
    relative = reference_rotation.T @ rotation
    angle = rotation_angle_deg(relative)
    axis_text = describe_axis(rotation_axis(relative))
    principal = not axis_text.startswith("about (")
    if angle <= MATCH_DEG:
        turn, turn_ok = "the axes are this package's", True
    elif abs(angle - 180.0) <= MATCH_DEG and principal:
        turn, turn_ok = (f"the axes differ by a half turn {axis_text} of the tool frame: a "
                         "different object-frame convention (this package, as the course's "
                         "IK assignment draws it: z up at a top-down grasp, Rz(yaw))"), True
    elif abs(angle - 90.0) <= MATCH_DEG and principal:
        turn, turn_ok = f"the axes differ by a quarter turn {axis_text}: another convention", True
    else:
        turn, turn_ok = f"the axes differ by {angle:.2f} deg {axis_text}", False
    return {"accepted": bool(named) and turn_ok, "text": f"{where}; {turn}",
            "distance_mm": float(distance_mm), "angle_deg": float(angle)}


def units_note(causes_by_transform: dict[str, list[str]]) -> str:
    """One sentence when degrees are used as radians in several factors (one mistake), else ''."""
    factors = [f"g{name}" for name, causes in causes_by_transform.items()
               if any(cause.startswith("degrees passed where radians") for cause in causes)]
    if len(factors) < 2:
        return ""
    return (f"Degrees are used as radians in {len(factors)} of 5 factors ({', '.join(factors)}): "
            "one mistake, in the rotation helpers or where the angles go in. Fix: convert "
            "degrees to radians once (np.deg2rad) before cos/sin.")


def diagram_note(causes_by_transform: dict[str, list[str]]) -> str:
    """A summary when the dropped offsets are the course diagram's rounding, else ''."""
    dropped = {(name, index) for name, causes in causes_by_transform.items()
               for index in range(3) for cause in causes
               if name in FIXED_TRANSFORMS and cause.startswith("the ")
               and _offset_name(name, index) in cause and cause.endswith("is missing")}
    tilt = any("mount tilt is missing" in cause for cause in causes_by_transform.get("45", []))
    if len(dropped & DIAGRAM_DROPS) + tilt >= 2:
        return ("These are the course diagram's rounded numbers: it leaves out the 18.3 mm "
                "(g12), 5.2 mm (g34) and 18.1 mm (g45) offsets and the 2.79 deg mount tilt "
                "that the upstream model has.")
    return ""
