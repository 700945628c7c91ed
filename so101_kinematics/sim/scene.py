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

import logging
import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.errors import PlanError
from so101_kinematics.frames import GRIPPER_RANGE, JOINT_RANGES_RAD, JOINTS, TOOL_SITE
from so101_kinematics.inputs import (
    LIMIT_TOLERANCE,
    Configuration,
    check_configuration,
    describe_value,
    format_limit,
    limit_excess,
    unit,
)
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sim import actuation
from so101_kinematics.sim.meshes import ensure_meshes

__all__ = [
    "convert_to_dictionary", "convert_to_list", "from_radians", "get_command",
    "get_configuration", "get_object_pose", "gripper_from_radians", "gripper_to_radians",
    "held_at_limits", "joint_limits", "joint_table", "load_model", "send_position_command",
    "send_velocity_command", "set_initial_pose", "to_radians", "validate",
]

logger = logging.getLogger(__name__)


def load_model(path: str | Path = SCENE_PATH) -> mujoco.MjModel:
    """Load an SO-101 scene, installing and verifying the meshes first.

    The model's servos are the measured STS3215 at lerobot's settings on the kit's
    supply, with the gravity feed-forward (``actuation.use_servo``'s defaults); call
    ``actuation.use_servo(m, ...)`` to choose another. A velocity model
    (``model/scene_with_velocity.xml``: 12 actuators) keeps its own, the course's.

    Args:
        path: MJCF file (default ``model/scene.xml``).

    Returns:
        The compiled model.
    """
    ensure_meshes()
    m = mujoco.MjModel.from_xml_path(str(path))
    if actuation.has_velocity_actuators(m):
        logger.info("%s has velocity actuators: it runs on the course's own gains, not the "
                    "STS3215 model.", Path(path).name)
        return m
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


def convert_to_dictionary(qpos) -> Configuration:
    """The course's helper: joint angles [rad] in ``qpos`` order -> a configuration.

    ``qpos``'s first six entries are the joints in ``JOINTS`` order (in every
    scene of this project the arm comes first; cubes' free joints follow, and
    are left out). Arm joints become [deg]; the gripper becomes [0, 100] by
    the same mapping as :func:`gripper_from_radians` (linear over the
    gripper's range, lerobot's RANGE_0_100), not the course's ``value * 100 /
    pi``: so ``convert_to_dictionary(d.qpos)`` is :func:`get_configuration`,
    and passing it to ``move_to_pose`` or ``set_initial_pose`` puts the
    gripper where it is (with the course's mapping a gripper at 0 rad would
    read 0, and go back to its fully closed -10 deg).

    Raises:
        PlanError: fewer than six angles, or an angle that is not a finite number.

    Example:
        >>> cfg = convert_to_dictionary([0.0, -1.75, 0.0, 0.0, 0.0, -0.17453297762778586])
        >>> round(cfg["shoulder_lift"], 3), cfg["gripper"]
        (-100.268, 0.0)
    """
    try:
        angles = [qpos[i] for i in range(len(JOINTS))]
    except (TypeError, IndexError, KeyError):
        raise PlanError(f"convert_to_dictionary takes the six joint angles [rad] (d.qpos), got "
                        f"{describe_value(qpos)}. Fix: pass d.qpos.") from None
    angles = check_configuration(dict(zip(JOINTS, angles, strict=True)),
                                 dict.fromkeys(JOINTS, (-math.inf, math.inf)),
                                 "convert_to_dictionary")
    lower, upper = JOINT_RANGES_RAD["gripper"]
    out = {joint: math.degrees(angle) for joint, angle in angles.items()}
    out["gripper"] = (angles["gripper"] - lower) / (upper - lower) * 100.0
    return out


def convert_to_list(cfg: Mapping[str, float]) -> list[float]:
    """The course's helper: a configuration -> joint angles [rad] in ``JOINTS`` (qpos, ctrl) order.

    The inverse of :func:`convert_to_dictionary` (the gripper's [0, 100]
    linear over its range): ``d.ctrl[:] = convert_to_list(cfg)`` commands what
    ``send_position_command(d, cfg)`` does. No limits are applied here.

    Raises:
        PlanError: a joint missing or unknown, a value that is not a finite number.

    Example:
        >>> [round(angle, 4) for angle in convert_to_list(
        ...     {"shoulder_pan": 90.0, "shoulder_lift": 0.0, "elbow_flex": 0.0,
        ...      "wrist_flex": 0.0, "wrist_roll": 0.0, "gripper": 100.0})]
        [1.5708, 0.0, 0.0, 0.0, 0.0, 1.7453]
    """
    if not isinstance(cfg, Mapping):
        raise PlanError(f"convert_to_list takes a configuration dict joint name -> value, got "
                        f"{describe_value(cfg)}. Fix: e.g. {{'shoulder_pan': 0.0, ...}}.")
    values = check_configuration(cfg, dict.fromkeys(JOINTS, (-math.inf, math.inf)),
                                 "convert_to_list")
    lower, upper = JOINT_RANGES_RAD["gripper"]
    return [lower + (upper - lower) * value / 100.0 if joint == "gripper" else
            math.radians(value) for joint, value in values.items()]


