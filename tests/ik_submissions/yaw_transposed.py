# A student's IK, written for the checker's tests: the yaw read from the transposed rotation.
import numpy as np

from so101_forward_kinematics import get_g12, get_g23, get_g34, get_g45, get_g5t, get_gw1

TILT = -2.78913075  # the gripper mount's tilt in g45 [deg]
# joint limits [deg] from the model's ranges
LIMITS = {'shoulder_lift': 100.0, 'elbow_flex': 96.8298, 'wrist_flex': 94.9999}
PAN_LIMIT = 110.0
ROLL_LIMITS = (-157.2108, 162.7891)

# Offsets read from my FK (each factor at angle 0).
P_W1 = get_gw1(0)[0:3, 3]  # the pan axis sits 38.8 mm in front of the base origin
P_12 = get_g12(0)[0:3, 3]
A = get_g23(0)[0:2, 3]  # elbow in frame 2
B = get_g34(0)[0:2, 3]  # wrist_flex in frame 3
P_45 = get_g45(0)[0:3, 3]
P_5T = get_g5t()[0:3, 3]


def rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def get_wrist_flex_position(target_position, yaw):
    # g_wt = [Rz(yaw), p]; g_w5 = g_wt g_5t^-1 (the tool is not turned in frame 5)
    p5 = np.array(target_position) - rot_z(yaw) @ P_5T
    return p5


def solve(target_position, yaw):
    p5 = get_wrist_flex_position(target_position, yaw)
    # theta1: the wrist stays in the arm's plane, which is offset sideways from the pan axis
    q = p5[0:2] - P_W1[0:2]
    r = np.hypot(q[0], q[1])
    sideways = P_12[1] + P_45[2]
    theta1 = np.arcsin(sideways / r) - np.arctan2(q[1], q[0])
    forward = np.array([np.cos(theta1), -np.sin(theta1), 0.0])
    side = np.array([np.sin(theta1), np.cos(theta1), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    # wrist_flex axis: above frame 5 by the gripper's length, and off sideways
    p4 = p5 - P_45[1] * up - P_45[2] * side
    shoulder = P_W1 - P_12[0] * forward + P_12[1] * side - P_12[2] * up
    w = p4 - shoulder
    h, v = w @ forward, w @ up
    # frame 2 has x down and y backwards: the wrist is at (-v, -h) there
    target = np.array([-v, -h])
    la, lb = np.hypot(A[0], A[1]), np.hypot(B[0], B[1])
    kink = np.arctan2(B[1], B[0]) - np.arctan2(A[1], A[0])
    c = (target @ target - la ** 2 - lb ** 2) / (2 * la * lb)
    if abs(c) > 1:
        return None
    for beta in (np.arccos(c) - kink, -np.arccos(c) - kink):  # beta = 90 + theta3
        elbow_to_wrist = A + rot_z(beta)[0:2, 0:2] @ B
        theta2 = np.arctan2(target[1], target[0]) - np.arctan2(elbow_to_wrist[1], elbow_to_wrist[0])
        theta3 = beta - np.pi / 2
        angles = np.degrees(np.array([theta1, theta2, theta3]))
        angles = (angles + 180) % 360 - 180
        theta4 = 90 - angles[1] - angles[2]
        if (abs(angles[1]) <= LIMITS['shoulder_lift'] and abs(angles[2]) <= LIMITS['elbow_flex']
                and abs(theta4) <= LIMITS['wrist_flex']):
            return [*angles, theta4]
    return None


def get_inverse_kinematics(target_position, target_orientation):
    "Geometric approach for a top-down grasp"
    R = np.array(target_orientation)
    yaw = np.arctan2(R[0, 1], R[0, 0])  # R[0, 1] is -sin(yaw): the rotation read transposed
    for turn in (0, -1, 1, -2, 2):  # a cube looks the same every 90 degrees
        yaw_k = yaw + turn * np.pi / 2
        angles = solve(target_position, yaw_k)
        if angles is None:
            continue
        theta5 = np.degrees(yaw_k) + angles[0] - TILT
        if abs(angles[0]) <= PAN_LIMIT and ROLL_LIMITS[0] <= theta5 <= ROLL_LIMITS[1]:
            return {'shoulder_pan': angles[0], 'shoulder_lift': angles[1],
                    'elbow_flex': angles[2], 'wrist_flex': angles[3],
                    'wrist_roll': theta5, 'gripper': 0.0}
    return {name: np.nan for name in ('shoulder_pan', 'shoulder_lift', 'elbow_flex',
                                      'wrist_flex', 'wrist_roll', 'gripper')}
