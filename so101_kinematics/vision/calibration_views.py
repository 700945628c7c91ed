"""Calibration in the simulator: the views a student would take, rendered, solved and graded.

The simulator plays the student with a printed board (``boards.py``) and a webcam:

- **intrinsics**: the board held in front of each camera, tilted 15 to 40 deg a different way
  each time, 22 to 38 cm away (:func:`board_views`); ``charuco.calibrate_intrinsics``;
- **the wrist camera** (eye in hand): the board lies on the table at
  :data:`TABLE_BOARD_AT`; the arm is posed N times so that the wrist camera sees it from
  different sides (:func:`wrist_views`); the gripper's pose from the course's FK of the joint
  angles (``frames.get_frame_chain``'s frame 5, the ``gripper`` body);
  ``hand_eye.solve_hand_eye``;
- **the overhead camera** (eye to hand): the board is held in the jaws by its top edge
  (:data:`G_GRIPPER_BOARD`), the arm posed N times with the board facing the camera
  (:func:`held_views`); ``hand_eye.solve_eye_to_hand``.

The arm's poses are set directly (``qpos``): what the student does by hand, torque off. The
simulator's truth chooses the poses (the board in view, as a student checks on the screen)
and grades the results; the calibrations themselves see only the images and the joint
angles. Each image is rendered by ``SimCamera`` with the webcam's blur and noise (seeded).
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from so101_kinematics import model_facts
from so101_kinematics.errors import VisionError
from so101_kinematics.frames import (
    ARM_JOINTS,
    BODY_OF_FRAME,
    JOINT_LIMITS,
    TOOL_SITE,
    get_frame_chain,
)
from so101_kinematics.vision.boards import (
    CALIBRATION_BOARD,
    G_BODY_BOARD,
    add_board,
    charuco_board,
    set_board_pose,
)
from so101_kinematics.vision.camera_model import BASE_BODY, get_camera_pose_base, project_points
from so101_kinematics.vision.charuco import BoardSighting, find_board
from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec

__all__ = [
    "GRIPPER_BODY", "G_GRIPPER_BOARD", "TABLE_BOARD_AT", "ViewSampler", "WRIST_VIEW_RANGES",
    "board_views", "calibration_model", "gripper_pose", "held_views", "set_arm",
    "table_board_pose", "take_view", "wrist_views",
]

TABLE_BOARD_AT = (0.24, 0.0)
"""(x, y) [m] of the board's centre lying on the table, in the base frame: its long side
along x, in front of the arm (the wrist camera's calibration)."""


def _gripper_board() -> np.ndarray:
    """The board's frame in the gripper frame: held in the jaws by its top edge, hanging on."""
    g_g_body = np.eye(4)
    g_g_body[:3, :3] = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]  # face towards +x
    held = model_facts.site_position(TOOL_SITE)  # a held cube's centre, between the jaw pads
    top = held[2] - 0.0025  # [m] the board's top edge, just below it
    g_g_body[:3, 3] = (held[0] + CALIBRATION_BOARD.thickness / 2, 0.0,
                       top - CALIBRATION_BOARD.face[1] / 2)
    return g_g_body @ G_BODY_BOARD


G_GRIPPER_BOARD = _gripper_board()
"""The board frame in the gripper frame (4x4) [m] when the arm holds it (the eye-to-hand views):
its top edge in the jaws, its printed face towards the moving jaw (the gripper's +x)."""

GRIPPER_BODY = BODY_OF_FRAME["5"]
"""The model's body of the FK's frame 5, the gripper: the wrist camera's mount."""


def table_board_pose() -> np.ndarray:
    """``g_b_board`` of the board lying face up on the table at :data:`TABLE_BOARD_AT`.

    Its rows run along the base's +x (the top of the board towards the arm), its face up:
    the board frame's x is the base's +y, y the base's +x, z (into the board) down.
    """
    g = np.eye(4)
    g[:3, :3] = [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]
    width, height = CALIBRATION_BOARD.size
    centre = np.array([*TABLE_BOARD_AT, CALIBRATION_BOARD.thickness])
    g[:3, 3] = centre - g[:3, :3] @ np.array([width / 2, height / 2, 0.0])
    return g


def calibration_model() -> mujoco.MjModel:
    """The course's scene with the board (a mocap body, out of sight until posed)."""
    spec = tagged_spec()
    add_board(spec)
    return build_tagged_model(spec=spec)


def set_arm(m: mujoco.MjModel, d: mujoco.MjData, angles_deg) -> None:
    """Pose the arm's five joints [deg] (the gripper as it is) and update the kinematics."""
    for joint, angle in zip(ARM_JOINTS, angles_deg, strict=True):
        d.qpos[m.joint(joint).qposadr[0]] = np.radians(angle)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_camlight(m, d)


