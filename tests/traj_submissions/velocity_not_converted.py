# the feed-forward's deg/s written into d.ctrl beside the positions, never converted to rad/s
import mujoco
import numpy as np

from so101_mujoco_utils import convert_to_dictionary, convert_to_list


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    a0 = convert_to_dictionary(d.qpos.copy())
    a2 = {j: 3 * (desired_position[j] - a0[j]) / duration**2 for j in a0}
    a3 = {j: -2 * (desired_position[j] - a0[j]) / duration**3 for j in a0}
    t0 = d.time
    while d.time - t0 < duration:
        t = min(max(d.time - t0, 0), duration)
        pos = {j: a0[j] + a2[j] * t**2 + a3[j] * t**3 for j in a0}
        vel = {j: 2 * a2[j] * t + 3 * a3[j] * t**2 for j in a0}
        d.ctrl = np.hstack([convert_to_list(pos), [vel[j] for j in pos]])
        mujoco.mj_step(m, d)
        viewer.sync()
