# Week 9 (simulation): the student's own cubic move, stepping MuJoCo and the viewer by hand with
# send_position_command, then the course's hold_position.
import mujoco
import mujoco.viewer

from so101_inverse_kinematics import get_inverse_kinematics
from so101_mujoco_utils import (
    convert_to_dictionary,
    hold_position,
    send_position_command,
    set_initial_pose,
)

m = mujoco.MjModel.from_xml_path('model/scene.xml')
d = mujoco.MjData(m)


def move_to_pose_cubic(m, d, viewer, desired_position, duration):
    starting_position = convert_to_dictionary(d.qpos)
    a0 = starting_position
    a2 = {j: 3 * (desired_position[j] - a0[j]) / duration**2 for j in desired_position}
    a3 = {j: -2 * (desired_position[j] - a0[j]) / duration**3 for j in desired_position}
    t0 = d.time
    while d.time - t0 < duration:
        t = min(max(d.time - t0, 0), duration)
        position_dict = {j: a0[j] + a2[j] * t**2 + a3[j] * t**3 for j in desired_position}
        send_position_command(d, position_dict)
        mujoco.mj_step(m, d)
        viewer.sync()


initial_config = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.0,
                  'wrist_flex': 0.0, 'wrist_roll': 0.0, 'gripper': 0}
set_initial_pose(d, initial_config)
send_position_command(d, initial_config)
config1 = get_inverse_kinematics([0.25, 0.1, 0.0285 / 2])
config2 = get_inverse_kinematics([0.25, -0.1, 0.0285 / 2])

with mujoco.viewer.launch_passive(m, d) as viewer:
    move_to_pose_cubic(m, d, viewer, config1, 2.0)
    hold_position(m, d, viewer, 1.0)
    move_to_pose_cubic(m, d, viewer, config2, 2.0)
    hold_position(m, d, viewer, 1.0)
    move_to_pose_cubic(m, d, viewer, initial_config, 2.0)
    hold_position(m, d, viewer, 1.0)

print(f"back home: shoulder_lift {convert_to_dictionary(d.qpos)['shoulder_lift']:.1f} deg")
