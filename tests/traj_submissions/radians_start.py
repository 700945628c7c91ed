# the start read straight from d.qpos (radians) and used as degrees
import mujoco

from so101_mujoco_utils import send_position_command

JOINTS = ['shoulder_pan', 'shoulder_lift', 'elbow_flex', 'wrist_flex', 'wrist_roll', 'gripper']


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    a0 = dict(zip(JOINTS, d.qpos))
    a2 = {j: 3 * (desired_position[j] - a0[j]) / duration**2 for j in a0}
    a3 = {j: -2 * (desired_position[j] - a0[j]) / duration**3 for j in a0}
    t0 = d.time
    while d.time - t0 < duration:
        t = min(max(d.time - t0, 0), duration)
        send_position_command(d, {j: a0[j] + a2[j] * t**2 + a3[j] * t**3 for j in a0})
        mujoco.mj_step(m, d)
        viewer.sync()
