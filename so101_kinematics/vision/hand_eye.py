"""Hand-eye calibration: a camera's pose on the gripper, or in the base frame, from board views.

Both forms solve ``A X = X B`` with ``cv2.calibrateHandEye``, from N poses of the arm (the
gripper's pose ``g_b_g`` from the FK of the joint angles read) and the board's pose in the
camera at each (``g_c_board``, ``charuco.board_pose``):

- **eye in hand** (the wrist camera; the board fixed on the table): the board's pose in the
  base, ``g_b_g @ X @ g_c_board``, is the same in every view; ``X = g_g_c``, the camera in
  the gripper frame (:func:`solve_hand_eye`);
- **eye to hand** (the fixed camera; the board held in the gripper): the board's pose in the
  gripper, ``inv(g_b_g) @ Y @ g_c_board``, is the same in every view; the same solver given
  the *inverted* gripper poses returns ``Y = g_b_c``, the camera in the base frame
  (:func:`solve_eye_to_hand`).

What stays the same is the residual: the spread of that constant pose over the views (RMS
of its positions about their mean [mm], of its rotations from their mean [deg]), which a real
calibration can report without any truth. OpenCV's five methods (Tsai, Park, Horaud,
Andreff, Daniilidis), where this OpenCV has ``calibrateHandEye`` (OpenCV 5.0's Python module
does not), and Park and Martin's method in numpy are each tried; the one with the smallest
spread is kept.

Then :func:`refine_on_corners` (Levenberg-Marquardt, numpy only) moves the camera's pose and
the board's constant pose together to make every corner of every view land where it was
seen: the board's far-away depth, which one view's ``solvePnP`` measures worst, is then
pinned by all the views at once (bundle adjustment of the two unknowns, the FK's gripper
poses taken as exact).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from so101_kinematics.errors import VisionError
from so101_kinematics.opencv_import import require_opencv

__all__ = ["HandEye", "MIN_HAND_EYE_VIEWS", "pose_error", "refine_on_corners", "solve_eye_to_hand",
           "solve_hand_eye"]

MIN_HAND_EYE_VIEWS = 3
"""``cv2.calibrateHandEye`` needs at least three poses (two motions about different axes)."""
METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")
"""OpenCV's hand-eye methods (``cv2.CALIB_HAND_EYE_<name>``)."""


@dataclass(frozen=True)
class HandEye:
    """A hand-eye result.

    Attributes:
        pose: 4x4 [m]: ``g_g_c`` (eye in hand) or ``g_b_c`` (eye to hand).
        spread_mm: RMS distance of the constant pose's positions from their mean [mm].
        spread_deg: RMS angle of its rotations from their mean [deg].
        method: the OpenCV method kept (with ``+corners`` once :func:`refine_on_corners` ran).
        views: the poses used.
        rms_px: RMS reprojection error of every board corner through the chain (after
            :func:`refine_on_corners`; None before).
    """

    pose: np.ndarray
    spread_mm: float
    spread_deg: float
    method: str
    views: int
    rms_px: float | None = None


