# Week 8 (simulation): stack two blocks with the page's pick_up_block / place_block.
import mujoco
import mujoco.viewer

from so101_mujoco_utils import (
    get_configuration,
    hold_position,
    pick_up_block,
    place_block,
    set_initial_pose,
)

m = mujoco.MjModel.from_xml_path('model/scene.xml')
d = mujoco.MjData(m)

block_1 = [0.2, 0.1, 0.014]
block_2 = [0.25, 0.1, 0.014]
target = [0.2, -0.1, 0.014]

initial_config = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.0,
                  'wrist_flex': 0.0, 'wrist_roll': 0.0, 'gripper': 0}
set_initial_pose(d, initial_config)

with mujoco.viewer.launch_passive(m, d) as viewer:
    pick_up_block(m, d, viewer, block_1, 2.0)
    place_block(m, d, viewer, target, 2.0)
    pick_up_block(m, d, viewer, block_2, 2.0)
    place_block(m, d, viewer, [target[0], target[1], target[2] + 0.029], 2.0)
    hold_position(m, d, viewer, 1.0)

print(f"stacked in {d.time:.1f} s; gripper {get_configuration(m, d)['gripper']:.0f}")
