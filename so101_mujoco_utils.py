"""MuJoCo helpers for the SO-101, as the course's scripts call them.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.

``move_to_pose(m, d, viewer, cfg, duration)`` and ``hold_position(m, d, viewer, duration)``
(assignment 6; ``hold_position(m, d, viewer, cfg, duration)`` in assignment 7) step the
physics (``mj_step``) and refresh the viewer (``viewer.sync()``) at real time, arm joints in
[deg], the gripper in [0, 100] (``so101_kinematics/sim/stepping.py``). As the course's utils:
a joint beyond the model's range is held at its limit with one warning line (the real arm,
``so101_utils``, refuses it); closing the viewer stops the motion, so ``while
viewer.is_running():`` ends. Also: the converters ``convert_to_dictionary(d.qpos)`` /
``convert_to_list(cfg)``, assignment 8's ``pick_up_block`` / ``place_block``, assignment 9's
``move_to_pose_cubic`` (on ``model/scene_with_velocity.xml`` with the velocity fed too), week
8's ``move_to_pose_with_logging`` / ``plot_data``.

Example (the course's test pose, headless)::

    >>> import mujoco
    >>> m = load_model()
    >>> d = mujoco.MjData(m)
    >>> set_initial_pose(d, {"shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0,
    ...                      "wrist_flex": 90.0, "wrist_roll": 0.0, "gripper": 50.0})
    >>> round(get_configuration(m, d)["elbow_flex"], 6)
    -45.0
"""

from __future__ import annotations

from collections.abc import Mapping

from so101_kinematics.errors import CallShapeError, ViewerClosed  # noqa: F401
from so101_kinematics.frames import TOOL_SITE  # noqa: F401
from so101_kinematics.ik.blocks import pick_up_moves, place_moves
from so101_kinematics.paths import MODEL_DIR, SCENE_PATH  # noqa: F401 - the course's scene files
from so101_kinematics.planning import trajectory_log
from so101_kinematics.planning.trajectory_log import plot_data  # noqa: F401 - week 8's plot
from so101_kinematics.sim import scene, tracking
from so101_kinematics.sim.scene import (  # noqa: F401 - the course's names
    convert_to_dictionary,
    convert_to_list,
    from_radians,
    get_command,
    get_configuration,
    get_object_pose,
    gripper_from_radians,
    gripper_to_radians,
    joint_limits,
    load_model,
    to_radians,
)
from so101_kinematics.sim.stepping import (  # noqa: F401
    HOLD_SHAPES,
    hold_position,
    move_to_pose,
)


def set_initial_pose(d, position_dict: Mapping[str, float]) -> None:
    """Place the arm at ``position_dict`` at rest ([deg], gripper [0, 100]) and command it there.

    A joint beyond the model's range is held at its limit, with a warning line.
    """
    scene.set_initial_pose(d, scene.held_at_limits(d.model, position_dict, "set_initial_pose"))


def send_position_command(d, position_dict: Mapping[str, float],
                          velocity_dict: Mapping[str, float] | None = None) -> None:
    """Command the servos to ``position_dict`` ([deg], gripper [0, 100]); others keep theirs.

    A joint beyond the model's range is commanded to its limit, with a warning line.
    With ``model/scene_with_velocity.xml`` (assignment 9's 12 controls) the velocity
    actuators get ``velocity_dict`` ([deg/s], gripper [%/s]), or 0 when it is None,
    as the course's ``d.ctrl = [positions..., velocities...]``.

    Raises:
        PlanError: a velocity for a model without velocity actuators, or one that is
            not a finite number.
    """
    scene.send_position_command(
        d, scene.held_at_limits(d.model, position_dict, "send_position_command", partial=True))
    scene.send_velocity_command(d, velocity_dict)


def move_to_pose_cubic(m, d, viewer, *args, **keywords) -> None:
    """Assignment 9's move: as ``move_to_pose``, along the course's cubic.

    ``move_to_pose_cubic(m, d, viewer, desired_position, duration)`` or
    ``move_to_pose_cubic(m, d, viewer, starting_position, desired_position, duration)``.
    Per joint ``q(t) = a0 + a1 t + a2 t^2 + a3 t^3`` from the start ``a0 = q0`` to
    ``qf``, zero velocity at both ends::

        a1 = 0,  a2 = 3 (qf - q0) / duration**2,  a3 = -2 (qf - q0) / duration**3

    with ``t`` clipped to ``[0, duration]`` (``profiles.cubic_coefficients``). The
    move starts at the last command; a ``starting_position`` farther than 3 deg from
    it is named in a warning, never jumped to. On ``model/scene_with_velocity.xml``
    the cubic's velocity ``a1 + 2 a2 t + 3 a3 t^2`` goes to the velocity actuators
    (the course's optional part; ``velocity=False`` leaves them at 0).
    """
    move_to_pose(m, d, viewer, *args, profile="cubic", **keywords)


def move_to_pose_with_logging(m, d, viewer, *args, profile: str = "linear", **keywords):
    """Week 8's logged move: as ``move_to_pose``, returning the course's DataFrame.

    ``move_to_pose_with_logging(m, d, viewer, desired_position, duration)`` or
    ``(m, d, viewer, starting_position, desired_position, duration)``; one row per
    physics step: ``time`` [s] from the move's start, ``target_<joint>`` (the
    command) and ``actual_<joint>`` (``d.qpos``), [deg] and the gripper [0, 100].
    ``profile`` is the move's ("linear", the course's, or "cubic", ...); pandas is
    needed (checked before the arm moves).
    """
    trajectory_log.require_pandas()
    log = tracking.StepLog(m, d, viewer)
    move_to_pose(m, d, log, *args, profile=profile, **keywords)
    return tracking.log_frame(log)


def pick_up_block(m, d, viewer, block_position, move_to_duration: float) -> None:
    """Assignment 8's pick: above the block open, down, close, lift (top-down, yaw 0).

    Args:
        m: the model.
        d: the simulation data.
        viewer: as for ``move_to_pose`` (None when headless).
        block_position: the block's centre (x, y, z) [m].
        move_to_duration: [s] of the first move, to 3 cm above the block; the others take 1 s.
    """
    for cfg, duration in pick_up_moves(block_position, move_to_duration):
        move_to_pose(m, d, viewer, cfg, duration)


def place_block(m, d, viewer, target_position, move_to_duration: float) -> None:
    """Assignment 8's place: above the target closed, down, open, back up (top-down, yaw 0).

    Args:
        m: the model.
        d: the simulation data.
        viewer: as for ``move_to_pose`` (None when headless).
        target_position: where the block's centre goes (x, y, z) [m].
        move_to_duration: [s] of the first move, to 3 cm above the target; the others take 1 s.
    """
    for cfg, duration in place_moves(target_position, move_to_duration):
        move_to_pose(m, d, viewer, cfg, duration)