def pose_error(g: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Position [mm] and rotation [deg] between two 4x4 poses."""
    relative = np.asarray(g)[:3, :3].T @ np.asarray(truth)[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(relative) - 1.0) / 2.0, -1.0, 1.0)))
    return float(np.linalg.norm(np.asarray(g)[:3, 3] - np.asarray(truth)[:3, 3]) * 1000.0), \
        float(angle)


def _mean_rotation(rotations: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(rotations.sum(axis=0))
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def _spread(poses: Sequence[np.ndarray]) -> tuple[float, float]:
    poses = np.asarray(poses)
    positions = poses[:, :3, 3]
    mean = np.eye(4)
    mean[:3, :3] = _mean_rotation(poses[:, :3, :3])
    mean[:3, 3] = positions.mean(axis=0)
    errors = np.array([pose_error(g, mean) for g in poses])
    return tuple(float(np.sqrt(np.mean(errors[:, i] ** 2))) for i in (0, 1))


def _opencv_candidates(a, b) -> dict[str, np.ndarray]:
    """``cv2.calibrateHandEye``'s ``X`` by each method (none where this OpenCV lacks it)."""
    cv2 = require_opencv()
    if not hasattr(cv2, "calibrateHandEye"):  # OpenCV 5.0's Python has the constants only
        return {}
    arguments = ([np.asarray(g)[:3, :3] for g in a], [np.asarray(g)[:3, 3] for g in a],
                 [np.asarray(g)[:3, :3] for g in b], [np.asarray(g)[:3, 3] for g in b])
    found = {}
    for method in METHODS:
        rotation, translation = cv2.calibrateHandEye(
            *arguments, method=getattr(cv2, f"CALIB_HAND_EYE_{method}"))
        x = np.eye(4)
        x[:3, :3] = rotation
        x[:3, 3] = np.asarray(translation).ravel()
        found[method.lower()] = x
    return found


def _procrustes(a, b) -> np.ndarray:
    """``X`` of ``a_i X b_i = const`` by Park and Martin's method, in numpy.

    Every pair of views gives a motion ``A X = X B`` (``A = inv(a_j) a_i``,
    ``B = b_j inv(b_i)``); the rotations' axes turn as ``alpha = R_X beta``, solved as an
    orthogonal Procrustes problem (Park and Martin, IEEE Trans. Robotics and Automation
    10(5), 1994, with an SVD for their inverse square root); then
    ``(R_A - I) t_X = R_X t_B - t_A`` by least squares.
    """
    cv2 = require_opencv()
    motions = [(np.linalg.inv(a[j]) @ a[i], b[j] @ np.linalg.inv(b[i]))
               for i in range(len(a)) for j in range(i + 1, len(a))]
    alpha = np.array([cv2.Rodrigues(m_a[:3, :3])[0].ravel() for m_a, _ in motions])
    beta = np.array([cv2.Rodrigues(m_b[:3, :3])[0].ravel() for _, m_b in motions])
    u, _, vt = np.linalg.svd(alpha.T @ beta)
    rotation = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    lhs = np.vstack([m_a[:3, :3] - np.eye(3) for m_a, _ in motions])
    rhs = np.concatenate([rotation @ m_b[:3, 3] - m_a[:3, 3] for m_a, m_b in motions])
    x = np.eye(4)
    x[:3, :3] = rotation
    x[:3, 3] = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return x


def _solve(a: Sequence[np.ndarray], b: Sequence[np.ndarray], what: str) -> HandEye:
    """Each method's ``X`` of ``a_i X b_i = const``; the one whose constant spreads least."""
    if len(a) != len(b) or len(a) < MIN_HAND_EYE_VIEWS:
        raise VisionError(f"{what} needs at least {MIN_HAND_EYE_VIEWS} arm poses, each with the "
                          f"board seen; got {min(len(a), len(b))}. Fix: pose the arm more times, "
                          "turning the gripper about different axes.")
    a = [np.asarray(g, dtype=float) for g in a]
    b = [np.asarray(g, dtype=float) for g in b]
    candidates = {**_opencv_candidates(a, b), "park-procrustes": _procrustes(a, b)}
    best = None
    for method, x in candidates.items():
        if not np.all(np.isfinite(x)):
            continue
        spread_mm, spread_deg = _spread([ga @ x @ gb for ga, gb in zip(a, b, strict=True)])
        if best is None or spread_mm < best.spread_mm:
            best = HandEye(x, spread_mm, spread_deg, method, len(a))
    if best is None:
        raise VisionError(f"{what}: no hand-eye method found a pose. Fix: pose the arm with "
                          "larger turns of the gripper between views.")
    return best


def solve_hand_eye(g_b_gripper: Sequence[np.ndarray],
                   g_c_board: Sequence[np.ndarray]) -> HandEye:
    """Eye in hand: ``g_g_c``, the camera (OpenCV axes) in the gripper frame.

    Args:
        g_b_gripper: the gripper's pose in the base frame at each view (the FK's) [m].
        g_c_board: the board's pose in the camera at each view (fixed board) [m].
    """
    return _solve(g_b_gripper, g_c_board, "Hand-eye calibration")


def solve_eye_to_hand(g_b_gripper: Sequence[np.ndarray],
                      g_c_board: Sequence[np.ndarray]) -> HandEye:
    """Eye to hand: ``g_b_c``, the fixed camera (OpenCV axes) in the base frame.

    Args:
        g_b_gripper: the gripper's pose in the base frame at each view [m].
        g_c_board: the pose of the board held in the gripper, in the camera, at each view [m].
    """
    return _solve([np.linalg.inv(g) for g in g_b_gripper], g_c_board,
                  "Eye-to-hand calibration")


def _exp(twist: np.ndarray) -> np.ndarray:
    """A small motion's pose: rotation vector ``twist[:3]`` [rad], translation ``twist[3:]`` [m]."""
    cv2 = require_opencv()
    g = np.eye(4)
    g[:3, :3] = cv2.Rodrigues(np.asarray(twist[:3], dtype=float))[0]
    g[:3, 3] = twist[3:]
    return g


def _reprojection(p: np.ndarray, q: np.ndarray, chain, views, K, dist) -> np.ndarray:
    """Every corner's pixel error when the board is at ``inv(p) @ chain_i @ q`` in the camera."""
    cv2 = require_opencv()
    errors = []
    for m_i, (object_points, corners) in zip(chain, views, strict=True):
        g = np.linalg.inv(p) @ m_i @ q
        rvec = cv2.Rodrigues(g[:3, :3])[0]
        projected = cv2.projectPoints(object_points, rvec, g[:3, 3], K, dist)[0].reshape(-1, 2)
        errors.append((projected - corners).ravel())
    return np.concatenate(errors)


def refine_on_corners(result: HandEye, g_b_gripper: Sequence[np.ndarray],
                      g_c_board: Sequence[np.ndarray], views, K: np.ndarray, dist=None, *,
                      eye_in_hand: bool, iterations: int = 30) -> HandEye:
    """``result`` refined on the board's corners (Levenberg-Marquardt, numeric Jacobian).

    Args:
        result: :func:`solve_hand_eye`'s or :func:`solve_eye_to_hand`'s.
        g_b_gripper: the gripper's poses (as given to the solver) [m].
        g_c_board: the board's poses in the camera (as given to the solver) [m].
        views: per pose, (N x 3 board points [m], N x 2 pixels [px]) of the corners seen.
        K: the camera matrix [px].
        dist: its distortion coefficients (None: none).
        eye_in_hand: the wrist form (board fixed in the base) or the fixed camera's (board in
            the gripper).
        iterations: at most this many steps.

    Returns:
        The refined result (its spread recomputed, ``rms_px`` set).
    """
    K = np.asarray(K, dtype=float)
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float)
    chain = [np.linalg.inv(g) if eye_in_hand else np.asarray(g) for g in g_b_gripper]
    p = result.pose
    constants = [np.linalg.inv(m_i) @ p @ g for m_i, g in zip(chain, g_c_board, strict=True)]
    q = np.eye(4)
    q[:3, :3] = _mean_rotation(np.asarray(constants)[:, :3, :3])
    q[:3, 3] = np.mean(np.asarray(constants)[:, :3, 3], axis=0)
    residual = _reprojection(p, q, chain, views, K, dist)
    damping, step = 1e-3, 1e-7
    for _ in range(iterations):
        jacobian = np.empty((len(residual), 12))
        for k in range(12):
            delta = np.zeros(12)
            delta[k] = step
            jacobian[:, k] = (_reprojection(p @ _exp(delta[:6]), q @ _exp(delta[6:]), chain,
                                            views, K, dist) - residual) / step
        normal = jacobian.T @ jacobian
        gradient = jacobian.T @ residual
        update = -np.linalg.solve(normal + damping * np.diag(np.diag(normal)), gradient)
        p_new, q_new = p @ _exp(update[:6]), q @ _exp(update[6:])
        trial = _reprojection(p_new, q_new, chain, views, K, dist)
        cost, trial_cost = residual @ residual, trial @ trial
        if trial_cost < cost:
            p, q, residual, damping = p_new, q_new, trial, damping / 3.0
            if cost - trial_cost < 1e-6 * cost:  # converged: the last step gained nothing
                break
        else:
            damping *= 5.0
    spread_mm, spread_deg = _spread([np.linalg.inv(m_i) @ p @ g
                                     for m_i, g in zip(chain, g_c_board, strict=True)])
    rms = float(np.sqrt(np.mean(residual.reshape(-1, 2) ** 2) * 2.0))
    return HandEye(p, spread_mm, spread_deg, f"{result.method}+corners", result.views, rms)
