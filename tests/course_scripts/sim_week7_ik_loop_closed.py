# Week 7 (simulation): the IK test loop. The student closes the viewer part-way (the test sets
# COURSE_VIEWER_CLOSES_AFTER); the loop must end and the script carry on to its last line.
import time

import mujoco
import mujoco.viewer
import numpy as np

from so101_inverse_kinematics import get_inverse_kinematics, get_wrist_flex_position
from so101_mujoco_utils import hold_position, move_to_pose, send_position_command, set_initial_pose

m = mujoco.MjModel.from_xml_path('model/scene.xml')
d = mujoco.MjData(m)
np.random.seed(4560)


def show_cube(viewer, position, orientation, geom_num=0, halfwidth=0.013):
    mujoco.mjv_initGeom(viewer.user_scn.geoms[geom_num], type=mujoco.mjtGeom.mjGEOM_BOX,
                        size=[halfwidth, halfwidth, halfwidth], pos=position,
                        mat=orientation.flatten(), rgba=[1, 0, 0, 0.2])
    viewer.user_scn.ngeom = max(viewer.user_scn.ngeom, geom_num + 1)
    viewer.sync()


def get_random_position():
    x = np.random.uniform(0.15, 0.25)
    y = np.random.uniform(-0.15, 0.15)
    yaw = np.random.uniform(0, np.pi / 2)
    return [x, y, 0.014], yaw


initial_config = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.00,
                  'wrist_flex': 0.0, 'wrist_roll': 0.0, 'gripper': 0}
set_initial_pose(d, initial_config)
send_position_command(d, initial_config)

loops = 0
with mujoco.viewer.launch_passive(m, d) as viewer:
    time.sleep(0.1)
    while viewer.is_running():
        loops += 1
        for _ in range(5):
            desired_position, desired_yaw = get_random_position()
            desired_orientation = np.eye(3)
            show_cube(viewer, desired_position, desired_orientation)
            wrist_position, wrist_orientation = get_wrist_flex_position(desired_position)
            show_cube(viewer, wrist_position, wrist_orientation, geom_num=1, halfwidth=0.008)
            joint_configuration = get_inverse_kinematics(desired_position, desired_orientation)
            move_to_pose(m, d, viewer, joint_configuration, 1.0)
            hold_position(m, d, viewer, joint_configuration, 2.0)

print(f"viewer closed after {loops} loop(s) at t = {d.time:.2f} s")
