"""MuJoCo helpers for the SO-101, as the course's scripts call them.

Load the scene, set the arm's pose, command it, and move it as the course
does: ``move_to_pose(m, d, viewer, cfg, duration)`` and
``hold_position(m, d, viewer, duration)`` (assignment 6) or
``hold_position(m, d, viewer, cfg, duration)`` (assignment 7: command ``cfg``,
then hold), with arm joints in [deg] and the
gripper in [0, 100] (0 closed, 100 open). The machinery lives in the
package: ``so101_kinematics/sim/scene.py`` (loading, units, poses, commands)
and ``so101_kinematics/sim/stepping.py`` (the timed moves, the viewer).

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

from so101_kinematics.display import has_display  # noqa: F401 - the scripts' display check
from so101_kinematics.errors import CallShapeError, ViewerClosed  # noqa: F401
from so101_kinematics.frames import GRIPPER_RANGE, JOINTS, TOOL_SITE  # noqa: F401
from so101_kinematics.sim.scene import (  # noqa: F401 - the course's names
    MODEL_DIR,
    SCENE_PATH,
    from_radians,
    get_command,
    get_configuration,
    get_object_pose,
    gripper_from_radians,
    gripper_to_radians,
    joint_limits,
    joint_table,
    load_model,
    send_position_command,
    set_initial_pose,
    to_radians,
    validate,
)
from so101_kinematics.sim.stepping import (  # noqa: F401
    COMMAND_BLOCK_STEPS,
    HOLD_SHAPES,
    VIEWER_SYNC_PERIOD,
    hold_position,
    move_to_pose,
)
