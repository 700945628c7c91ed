# Week 8 (hardware): move to an IK target, hold, move back, release; then the calibration check
# at the all-zero pose. PORT_ID: the test passes the virtual arm's port in SO101_PORT.
import os

from so101_inverse_kinematics import get_inverse_kinematics
from so101_utils import hold_position, load_calibration, move_to_pose, setup_motors

PORT_ID = os.environ.get("SO101_PORT", "/dev/ttyACM0")  # REPLACE WITH YOUR PORT!
ROBOT_NAME = "follower-1"

desired_ee = [0.2, 0.0, 0.014]  # x, y, z in meters
desired_configuration = get_inverse_kinematics(desired_ee)
move_time = 1.5
hold_time = 1.0

calibration = load_calibration(ROBOT_NAME)
bus = setup_motors(calibration, PORT_ID)

starting_pose = bus.sync_read("Present_Position")
print("Starting Pose:", {joint: round(value, 1) for joint, value in starting_pose.items()})

move_to_pose(bus, desired_configuration, move_time)
hold_position(bus, hold_time)

home = {'shoulder_pan': 0.0, 'shoulder_lift': 0.0, 'elbow_flex': 0.0, 'wrist_flex': 0.0,
        'wrist_roll': 0.0, 'gripper': 0.0}
move_to_pose(bus, home, move_time)
reached = bus.sync_read("Present_Position")
print("home check, elbow_flex:", round(reached["elbow_flex"], 1))

move_to_pose(bus, starting_pose, move_time)
bus.disable_torque()
