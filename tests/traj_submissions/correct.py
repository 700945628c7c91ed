# so101_mujoco_utils.py with assignment 9's cubic (the course's move_to_pose, timed by the wall clock)
import time
import mujoco


def convert_to_dictionary(qpos):
    return {
        'shoulder_pan': qpos[0]*180.0/3.14159,
        'shoulder_lift': qpos[1]*180.0/3.14159,
        'elbow_flex': qpos[2]*180.0/3.14159,
        'wrist_flex': qpos[3]*180.0/3.14159,
        'wrist_roll': qpos[4]*180.0/3.14159,
        'gripper': qpos[5]*100/3.14159
    }


def convert_to_list(dictionary):
    return [
        dictionary['shoulder_pan']*3.14159/180.0,
        dictionary['shoulder_lift']*3.14159/180.0,
        dictionary['elbow_flex']*3.14159/180.0,
        dictionary['wrist_flex']*3.14159/180.0,
        dictionary['wrist_roll']*3.14159/180.0,
        dictionary['gripper']*3.14159/100.0
    ]


def send_position_command(d, position_dict):
    pos = convert_to_list(position_dict)
    d.ctrl = pos


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    start_time = time.time()
    starting_position = convert_to_dictionary(d.qpos.copy())

    # Cubic coefficients stored in a dictionary similar to starting_position
    a0 = starting_position
    a1 = {joint: 0.0 for joint in starting_position}
    a2 = {joint: 3*(desired_position[joint] - a0[joint])/duration**2 for joint in starting_position}
    a3 = {joint: -2*(desired_position[joint] - a0[joint])/duration**3 for joint in starting_position}

    def cubic_interpolation(t, joint):
        tlim = min(max(t, 0), duration)
        pos = a0[joint] + a1[joint]*tlim + a2[joint]*(tlim**2) + a3[joint]*(tlim**3)
        return pos

    while True:
        t = time.time() - start_time
        if t > duration:
            break

        # Interpolate each joint
        position_dict = {}
        for joint in desired_position:
            position_dict[joint] = cubic_interpolation(t, joint)

        # Send command
        send_position_command(d, position_dict)
        mujoco.mj_step(m, d)
        viewer.sync()
