# Week 9: the page script's shape, with the start passed in, timed by the simulation's clock
import mujoco
import numpy as np

from so101_mujoco_utils import send_position_command


def move_to_pose_cubic(m, d, viewer, starting_position, desired_position, duration):
    q0 = {j: starting_position[j] for j in desired_position}
    a2 = {j: 3 * (desired_position[j] - q0[j]) / duration**2 for j in q0}
    a3 = {j: -2 * (desired_position[j] - q0[j]) / duration**3 for j in q0}
    t0 = d.time
    while d.time - t0 <= duration:
        t = np.clip(d.time - t0, 0, duration)
        send_position_command(d, {j: q0[j] + a2[j] * t**2 + a3[j] * t**3 for j in q0})
        mujoco.mj_step(m, d)
        viewer.sync()


if __name__ == "__main__":
    m = mujoco.MjModel.from_xml_path('model/scene.xml')
    d = mujoco.MjData(m)