def gripper_pose(angles_deg) -> np.ndarray:
    """``g_b_g``: the gripper frame (frame 5) in the base frame, from the course's FK [m]."""
    return get_frame_chain(dict(zip(ARM_JOINTS, (float(a) for a in angles_deg),
                                    strict=True)))["5"]


def _inner_corners_base(g_b_board: np.ndarray) -> np.ndarray:
    corners = np.asarray(charuco_board(CALIBRATION_BOARD).getChessboardCorners(), dtype=float)
    return corners @ g_b_board[:3, :3].T + g_b_board[:3, 3]


def _shows_board(K, g_bc, size, g_b_board, fraction: float = 0.9, margin: float = 15.0,
                 max_tilt_deg: float = 45.0) -> bool:
    """The board faces the camera within ``max_tilt_deg`` and most of its corners are in view."""
    uv = project_points(K, g_bc, _inner_corners_base(g_b_board))
    inside = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] > margin) & (uv[:, 1] > margin) & \
        (uv[:, 0] < size[0] - margin) & (uv[:, 1] < size[1] - margin)
    facing = float(g_bc[:3, 2] @ g_b_board[:3, 2])  # both z: the camera's forward, into the board
    return bool(np.mean(inside) >= fraction and facing >= np.cos(np.radians(max_tilt_deg)))


def _above_table(g_b_board: np.ndarray, clearance: float = 0.01) -> bool:
    width, height = CALIBRATION_BOARD.face
    margin = CALIBRATION_BOARD.margin
    corners = np.array([[x, y, 0.0] for x in (-margin, width - margin)
                        for y in (-margin, height - margin)])
    return bool(np.all((corners @ g_b_board[:3, :3].T + g_b_board[:3, 3])[:, 2] > clearance))


def _turned(rotation: np.ndarray, taken: list[np.ndarray], min_deg: float) -> bool:
    """``rotation`` differs from every one already taken by at least ``min_deg``."""
    cos_min = np.cos(np.radians(min_deg))
    return all((np.trace(r.T @ rotation) - 1.0) / 2.0 < cos_min for r in taken)


ViewSampler = Callable[[np.random.Generator], object]
"""Draws one candidate view (its arm angles or its board pose), or None to draw again."""


def _draw(rng: np.random.Generator, n: int, sampler: ViewSampler, what: str,
          tries: int = 20000) -> list:
    found = []
    for _ in range(tries):
        if len(found) == n:
            return found
        view = sampler(rng)
        if view is not None:
            found.append(view)
    raise VisionError(f"Only {len(found)} of {n} {what} were found in {tries} draws. Fix: ask "
                      "for fewer views.")


def board_views(rng: np.random.Generator, n: int, g_bc: np.ndarray, K: np.ndarray,
                size) -> list[np.ndarray]:
    """``n`` board poses in the base frame, each tilted a different way in front of the camera."""
    width, height = CALIBRATION_BOARD.size

    def sample(rng):
        distance = rng.uniform(0.22, 0.38)
        pixel = rng.uniform([0.3 * size[0], 0.3 * size[1]], [0.7 * size[0], 0.7 * size[1]])
        centre = distance * np.array([(pixel[0] - K[0, 2]) / K[0, 0],
                                      (pixel[1] - K[1, 2]) / K[1, 1], 1.0])
        axis_angle = rng.uniform(0.0, 2 * np.pi)
        tilt = np.radians(rng.uniform(15.0, 40.0)) * np.array(
            [np.cos(axis_angle), np.sin(axis_angle), 0.0])
        roll = np.radians(rng.uniform(-30.0, 30.0)) * np.array([0.0, 0.0, 1.0])
        rotation = _rotation(roll) @ _rotation(tilt)
        g_c_board = np.eye(4)
        g_c_board[:3, :3] = rotation
        g_c_board[:3, 3] = centre - rotation @ np.array([width / 2, height / 2, 0.0])
        g_b_board = g_bc @ g_c_board
        ok = _shows_board(K, g_bc, size, g_b_board, fraction=1.0, max_tilt_deg=60.0) and \
            _above_table(g_b_board)
        return g_b_board if ok else None

    return _draw(rng, n, sample, "board poses in view")


def _rotation(rotation_vector: np.ndarray) -> np.ndarray:
    matrix = np.empty(9)
    angle = float(np.linalg.norm(rotation_vector))
    quaternion = np.empty(4)
    mujoco.mju_axisAngle2Quat(quaternion, rotation_vector / angle if angle else [0, 0, 1], angle)
    mujoco.mju_quat2Mat(matrix, quaternion)
    return matrix.reshape(3, 3)


WRIST_VIEW_RANGES = {"shoulder_pan": (-25.0, 25.0), "shoulder_lift": (-100.0, 10.0),
                     "elbow_flex": (-20.0, 70.0), "wrist_flex": (55.0, 100.0),
                     "wrist_roll": (-160.0, 160.0)}
