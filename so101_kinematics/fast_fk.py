"""The object frame's pose in closed form: the course's product ``gw1 @ ... @ g5t``, fast.

:func:`forward_kinematics` equals ``so101_forward_kinematics.get_forward_kinematics``
(the literal product of the six factors) to about 1e-16 and costs a tenth of it;
:func:`forward_kinematics_batch` does the same for many configurations at once.
The IK, the planners and the benchmarks use these; the derivation is below.
"""

from __future__ import annotations

import math
import numbers
import operator
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from so101_kinematics.errors import KinematicsInputError, KinematicsTypeError
from so101_kinematics.frames import (
    ANGLE_RANGE_DEG,
    ARM_JOINTS,
    FIXED_ROTATION,
    FIXED_TRANSFORMS,
    GRIPPER_MOUNT_TILT_DEG,
    Rx,
    Rz,
    _as_degrees,
    read_angles,
)

__all__ = ["_closed_form_assumptions", "forward_kinematics", "forward_kinematics_batch"]

# ---------------------------------------------------------------------------
# Closed form of g_wt, used by get_forward_kinematics and the batch form.
#
# The product gw1 @ g12 @ g23 @ g34 @ g45 @ g5t simplifies because of two
# facts about the SO-101 (checked below at import, and against MuJoCo and the
# product itself in tests/course_files/test_so101_forward_kinematics.py):
#   1. shoulder_lift, elbow_flex and wrist_flex turn about parallel axes: the
#      fixed rotations of g23 and g34 are Rz(+90) and Rz(-90), so
#      Rz(th2) Rz(90) Rz(th3) Rz(-90) Rz(th4) = Rz(phi), phi = th2 + th3 + th4.
#   2. the other fixed rotations are signed permutations:
#      R_w1 = diag(-1, 1, -1), R_12 = P (rows e_y, e_z, e_x), R_5t = I,
#      and R_45 = D Rz(tilt) with D = Rz(180) Rx(90); the tilt adds to wrist_roll:
#      psi = th5 + GRIPPER_MOUNT_TILT_DEG.
# Then R_wt = diag(-1, 1, -1) Rz(th1) P Rz(phi) D Rz(psi), whose
# entries are the short products written out in get_forward_kinematics, and
#   p_wt = p_w1 + diag(-1, 1, -1) Rz(th1) (p_12 + P r), with
#   r = Rz(th2) p_23 + Rz(th2 + th3 + 90) p_34 + Rz(phi) (p_45 + D Rz(psi) p_5t).
_P_W1, _P_12, _P_23, _P_34, _P_45, _P_5T = (
    tuple(map(float, FIXED_TRANSFORMS[name][0])) for name in ("w1", "12", "23", "34", "45", "5t")
)
_V_X = _P_45[0]                             # p_45 + D Rz(psi) p_5t = (V_X - c5 a + s5 b,
_V_Y = _P_45[1] + _P_5T[2]                  #                          V_Y,
_V_Z = _P_45[2] + _P_12[1] + _P_23[2] + _P_34[2]  # V_Z + s5 a + c5 b), plus p_12,y and r_z
_TOOL_A, _TOOL_B = _P_5T[0], _P_5T[1]       # a, b
_DEG = math.pi / 180.0
_HALF_DEG = math.pi / 360.0
_TILT_DEG = GRIPPER_MOUNT_TILT_DEG


def _closed_form_assumptions() -> None:
    """Fail loudly if ``_FIXED`` no longer has the structure the closed form assumes."""
    flip = np.diag([1.0, -1.0, 1.0]) * -1.0  # diag(-1, 1, -1)
    expected = {
        "w1": flip,
        "12": np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
        "23": Rz(90.0),
        "34": Rz(-90.0),
        "45": Rz(180.0) @ Rx(90.0) @ Rz(_TILT_DEG),
        "5t": np.eye(3),
    }
    for name, rotation in expected.items():
        if not np.allclose(FIXED_ROTATION[name], rotation, rtol=0.0, atol=1e-15):
            raise RuntimeError(
                f"The fixed rotation of g_{name} changed; update the closed form in "
                f"{Path(__file__).name} (get_forward_kinematics and the batch form) to match."
            )


_closed_form_assumptions()


