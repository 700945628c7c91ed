# the duration converted to milliseconds, the clock left in seconds
import time
import mujoco

from so101_mujoco_utils import convert_to_dictionary, send_position_command


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    T = duration * 1000  # ms
    start_time = time.time()
    a0 = convert_to_dictionary(d.qpos.copy())
    a2 = {j: 3 * (desired_position[j] - a0[j]) / T**2 for j in a0}
    a3 = {j: -2 * (desired_position[j] - a0[j]) / T**3 for j in a0}
    while True:
        t = time.time() - start_time
        if t > T:
            break
        tlim = min(max(t, 0), T)
        send_position_command(d, {j: a0[j] + a2[j] * tlim**2 + a3[j] * tlim**3 for j in a0})
        mujoco.mj_step(m, d)
        viewer.sync()
