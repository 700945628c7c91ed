# Week 6 (simulation): show the FK's object frame as a cylinder, then the six-configuration
# pick and place, written the way the assignment's starter code is laid out.
import time

import mujoco
import mujoco.viewer
import numpy as np

from so101_forward_kinematics import get_forward_kinematics
from so101_mujoco_utils import hold_position, move_to_pose, send_position_command, set_initial_pose

m = mujoco.MjModel.from_xml_path('model/scene.xml')
d = mujoco.MjData(m)


def show_cylinder(viewer, position, rotation, radius=0.0245, halfheight=0.05, rgba=(1, 0, 0, 1)):
    mujoco.mjv_initGeom(viewer.user_scn.geoms[0], type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                        size=[radius, halfheight, 0], pos=position, mat=rotation.flatten(),
                        rgba=rgba)
    viewer.user_scn.ngeom = 1
    viewer.sync()


start_open = {'shoulder_pan': -45.0, 'shoulder_lift': 45.0, 'elbow_flex': -45.00,
              'wrist_flex': 90.0, 'wrist_roll': 0.0, 'gripper': 50}
start_closed = dict(start_open, gripper=5)
lifted_1 = {'shoulder_pan': -45.0, 'shoulder_lift': 0.0, 'elbow_flex': -20.0,
            'wrist_flex': 95, 'wrist_roll': 0.0, 'gripper': 5}  # the wrist at its stop
lifted_2 = dict(lifted_1, shoulder_pan=45.0)
final_closed = dict(start_closed, shoulder_pan=45.0)
final_open = dict(start_open, shoulder_pan=45.0)

set_initial_pose(d, start_open)
send_position_command(d, start_open)
object_position, object_orientation = get_forward_kinematics(start_open)
print("object frame:", np.round(object_position, 4))

with mujoco.viewer.launch_passive(m, d) as viewer:
    start = time.time()
    show_cylinder(viewer, object_position, object_orientation)
    hold_position(m, d, viewer, 1.0)
    for cfg in (start_closed, lifted_1, lifted_2, final_closed, final_open):
        move_to_pose(m, d, viewer, cfg, 2.0)
        hold_position(m, d, viewer, 0.5)

print("final shoulder_pan:", round(float(np.degrees(d.qpos[0])), 1))
