"""The SO-101 scene in MuJoCo: loading, joint tables, unit conversion, poses and commands.

Units at the user's boundary are the course's: arm joints in [deg], the
gripper in [0, 100]. Inside MuJoCo everything is [rad]. The conversion lives
here and only here (:func:`to_radians`, :func:`from_radians`):

- arm joints: radians = degrees * pi / 180 (zero at the middle of the range,
  as lerobot's SO-101 calibration defines it);
- gripper: 0..100 maps linearly onto the gripper joint's range, 0 at its
  lower (closed) end and 100 at its upper (open) end; the same mapping as
  lerobot's RANGE_0_100 over the calibrated range, so the virtual and the real
  arm agree with the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.frames import GRIPPER_RANGE, JOINTS, TOOL_SITE
from so101_kinematics.motion import Configuration, check_configuration
from so101_kinematics.paths import MODEL_DIR, SCENE_PATH  # noqa: F401 - the scene's files
from so101_kinematics.sim import actuation
from so101_kinematics.sim.meshes import ensure_meshes


def load_model(path: str | Path = SCENE_PATH) -> mujoco.MjModel:
    """Load an SO-101 scene, installing and verifying the meshes first.

    The model's servos are the measured STS3215 at lerobot's settings on the kit's
    supply, with the gravity feed-forward (``actuation.use_servo``'s defaults); call
    ``actuation.use_servo(m, ...)`` to choose another.

    Args:
        path: MJCF file (default ``model/scene.xml``).

    Returns:
        The compiled model.
    """
    ensure_meshes()
    m = mujoco.MjModel.from_xml_path(str(path))
    actuation.use_servo(m)
    return m


@lru_cache(maxsize=8)
def joint_table(m: mujoco.MjModel) -> tuple[tuple[str, int, int, float, float], ...]:
    """(name, qpos address, actuator id, lower, upper [rad]) for each joint."""
    return tuple(
        (name, int(m.joint(name).qposadr[0]), int(m.actuator(name).id),
         *map(float, m.joint(name).range))
        for name in JOINTS
    )


def joint_limits(m: mujoco.MjModel) -> dict[str, tuple[float, float]]:
    """Joint limits in user units: [deg] for the arm, (0, 100) for the gripper."""
    limits = {}
    for name, _, _, lower, upper in joint_table(m):
        if name == "gripper":
            limits[name] = GRIPPER_RANGE
        else:
            limits[name] = (math.degrees(lower), math.degrees(upper))
    return limits


def gripper_to_radians(m: mujoco.MjModel, percent: float) -> float:
    """Gripper opening in [0, 100] -> gripper joint angle [rad]."""
    lower, upper = m.joint("gripper").range
    return float(lower + (upper - lower) * percent / 100.0)


def gripper_from_radians(m: mujoco.MjModel, angle: float) -> float:
    """Gripper joint angle [rad] -> opening in [0, 100] (not clamped)."""
    lower, upper = m.joint("gripper").range
    return float((angle - lower) / (upper - lower) * 100.0)


def to_radians(m: mujoco.MjModel, cfg: Mapping[str, float]) -> dict[str, float]:
    """User configuration ([deg], gripper [0, 100]) -> joint angles [rad]."""
    return {
        name: gripper_to_radians(m, value) if name == "gripper" else math.radians(value)
        for name, value in cfg.items()
    }


def from_radians(m: mujoco.MjModel, angles: Mapping[str, float]) -> Configuration:
    """Joint angles [rad] -> user configuration ([deg], gripper [0, 100])."""
    return {
        name: gripper_from_radians(m, value) if name == "gripper" else math.degrees(value)
        for name, value in angles.items()
    }


def validate(m: mujoco.MjModel, cfg: Mapping[str, float], where: str = "") -> Configuration:
    """Check a full configuration against the model's joint limits.

    Raises:
        JointLimitError: naming joint, value and limit.
        PlanError: missing, unknown or non-numeric joints.
    """
    return check_configuration(cfg, joint_limits(m), where)


def get_configuration(m: mujoco.MjModel, d: mujoco.MjData) -> Configuration:
    """Measured configuration (from ``d.qpos``) in user units."""
    return from_radians(m, {name: float(d.qpos[adr]) for name, adr, *_ in joint_table(m)})


def get_command(m: mujoco.MjModel, d: mujoco.MjData) -> Configuration:
    """Currently commanded configuration (from ``d.ctrl``) in user units."""
    return from_radians(m, {name: float(d.ctrl[act]) for name, _, act, *_ in joint_table(m)})


def set_initial_pose(d: mujoco.MjData, cfg: Mapping[str, float]) -> None:
    """Place the arm at ``cfg`` at rest (qpos, zero velocity) and command it there.

    Args:
        d: the simulation data (its model is ``d.model``).
        cfg: configuration ([deg], gripper [0, 100]); validated against the limits.
    """
    m = d.model
    angles = to_radians(m, validate(m, cfg, "initial pose"))
    for name, adr, act, *_ in joint_table(m):
        d.qpos[adr] = angles[name]
        d.qvel[m.joint(name).dofadr[0]] = 0.0
        d.ctrl[act] = angles[name]
    actuation.forget(d)  # the servos' targets restart where the arm now is
    mujoco.mj_forward(m, d)


def send_position_command(d: mujoco.MjData, cfg: Mapping[str, float]) -> None:
    """Set the position servos' targets; joints missing from ``cfg`` keep theirs.

    Args:
        d: the simulation data.
        cfg: joint name -> target ([deg], gripper [0, 100]).
    """
    m = d.model
    limits = joint_limits(m)
    partial = {name: limits[name] for name in cfg if name in limits}
    angles = to_radians(m, check_configuration(cfg, partial, "position command"))
    for name, _, act, *_ in joint_table(m):
        if name in angles:
            d.ctrl[act] = angles[name]


def get_object_pose(m: mujoco.MjModel, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Simulated object-frame pose (position (3,) [m], rotation (3, 3)) from the last kinematics."""
    site = d.site(TOOL_SITE)
    return site.xpos.copy(), site.xmat.reshape(3, 3).copy()
