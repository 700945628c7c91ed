# a1 set to the average speed
import time
import mujoco

from so101_mujoco_utils import convert_to_dictionary, send_position_command


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    start_time = time.time()
    starting_position = convert_to_dictionary(d.qpos.copy())
    a0 = starting_position
    a1 = {joint: (desired_position[joint] - a0[joint])/duration for joint in starting_position}
    a2 = {joint: 3*(desired_position[joint] - a0[joint])/duration**2 for joint in starting_position}
    a3 = {joint: -2*(desired_position[joint] - a0[joint])/duration**3 for joint in starting_position}

    def cubic_interpolation(t, joint):
        tlim = min(max(t, 0), duration)
        return a0[joint] + a1[joint]*tlim + a2[joint]*(tlim**2) + a3[joint]*(tlim**3)

    while True:
        t = time.time() - start_time
        if t > duration:
            break
        position_dict = {}
        for joint in desired_position:
            position_dict[joint] = cubic_interpolation(t, joint)
        send_position_command(d, position_dict)
        mujoco.mj_step(m, d)
        viewer.sync()
