# t set once before the loop and never advanced
import mujoco

from so101_mujoco_utils import convert_to_dictionary, send_position_command


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    a0 = convert_to_dictionary(d.qpos.copy())
    a2 = {j: 3 * (desired_position[j] - a0[j]) / duration**2 for j in a0}
    a3 = {j: -2 * (desired_position[j] - a0[j]) / duration**3 for j in a0}
    t = 0
    while t <= duration:
        tlim = min(max(t, 0), duration)
        send_position_command(d, {j: a0[j] + a2[j] * tlim**2 + a3[j] * tlim**3 for j in a0})
        mujoco.mj_step(m, d)
        viewer.sync()
