"""The SO-101 model: loads as the course does, named as lerobot names it, steps cleanly."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from conftest import REPO

from so101_forward_kinematics import JOINTS, TOOL_SITE
from so101_kinematics.frames import BODY_OF_FRAME
from so101_kinematics.gravity import holding_torques
from so101_kinematics.sim.meshes import read_manifest

SIM_SECONDS = 3.0  # [s] of random commands
COMMAND_PERIOD = 0.1  # [s] between new random targets


def test_course_loading_line_works_from_the_repo_root(monkeypatch):
    monkeypatch.chdir(REPO)
    m = mujoco.MjModel.from_xml_path("model/scene.xml")
    assert m.nmesh == len(read_manifest())


def test_joints_and_actuators_are_named_as_lerobot(model):
    joints = [model.joint(i).name for i in range(model.njnt)]
    actuators = [model.actuator(i).name for i in range(model.nu)]
    assert joints == list(JOINTS)
    assert actuators == list(JOINTS)
    for name in JOINTS:
        # Each actuator drives the joint of the same name, within that joint's range.
        actuator = model.actuator(name)
        assert actuator.trntype == mujoco.mjtTrn.mjTRN_JOINT
        assert model.joint(actuator.trnid[0]).name == name
        np.testing.assert_allclose(actuator.ctrlrange, model.joint(name).range)
        assert model.joint(name).type == mujoco.mjtJoint.mjJNT_HINGE
        np.testing.assert_array_equal(model.joint(name).axis, [0.0, 0.0, 1.0])


def test_fk_bodies_sites_and_cameras_exist(model):
    for body in BODY_OF_FRAME.values():
        assert model.body(body).id > 0
    assert model.body(model.site(TOOL_SITE).bodyid[0]).name == "gripper"
    for camera in ("pick_place", "gripper_closeup"):
        assert model.camera(camera).id >= 0


def test_home_keyframe_is_within_the_limits(model):
    key = model.key("home")
    for name in JOINTS:
        lower, upper = model.joint(name).range
        assert lower <= key.qpos[model.joint(name).qposadr[0]] <= upper
        assert lower <= key.ctrl[model.actuator(name).id] <= upper


def test_steps_under_random_commands_without_warnings(model):
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    rng = np.random.default_rng(3)
    lower, upper = model.actuator_ctrlrange.T
    steps_per_command = round(COMMAND_PERIOD / model.opt.timestep)
    for _ in range(round(SIM_SECONDS / COMMAND_PERIOD)):
        data.ctrl[:] = rng.uniform(lower, upper)
        mujoco.mj_step(model, data, nstep=steps_per_command)
    counts = {mujoco.mjtWarning(i).name: data.warning[i].number for i in range(len(data.warning))}
    assert not any(counts.values()), f"MuJoCo warnings: {counts}"
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert data.time == pytest.approx(SIM_SECONDS, abs=model.opt.timestep)


def test_arm_settles_at_the_commanded_pose_less_the_sag_of_its_native_servos(model):
    # The XML's own position servos (a plain mj_step, no project code) are the STS3215
    # linearised: they hold a pose off by gravity torque over their stiffness (hand
    # calculation for the default 12 V C018: the datasheet's 2.94 N m stall over 12 V, times
    # 12 V x 0.004 x 651.9 = 7.67 N m/rad), within a degree of that.
    data = mujoco.MjData(model)
    target = np.array([0.3, -0.5, 0.6, 0.4, -0.8, 0.2])  # [rad], joints in JOINTS order
    for name, value in zip(JOINTS, target, strict=True):
        data.ctrl[model.actuator(name).id] = value
    mujoco.mj_step(model, data, nstep=round(2.0 / model.opt.timestep))
    reached = np.array([data.qpos[model.joint(name).qposadr[0]] for name in JOINTS])
    cfg = {j: math.degrees(v) for j, v in zip(JOINTS, target, strict=True)}
    cfg["gripper"] = 50.0
    torques = holding_torques(cfg)
    sag = np.array([-torques[j] / 7.67 for j in JOINTS])  # [rad]: the joint rests below its goal
    assert abs(sag[1]) > np.radians(2.0)  # the shoulder's sag is no rounding error
    np.testing.assert_allclose(reached, target + sag, atol=np.radians(1.0))


def test_joint_limits_in_the_package_are_the_models(model):
    """The real-arm path knows the limits without MuJoCo: they must be the model's exactly."""
    from so101_kinematics.frames import JOINT_LIMITS, JOINT_RANGES_RAD

    for joint, (lower, upper) in JOINT_RANGES_RAD.items():
        assert (lower, upper) == tuple(map(float, model.joint(joint).range)), joint
    for joint in JOINTS[:-1]:
        lower, upper = model.joint(joint).range
        assert JOINT_LIMITS[joint] == pytest.approx(np.degrees([lower, upper]), abs=1e-12)
    assert JOINT_LIMITS["gripper"] == (0.0, 100.0)


def test_home_pose_is_the_models_home_keyframe_rounded(model):
    from so101_kinematics.constants import HOME_POSE
    from so101_kinematics.sim.scene import get_configuration

    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    home = get_configuration(model, data)
    for joint in JOINTS:
        assert home[joint] == pytest.approx(HOME_POSE[joint], abs=0.1), joint