def validate(m: mujoco.MjModel, cfg: Mapping[str, float], where: str = "") -> Configuration:
    """Check a full configuration against the model's joint limits.

    Raises:
        JointLimitError: naming joint, value and limit.
        PlanError: missing, unknown or non-numeric joints.
    """
    return check_configuration(cfg, joint_limits(m), where)


def held_at_limits(m: mujoco.MjModel, cfg: Mapping[str, float], where: str,
                   partial: bool = False) -> Configuration:
    """A configuration with each joint beyond the model's range held at its limit, with a warning.

    The course's leniency in simulation: its utils write ``qpos`` and ``ctrl``
    as given and MuJoCo holds a joint at its range (``ctrlrange`` clamps the
    command, the joint limit stops the joint), so a pose copied from the
    viewer (-1.75 rad is -100.27 deg, beyond -100) runs. Here it runs too,
    with one warning line naming each joint held, its value and its limit.
    The real arm refuses such a pose (``hw/``): its range is a physical stop.

    Args:
        m: the model.
        cfg: joint name -> value ([deg], gripper [0, 100]).
        where: the call, for the warning and errors (e.g. "move_to_pose target").
        partial: joints may be left out (a command); otherwise all six are required.

    Returns:
        The configuration within the limits, keys in ``JOINTS`` order.

    Raises:
        PlanError: not a dict, missing or unknown joints, values that are not finite numbers.
    """
    if not isinstance(cfg, Mapping):
        raise PlanError(f"{where} must be a dict joint name -> value ([deg], gripper [0, 100]), "
                        f"got {describe_value(cfg)}. Fix: e.g. {{'shoulder_pan': 0.0, ...}}; "
                        "convert_to_dictionary(d.qpos) makes one from the joint angles [rad].")
    limits = joint_limits(m)
    joints = [j for j in limits if j in cfg] if partial else list(limits)
    out = check_configuration(cfg, dict.fromkeys(joints, (-math.inf, math.inf)), where)
    held = []
    for joint, value in out.items():
        lower, upper = limits[joint]
        if limit_excess(value, lower, upper) > LIMIT_TOLERANCE:
            bound = lower if value < lower else upper
            held.append(f"{joint} = {format_limit(value)} {unit(joint)} is beyond its limit "
                        f"{format_limit(bound)} {unit(joint)}")
        out[joint] = min(upper, max(lower, value))
    if held:
        logger.warning("%s: %s; held at the limit, as MuJoCo holds it (the real arm refuses "
                       "this). Fix: keep each joint within its limits (joint_limits(m)).",
                       where, "; ".join(held))
    return out


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


def send_velocity_command(d: mujoco.MjData, velocities: Mapping[str, float] | None) -> None:
    """Set the ``<joint>_vel`` actuators to ``velocities`` ([deg/s], gripper [%/s]; None: 0).

    Joints missing from ``velocities`` get 0, as the course's list of six does. A model
    without velocity actuators takes only None.

    Raises:
        PlanError: velocities for a model without velocity actuators, values not finite.
    """
    m = d.model
    if not actuation.has_velocity_actuators(m):
        if velocities is None:
            return
        raise PlanError("send_position_command got velocities, but this model has position "
                        "actuators only. Fix: load model/scene_with_velocity.xml, or leave "
                        "velocity_dict out.")
    if velocities is None:
        velocities = {}
    if not isinstance(velocities, Mapping):
        raise PlanError(f"velocity_dict must be a dict joint name -> [deg/s] (gripper [%/s]), "
                        f"got {describe_value(velocities)}. Fix: e.g. {{'shoulder_pan': 10.0}}.")
    values = check_configuration(velocities, dict.fromkeys(
        [j for j in JOINTS if j in velocities], (-math.inf, math.inf)), "velocity command")
    lower, upper = m.joint("gripper").range
    for joint in JOINTS:
        value = values.get(joint, 0.0)
        rate = value * (upper - lower) / 100.0 if joint == "gripper" else math.radians(value)
        d.ctrl[m.actuator(joint + actuation.VELOCITY_SUFFIX).id] = rate


def get_object_pose(m: mujoco.MjModel, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Simulated object-frame pose (position (3,) [m], rotation (3, 3)) from the last kinematics."""
    site = d.site(TOOL_SITE)
    return site.xpos.copy(), site.xmat.reshape(3, 3).copy()
