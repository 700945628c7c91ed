# Week 9 (simulation): the page's test script as students run it, with its two typos fixed
# (move_to_pose_direct -> move_to_pose_cubic, hold_position imported), on the velocity scene.
import time

import mujoco
import mujoco.viewer
import numpy as np

from so101_inverse_kinematics import get_inverse_kinematics
from so101_mujoco_utils import (
    convert_to_dictionary,
    hold_position,
    move_to_pose_cubic,
    send_position_command,
    set_initial_pose,
)

m = mujoco.MjModel.from_xml_path('model/scene_with_velocity.xml')
d = mujoco.MjData(m)

size_block = 0.0285
pos1 = [0.25, 0.1, size_block / 2]
pos2 = [0.25, -0.1, size_block / 2]
config1 = get_inverse_kinematics(pos1)
config2 = get_inverse_kinematics(pos2)


def show_cube(viewer, position, orientation, geom_num=0, halfwidth=0.013):
    mujoco.mjv_initGeom(viewer.user_scn.geoms[geom_num], type=mujoco.mjtGeom.mjGEOM_BOX,
                        size=[halfwidth] * 3, pos=position, mat=orientation.flatten(),
                        rgba=np.random.rand(3).tolist() + [1])
    viewer.user_scn.ngeom += 1
    viewer.sync()


def worst(target):
    here = convert_to_dictionary(d.qpos)
    return max(abs(here[j] - target[j]) for j in target if j != 'gripper')


initial_config = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.00,
                  'wrist_flex': 0.0, 'wrist_roll': 0.0, 'gripper': 0}
set_initial_pose(d, initial_config)
send_position_command(d, initial_config)

with mujoco.viewer.launch_passive(m, d) as viewer:
    show_cube(viewer, pos1, np.eye(3), geom_num=0)
    show_cube(viewer, pos2, np.eye(3), geom_num=1)
    time.sleep(1.0)
    move_to_pose_cubic(m, d, viewer, initial_config, config1, 2.0)
    hold_position(m, d, viewer, 1.0)
    print(f"at config1: {worst(config1):.2f} deg")
    move_to_pose_cubic(m, d, viewer, config1, config2, 2.0)
    hold_position(m, d, viewer, 1.0)
    print(f"at config2: {worst(config2):.2f} deg")
    move_to_pose_cubic(m, d, viewer, config2, initial_config, 2.0)
    hold_position(m, d, viewer, 1.0)
    print(f"back home: {worst(initial_config):.2f} deg")
