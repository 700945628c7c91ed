# A student's FK, written for the checker's tests: * (element by element) instead of @ in the FK's product.
import numpy as np


def Rx(deg):
    a = np.deg2rad(deg)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def Ry(deg):
    a = np.deg2rad(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def Rz(deg):
    a = np.deg2rad(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def make_pose(R, p):
    g = np.eye(4)
    g[:3, :3] = R
    g[:3, 3] = p
    return g


TILT = -2.78913075


def get_gw1(theta1_deg):
    return make_pose(Rz(180) @ Rx(180) @ Rz(theta1_deg), [0.0388353, 0.0, 0.0624])


def get_g12(theta2_deg):
    return make_pose(Rx(-90) @ Rz(-90) @ Rz(theta2_deg), [-0.0303992, -0.0182778, -0.0542])


def get_g23(theta3_deg):
    return make_pose(Rz(90) @ Rz(theta3_deg), [-0.11257, -0.028, 0.0])


def get_g34(theta4_deg):
    return make_pose(Rz(-90) @ Rz(theta4_deg), [-0.1349, 0.0052, 0.0])


def get_g45(theta5_deg):
    return make_pose(Rz(180) @ Rx(90) @ Rz(TILT) @ Rz(theta5_deg), [0.0, -0.0611, 0.0181])


def get_g5t():
    return make_pose(np.eye(3), [0.0051, -0.000218, -0.1075])


def get_forward_kinematics(position_dict):
    gw1 = get_gw1(position_dict['shoulder_pan'])
    g12 = get_g12(position_dict['shoulder_lift'])
    g23 = get_g23(position_dict['elbow_flex'])
    g34 = get_g34(position_dict['wrist_flex'])
    g45 = get_g45(position_dict['wrist_roll'])
    g5t = get_g5t()
    gwt = gw1 * g12 * g23 * g34 * g45 * g5t
    return gwt[0:3, 3], gwt[0:3, 0:3]