def forward_kinematics(position_dict: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame pose in the world for one configuration.

    Equal (to rounding, ~1e-16) to ``get_gw1 @ get_g12 @ ... @ get_g5t`` as the
    assignment composes it, evaluated in closed form for speed.

    Args:
        position_dict: joint name -> angle [deg]. The five arm joints are
            required; ``gripper`` (and any other key) is ignored.

    Returns:
        ``(position, rotation)``: (3,) position [m] and (3, 3) rotation of the
        object frame in the world (``g_wt``).

    Raises:
        KinematicsInputError: a joint is missing or not a finite number in
            ``ANGLE_RANGE_DEG`` (see :func:`joint_angles`).
    """
    th1, th2, th3, th4, th5 = read_angles(position_dict)
    cos, sin = math.cos, math.sin
    a = th1 * _DEG
    c1, s1 = cos(a), sin(a)
    a = th2 * _DEG
    c2, s2 = cos(a), sin(a)
    a = (th2 + th3) * _DEG
    c23, s23 = cos(a), sin(a)
    a = (th2 + th3 + th4) * _DEG
    cp, sp = cos(a), sin(a)
    a = (th5 + _TILT_DEG) * _DEG
    c5, s5 = cos(a), sin(a)
    v_x = _V_X - c5 * _TOOL_A + s5 * _TOOL_B
    h_1 = _V_Z + s5 * _TOOL_A + c5 * _TOOL_B
    r_x = (c2 * _P_23[0] - s2 * _P_23[1] - s23 * _P_34[0] - c23 * _P_34[1]
           + cp * v_x - sp * _V_Y)
    h_0 = (_P_12[0] + s2 * _P_23[0] + c2 * _P_23[1] + c23 * _P_34[0] - s23 * _P_34[1]
           + sp * v_x + cp * _V_Y)
    spc5, sps5 = sp * c5, sp * s5
    position = np.array((_P_W1[0] - c1 * h_0 + s1 * h_1,
                         _P_W1[1] + s1 * h_0 + c1 * h_1,
                         _P_W1[2] - _P_12[2] - r_x))
    rotation = np.array(((c1 * spc5 + s1 * s5, s1 * c5 - c1 * sps5, -c1 * cp),
                         (c1 * s5 - s1 * spc5, s1 * sps5 + c1 * c5, s1 * cp),
                         (cp * c5, -cp * s5, sp)))
    return position, rotation


def _cos_sin_from_half(half: np.ndarray, cos: np.ndarray, sin: np.ndarray,
                       scratch: np.ndarray) -> None:
    """Cosine and sine of ``2 * half`` [rad], in place, from t = tan(half).

    cos = 2 / (1 + t^2) - 1 and sin = t * 2 / (1 + t^2): one vectorised tan
    (fast in numpy) instead of a sin and a cos (much slower), exact to a few
    1e-16 for every angle (t is at most ~1.6e16 at half = 90 deg).
    """
    np.tan(half, out=sin)
    np.multiply(sin, sin, out=scratch)
    scratch += 1.0
    np.divide(2.0, scratch, out=scratch)
    np.subtract(scratch, 1.0, out=cos)
    sin *= scratch


def _batch_angles(angles_deg) -> np.ndarray:
    """The (N, 5) float array of a batch, checked (see :func:`get_forward_kinematics_batch`)."""
    shape_text = f"an (N, {len(ARM_JOINTS)}) array with columns {', '.join(ARM_JOINTS)}"
    try:
        raw = np.asarray(angles_deg)
    except (TypeError, ValueError):  # ragged nested lists
        raise KinematicsInputError(f"angles_deg must be {shape_text} [deg]; got a ragged or "
                                   f"malformed {type(angles_deg).__name__}.") from None
    if raw.ndim != 2 or raw.shape[1] != len(ARM_JOINTS):
        raise KinematicsInputError(f"angles_deg must be {shape_text}; got shape {raw.shape}.")
    if raw.dtype.kind == "O":
        for (row, col), value in np.ndenumerate(raw):
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
                _as_degrees(f"Joint '{ARM_JOINTS[col]}' of configuration {row}", value)
                raise KinematicsTypeError(  # pragma: no cover - _as_degrees raised
                    f"Joint '{ARM_JOINTS[col]}' of configuration {row} is not a number.")
        try:
            raw = raw.astype(float)
        except OverflowError:
            raise KinematicsInputError("angles_deg holds an integer too large for a float. "
                                       "Fix: give finite angles [deg].") from None
    elif raw.dtype.kind not in "iuf":
        raise KinematicsTypeError(f"angles_deg must hold numbers [deg], got an array of "
                                  f"{raw.dtype} (kind '{raw.dtype.kind}'). Fix: pass floats, "
                                  "e.g. np.asarray(angles, dtype=float) of numbers, not text.")
    theta = np.asarray(raw, dtype=float)
    low, high = ANGLE_RANGE_DEG
    bad = ~((theta >= low) & (theta <= high))  # NaN fails both comparisons
    if bad.any():
        row, col = np.argwhere(bad)[0]
        value = theta[row, col]
        problem = "is not finite" if not math.isfinite(value) else \
            f"= {value:g} deg is outside [{low:g}, {high:g}] deg"
        raise KinematicsInputError(
            f"Joint '{ARM_JOINTS[col]}' of configuration {row} {problem} (the FK takes each "
            "angle within one turn). Fix: give finite angles wrapped into [-180, 180] deg.")
    return theta


def forward_kinematics_batch(angles_deg, chunk: int = 8192) -> tuple[np.ndarray, np.ndarray]:
    """Object-frame poses for many configurations at once.

    The closed form of :func:`get_forward_kinematics`, evaluated on columns of
    ``chunk`` configurations at a time with preallocated buffers.

    Args:
        angles_deg: (N, 5) arm joint angles [deg], columns in ``ARM_JOINTS`` order.
        chunk: configurations processed per block (keeps the work in cache).

    Returns:
        ``(positions, rotations)``: (N, 3) [m] and (N, 3, 3).

    Raises:
        KinematicsInputError: wrong shape, angles that are not finite or outside
            ``ANGLE_RANGE_DEG`` (naming the joint and the row), or chunk < 1;
            :class:`KinematicsTypeError` for text, booleans or other
            non-numbers, and a chunk that is not a whole number.
    """
    theta = _batch_angles(angles_deg)
    if isinstance(chunk, (bool, np.bool_)):
        raise KinematicsTypeError(f"chunk must be a whole number >= 1, got {chunk!r}. "
                                  "Fix: pass an int such as 8192.")
    try:
        chunk = operator.index(chunk)
    except TypeError:
        raise KinematicsTypeError(f"chunk must be a whole number >= 1, got {chunk!r} "
                                  f"({type(chunk).__name__}). Fix: pass an int such as "
                                  "8192.") from None
    if chunk < 1:
        raise KinematicsInputError(f"chunk must be a whole number >= 1, got {chunk!r}. "
                                   "Fix: pass an int such as 8192.")
    n = theta.shape[0]
    positions = np.empty((n, 3))
    rotations = np.empty((n, 3, 3))
    buffers = np.empty((16, min(chunk, n)))
    mul, add, sub, neg = np.multiply, np.add, np.subtract, np.negative
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        th = theta[start:stop]
        p, R = positions[start:stop], rotations[start:stop]
        (c1, s1, c2, s2, c23, s23, cp, sp, c5, s5,
         x, y, z, u, w, tmp) = buffers[:, : stop - start]
        # cos and sin of th1, th2, th2 + th3, phi and psi, from half angles [rad].
        mul(th[:, 0], _HALF_DEG, out=x)
        _cos_sin_from_half(x, c1, s1, tmp)
        mul(th[:, 1], _HALF_DEG, out=y)
        _cos_sin_from_half(y, c2, s2, tmp)
        mul(th[:, 2], _HALF_DEG, out=z)
        z += y
        _cos_sin_from_half(z, c23, s23, tmp)
        mul(th[:, 3], _HALF_DEG, out=x)
        x += z
        _cos_sin_from_half(x, cp, sp, tmp)
        add(th[:, 4], _TILT_DEG, out=x)
        x *= _HALF_DEG
        _cos_sin_from_half(x, c5, s5, tmp)
        # x = v_x, y = h_1 (as in get_forward_kinematics).
        mul(c5, -_TOOL_A, out=x)
        mul(s5, _TOOL_B, out=tmp)
        x += tmp
        x += _V_X
        mul(s5, _TOOL_A, out=y)
        mul(c5, _TOOL_B, out=tmp)
        y += tmp
        y += _V_Z
        # z = r_x, u = h_0.
        mul(cp, x, out=z)
        for column, factor in ((sp, -_V_Y), (c2, _P_23[0]), (s2, -_P_23[1]),
                               (s23, -_P_34[0]), (c23, -_P_34[1])):
            mul(column, factor, out=tmp)
            z += tmp
        mul(sp, x, out=u)
        for column, factor in ((cp, _V_Y), (s2, _P_23[0]), (c2, _P_23[1]),
                               (c23, _P_34[0]), (s23, -_P_34[1])):
            mul(column, factor, out=tmp)
            u += tmp
        u += _P_12[0]
        mul(c1, u, out=tmp)
        mul(s1, y, out=w)
        w -= tmp
        add(w, _P_W1[0], out=p[:, 0])
        mul(s1, u, out=tmp)
        mul(c1, y, out=w)
        w += tmp
        add(w, _P_W1[1], out=p[:, 1])
        sub(_P_W1[2] - _P_12[2], z, out=p[:, 2])
        # Rotation; x = sin(phi) cos(psi), y = sin(phi) sin(psi).
        mul(sp, c5, out=x)
        mul(sp, s5, out=y)
        mul(c1, x, out=tmp)
        mul(s1, s5, out=w)
        add(w, tmp, out=R[:, 0, 0])
        mul(s1, c5, out=tmp)
        mul(c1, y, out=w)
        sub(tmp, w, out=R[:, 0, 1])
        mul(c1, cp, out=tmp)
        neg(tmp, out=R[:, 0, 2])
        mul(s1, x, out=tmp)
        mul(c1, s5, out=w)
        sub(w, tmp, out=R[:, 1, 0])
        mul(s1, y, out=tmp)
        mul(c1, c5, out=w)
        add(tmp, w, out=R[:, 1, 1])
        mul(s1, cp, out=R[:, 1, 2])
        mul(cp, c5, out=R[:, 2, 0])
        mul(cp, s5, out=tmp)
        neg(tmp, out=R[:, 2, 1])
        R[:, 2, 2] = sp
    return positions, rotations
