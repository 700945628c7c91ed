# Week 7 (simulation): the limit mistakes students make. A starting pose copied from the viewer
# (-1.75 rad written as -100.268 deg), a joint pushed to -180, moves to the round-number limits
# (-100, -110, 95), and a configuration built from qpos in radians (read as degrees).
import mujoco
import numpy as np

from so101_mujoco_utils import hold_position, move_to_pose, set_initial_pose

m = mujoco.MjModel.from_xml_path('model/scene.xml')
d = mujoco.MjData(m)

starting_position = {'shoulder_pan': 0.0, 'shoulder_lift': -100.268, 'elbow_flex': 90.0,
                     'wrist_flex': 50.0, 'wrist_roll': 0.0, 'gripper': 10}
set_initial_pose(d, starting_position)
hold_position(m, d, None, 0.5)

folded = dict(starting_position, shoulder_lift=-180)
set_initial_pose(d, folded)
hold_position(m, d, None, 0.5)

move_to_pose(m, d, None, {'shoulder_pan': 0.0, 'shoulder_lift': -100, 'elbow_flex': 90.0,
                          'wrist_flex': 50.0, 'wrist_roll': 0.0, 'gripper': 10}, 2)
move_to_pose(m, d, None, {'shoulder_pan': -110, 'shoulder_lift': 0.0, 'elbow_flex': 0.0,
                          'wrist_flex': 95, 'wrist_roll': 0.0, 'gripper': 10}, 2)
print("at the limits:", np.round(np.degrees(d.qpos[:4]), 1))

names = ['shoulder_pan', 'shoulder_lift', 'elbow_flex', 'wrist_flex', 'wrist_roll', 'gripper']
current = {name: d.qpos[i] for i, name in enumerate(names)}  # radians, used as degrees
move_to_pose(m, d, None, current, 1.0)
print("done")