"""Joint ranges [deg] where the wrist camera looks down at the table in front of the arm."""


def _random_angles(rng: np.random.Generator, ranges=None) -> np.ndarray:
    """Joint angles [deg] drawn within ``ranges`` (each within the joint's limits)."""
    ranges = ranges or JOINT_LIMITS
    return np.array([rng.uniform(max(ranges[j][0], JOINT_LIMITS[j][0]),
                                 min(ranges[j][1], JOINT_LIMITS[j][1])) for j in ARM_JOINTS])


def _roll_towards(angles: np.ndarray, towards: np.ndarray, rng: np.random.Generator,
                  spread_deg: float = 25.0) -> np.ndarray:
    """``angles`` with the wrist roll that turns the gripper's +x towards the point ``towards``.

    The roll turns the gripper frame about its own z: ``g_b_g(roll) = g_b_g(0) @ Rz(roll)``,
    so ``x . u = cos(roll) (x0 . u) + sin(roll) (y0 . u)`` is largest at
    ``atan2(y0 . u, x0 . u)``; then turned by up to ``spread_deg`` either way.
    """
    angles = angles.copy()
    angles[4] = 0.0
    g = gripper_pose(angles)
    u = towards - g[:3, 3]
    best = np.degrees(np.arctan2(g[:3, 1] @ u, g[:3, 0] @ u))
    angles[4] = np.clip(best + rng.uniform(-spread_deg, spread_deg), *JOINT_LIMITS["wrist_roll"])
    return angles


def wrist_views(m, d, rng: np.random.Generator, n: int, g_b_board: np.ndarray, K: np.ndarray,
                size, min_turn_deg: float = 10.0) -> list[np.ndarray]:
    """``n`` arm poses [deg] from which the wrist camera sees the board on the table."""
    taken: list[np.ndarray] = []

    def sample(rng):
        angles = _random_angles(rng, WRIST_VIEW_RANGES)
        set_arm(m, d, angles)
        g_bc = get_camera_pose_base(m, d, "wrist")
        if d.site(TOOL_SITE).xpos[2] < 0.04 or not (0.15 < np.linalg.norm(
                g_bc[:3, 3] - g_b_board[:3, 3]) < 0.45):
            return None
        rotation = np.array(d.body(GRIPPER_BODY).xmat).reshape(3, 3)  # a copy
        if not (_shows_board(K, g_bc, size, g_b_board, fraction=0.6, margin=0.0,
                             max_tilt_deg=50.0) and _turned(rotation, taken,
                                                                  min_turn_deg)):
            return None
        taken.append(rotation)
        return angles

    return _draw(rng, n, sample, "wrist-camera poses seeing the board")


def held_views(m, d, rng: np.random.Generator, n: int, K: np.ndarray, size,
               camera: str = "overhead", min_turn_deg: float = 10.0) -> list[np.ndarray]:
    """``n`` arm poses [deg] holding the board (``G_GRIPPER_BOARD``) in the camera's view."""
    taken: list[np.ndarray] = []
    g_bc = get_camera_pose_base(m, d, camera)

    def sample(rng):
        angles = _roll_towards(_random_angles(rng), g_bc[:3, 3], rng)
        g_b_board = gripper_pose(angles) @ G_GRIPPER_BOARD
        if not (_above_table(g_b_board, 0.02) and _shows_board(K, g_bc, size, g_b_board,
                                                               max_tilt_deg=40.0)):
            return None
        if not _turned(g_b_board[:3, :3], taken, min_turn_deg):
            return None
        taken.append(g_b_board[:3, :3])
        return angles

    return _draw(rng, n, sample, f"arm poses holding the board in the {camera} camera's view")


def take_view(m, d, camera, angles_deg, g_b_board: np.ndarray | None) -> BoardSighting | None:
    """Pose the arm and the board, render ``camera`` (a ``SimCamera``), find the board.

    ``g_b_board`` None: the board is held in the jaws (``G_GRIPPER_BOARD`` on the model's
    gripper body, where the simulator has it).
    """
    set_arm(m, d, angles_deg)
    if g_b_board is None:
        g_w_base = np.eye(4)
        g_w_base[:3, :3] = np.asarray(d.body(BASE_BODY).xmat).reshape(3, 3)
        g_w_base[:3, 3] = d.body(BASE_BODY).xpos
        g_w_gripper = np.eye(4)
        g_w_gripper[:3, :3] = np.asarray(d.body(GRIPPER_BODY).xmat).reshape(3, 3)
        g_w_gripper[:3, 3] = d.body(GRIPPER_BODY).xpos
        g_b_board = np.linalg.inv(g_w_base) @ g_w_gripper @ G_GRIPPER_BOARD
    set_board_pose(m, d, g_b_board)
    mujoco.mj_forward(m, d)
    return find_board(camera.read())
