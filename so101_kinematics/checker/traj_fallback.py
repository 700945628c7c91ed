"""The ``so101_mujoco_utils`` a checked file imports when none is beside it (so101-check-traj).

Written into the child's fallback folder (the end of ``sys.path``), as the IK checker's
fallback FK: a student's script written against the course's utils imports its
conversions and commands from here. They follow the course's week-4 and week-9 pages
(degrees and the gripper's [0, 100] at the user's side, radians in ``d.qpos`` and
``d.ctrl``, the course's joint order, ``d.ctrl = [positions..., velocities...]`` on the
velocity scene) and run on the checker's stand-in ``mujoco``.
"""

__all__ = ["FALLBACK_UTILS"]

FALLBACK_UTILS = '''"""so101-check-traj's stand-in for the course's so101_mujoco_utils.

Used when none is beside the checked file: the course's conversions and commands,
in radians for MuJoCo."""
import math

import mujoco

JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")


def convert_to_dictionary(qpos):
    return {j: qpos[i] * (100.0 if j == "gripper" else 180.0) / math.pi
            for i, j in enumerate(JOINTS)}


def convert_to_list(dictionary):
    return [dictionary[j] * math.pi / (100.0 if j == "gripper" else 180.0) for j in JOINTS]


def get_positions_dict(m, d):
    return convert_to_dictionary(d.qpos)


def set_initial_pose(d, position_dict):
    d.qpos[:6] = convert_to_list(position_dict)


def send_position_command(d, position_dict, velocity_dict=None):
    position = convert_to_list(position_dict)
    if velocity_dict is None and len(d.ctrl) == 6:
        d.ctrl = position
    else:
        d.ctrl = position + (convert_to_list(velocity_dict) if velocity_dict else [0.0] * 6)


def hold_position(m, d, viewer, duration):
    here = convert_to_dictionary(d.qpos)
    start = d.time
    while d.time - start < duration:
        send_position_command(d, here)
        mujoco.mj_step(m, d)
        viewer.sync()
'''
