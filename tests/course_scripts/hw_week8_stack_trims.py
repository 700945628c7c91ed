# Week 8 (hardware): trims through setup_motors, the page's offset_config, and two blocks
# stacked with pick_up_block / place_block. PORT_ID from SO101_PORT (the virtual arm in tests).
import os

from so101_utils import (
    load_calibration,
    move_to_pose,
    offset_config,
    pick_up_block,
    place_block,
    setup_motors,
)

PORT_ID = os.environ.get("SO101_PORT", "/dev/ttyACM0")
ROBOT_NAME = "follower-1"

calibration = load_calibration(ROBOT_NAME)
bus = setup_motors(calibration, PORT_ID, offset_config={"shoulder_lift": 2.0, "elbow_flex": -4.0})
starting_pose = bus.sync_read("Present_Position")

zero = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.0, 'wrist_flex': 0.0,
        'wrist_roll': 0.0, 'gripper': 0.0}
print("offsets:", offset_config(zero))

block_position = [0.2, 0.1, 0.014]
target_position = [0.2, -0.1, 0.014]
pick_up_block(bus, block_position, 1.5)
bus = place_block(bus, target_position, 1.5)
second = [0.25, 0.1, 0.014]
pick_up_block(bus, second, 1.5)
place_block(bus, [0.2, -0.1, 0.043], 1.5)

move_to_pose(bus, starting_pose, 2.0)
bus.disable_torque()
