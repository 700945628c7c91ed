# the cubic in degrees written straight into d.ctrl (MuJoCo wants radians)
import mujoco

from so101_mujoco_utils import convert_to_dictionary

JOINTS = ['shoulder_pan', 'shoulder_lift', 'elbow_flex', 'wrist_flex', 'wrist_roll', 'gripper']


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    a0 = convert_to_dictionary(d.qpos.copy())
    a2 = {j: 3 * (desired_position[j] - a0[j]) / duration**2 for j in a0}
    a3 = {j: -2 * (desired_position[j] - a0[j]) / duration**3 for j in a0}
    t0 = d.time
    while d.time - t0 < duration:
        t = min(max(d.time - t0, 0), duration)
        d.ctrl = [a0[j] + a2[j] * t**2 + a3[j] * t**3 for j in JOINTS]
        mujoco.mj_step(m, d)
        viewer.sync()
