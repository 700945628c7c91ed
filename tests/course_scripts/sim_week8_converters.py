# Week 8 (simulation): the course's converters and assignment 8's starting configuration.
# The measured pose is read back with convert_to_dictionary(d.qpos) and passed as the start of
# each move; a command is also written straight into d.ctrl with convert_to_list.
import mujoco
import mujoco.viewer

from so101_inverse_kinematics import get_inverse_kinematics
from so101_mujoco_utils import (
    convert_to_dictionary,
    convert_to_list,
    hold_position,
    move_to_pose,
    set_initial_pose,
)

m = mujoco.MjModel.from_xml_path('model/scene.xml')
d = mujoco.MjData(m)

initial_config = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.0,
                  'wrist_flex': 0.0, 'wrist_roll': 0.0, 'gripper': 0}
set_initial_pose(d, initial_config)
d.ctrl = convert_to_list(initial_config)

with mujoco.viewer.launch_passive(m, d) as viewer:
    for target in ([0.2, 0.1, 0.014], [0.25, -0.05, 0.014]):
        joint_configuration = get_inverse_kinematics(target)
        joint_configuration['gripper'] = 50
        current_config = convert_to_dictionary(d.qpos.copy())
        move_to_pose(m, d, viewer, current_config, joint_configuration, 2.0)
        hold_position(m, d, viewer, 1.0)
    closed = dict(joint_configuration, gripper=5)
    d.ctrl = convert_to_list(closed)
    hold_position(m, d, viewer, 1.5)

final = convert_to_dictionary(d.qpos)
print(f"final gripper: {final['gripper']:.1f}")
print(f"final shoulder_pan: {final['shoulder_pan']:.1f} (IK: {closed['shoulder_pan']:.1f})")
