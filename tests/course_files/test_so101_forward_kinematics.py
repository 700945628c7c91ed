"""Forward kinematics against MuJoCo, the seed's composition, and the object frame's meaning."""

from __future__ import annotations

import doctest
import math

import mujoco
import numpy as np
import pytest
from conftest import assert_transforms_close

import so101_forward_kinematics as fk
from so101_kinematics.frames import (
    BODY_OF_FRAME,
    FIXED_ROTATION,
    FRAMES,
    GRIPPER_MOUNT_TILT_DEG,
    Rx,
    Ry,
    Rz,
    get_frame_chain,
    joint_angles,
)
from so101_mujoco_utils import joint_limits

N_CONFIGURATIONS = 1000
TOLERANCE = 1e-9  # [m] and [rad]
STARTING_CONFIGURATION = {"shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0,
                          "wrist_flex": 90.0, "wrist_roll": 0.0, "gripper": 50.0}


def random_configurations(model, n: int, seed: int) -> np.ndarray:
    """(n, 5) arm angles [deg], uniform within the model's joint limits."""
    limits = joint_limits(model)
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(*limits[j], n) for j in fk.ARM_JOINTS])


def as_dict(angles) -> dict[str, float]:
    return {joint: float(a) for joint, a in zip(fk.ARM_JOINTS, angles, strict=True)}


def set_arm(model, data, angles_deg) -> None:
    for joint, angle in zip(fk.ARM_JOINTS, angles_deg, strict=True):
        data.qpos[model.joint(joint).qposadr[0]] = math.radians(angle)
    mujoco.mj_kinematics(model, data)


def homogeneous(position, rotation) -> np.ndarray:
    g = np.zeros(np.shape(position)[:-1] + (4, 4))
    g[..., :3, :3] = rotation
    g[..., :3, 3] = position
    g[..., 3, 3] = 1.0
    return g


def pose_errors(g_actual: np.ndarray, g_expected: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and rotation [rad] errors of stacked (..., 4, 4) poses."""
    pos = np.linalg.norm(g_actual[..., :3, 3] - g_expected[..., :3, 3], axis=-1)
    r = np.swapaxes(g_actual[..., :3, :3], -1, -2) @ g_expected[..., :3, :3]
    skew = np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0],
                     r[..., 1, 0] - r[..., 0, 1]], axis=-1)
    cos = (np.trace(r, axis1=-2, axis2=-1) - 1.0) / 2.0
    rot = np.arctan2(0.5 * np.linalg.norm(skew, axis=-1), cos)
    return pos, rot


def assert_all_close(g_actual, g_expected, labels) -> None:
    """Vectorised check; the worst pose goes through conftest's helper for its message."""
    pos, rot = pose_errors(g_actual, g_expected)
    for errors in (pos, rot):
        worst = np.unravel_index(np.argmax(errors), errors.shape)
        assert_transforms_close(g_actual[worst], g_expected[worst], TOLERANCE, TOLERANCE,
                                label=labels(worst))
    assert pos.max() <= TOLERANCE and rot.max() <= TOLERANCE


@pytest.fixture(scope="module")
def samples(model):
    """FK chains and MuJoCo poses at N seeded random in-limit configurations."""
    data = mujoco.MjData(model)
    angles = random_configurations(model, N_CONFIGURATIONS, seed=20260101)
    frames = FRAMES[1:]
    n = len(angles)
    fk_chain = np.empty((n, len(frames), 4, 4))
    mj_chain = np.empty((n, len(frames), 4, 4))
    for i, a in enumerate(angles):
        set_arm(model, data, a)
        chain = get_frame_chain(as_dict(a))
        for k, frame in enumerate(frames):
            fk_chain[i, k] = chain[frame]
            if frame == "t":
                site = data.site(fk.TOOL_SITE)
                mj_chain[i, k] = homogeneous(site.xpos, site.xmat.reshape(3, 3))
            else:
                body = data.body(BODY_OF_FRAME[frame])
                mj_chain[i, k] = homogeneous(body.xpos, body.xmat.reshape(3, 3))
    return angles, fk_chain, mj_chain


def test_every_frame_matches_mujoco_at_random_configurations(samples):
    angles, fk_chain, mj_chain = samples
    frames = FRAMES[1:]
    assert_all_close(fk_chain, mj_chain,
                     lambda idx: f"frame {frames[idx[1]]} at {as_dict(angles[idx[0]])}:")


def test_single_fk_matches_mujoco_object_frame(samples):
    angles, _, mj_chain = samples
    g = np.array([homogeneous(*fk.get_forward_kinematics(as_dict(a))) for a in angles])
    assert_all_close(g, mj_chain[:, -1], lambda idx: f"tool at {as_dict(angles[idx[0]])}:")


def test_batch_fk_matches_mujoco_object_frame(samples):
    angles, _, mj_chain = samples
    positions, rotations = fk.get_forward_kinematics_batch(angles, chunk=97)  # several chunks
    assert_all_close(homogeneous(positions, rotations), mj_chain[:, -1],
                     lambda idx: f"batch tool at {as_dict(angles[idx[0]])}:")


def test_batch_equals_single_also_outside_the_limits():
    rng = np.random.default_rng(7)
    angles = rng.uniform(-360.0, 360.0, (300, 5))  # the whole ANGLE_RANGE_DEG
    angles[:20] = np.round(angles[:20] / 90.0) * 90.0  # exact quarter turns, incl. +-180
    positions, rotations = fk.get_forward_kinematics_batch(angles)
    for a, p_batch, r_batch in zip(angles, positions, rotations, strict=True):
        p, r = fk.get_forward_kinematics(as_dict(a))
        np.testing.assert_allclose(p_batch, p, rtol=0, atol=1e-14)
        np.testing.assert_allclose(r_batch, r, rtol=0, atol=1e-14)


def test_batch_handles_empty_and_single_rows():
    positions, rotations = fk.get_forward_kinematics_batch(np.empty((0, 5)))
    assert positions.shape == (0, 3) and rotations.shape == (0, 3, 3)
    cfg = as_dict([10.0, -20.0, 30.0, -40.0, 50.0])
    positions, rotations = fk.get_forward_kinematics_batch([list(cfg.values())])
    p, r = fk.get_forward_kinematics(cfg)
    np.testing.assert_allclose(positions[0], p, atol=1e-14)
    np.testing.assert_allclose(rotations[0], r, atol=1e-14)


def test_closed_form_equals_the_course_product_over_1000_random_configurations():
    """The package's fast path is the course's product, to 1e-12 (the layout issue's bar)."""
    from so101_kinematics.fast_fk import forward_kinematics, forward_kinematics_batch

    rng = np.random.default_rng(1000)
    angles = rng.uniform(-360.0, 360.0, (1000, 5))
    positions, rotations = forward_kinematics_batch(angles)
    for a, batch_p, batch_r in zip(angles, positions, rotations, strict=True):
        product_p, product_r = fk.get_forward_kinematics(as_dict(a))
        fast_p, fast_r = forward_kinematics(as_dict(a))
        for p, r in ((fast_p, fast_r), (batch_p, batch_r)):
            np.testing.assert_allclose(p, product_p, rtol=0, atol=1e-12)
            np.testing.assert_allclose(r, product_r, rtol=0, atol=1e-12)


def test_get_forward_kinematics_is_the_literal_product_of_the_six_factors():
    """The graded function multiplies get_gw1 ... get_g5t: a wrong factor changes its result."""
    import inspect

    source = inspect.getsource(fk.get_forward_kinematics)
    assert "gwt = gw1 @ g12 @ g23 @ g34 @ g45 @ g5t" in source
    cfg = as_dict([10.0, 20.0, 30.0, 40.0, 50.0])
    before, _ = fk.get_forward_kinematics(cfg)
    original = fk.get_g34
    try:
        fk.get_g34 = lambda theta: original(theta + 1.0)  # a student's wrong factor
        after, _ = fk.get_forward_kinematics(cfg)
    finally:
        fk.get_g34 = original
    assert np.linalg.norm(after - before) > 1e-3


def test_seed_style_composition_equals_get_forward_kinematics():
    rng = np.random.default_rng(11)
    angles = np.vstack([rng.uniform(-180.0, 180.0, (200, 5)),
                        rng.integers(-4, 5, (50, 5)) * 90.0])
    for a in angles:
        cfg = as_dict(a)
        g_wt = (fk.get_gw1(cfg["shoulder_pan"]) @ fk.get_g12(cfg["shoulder_lift"])
                @ fk.get_g23(cfg["elbow_flex"]) @ fk.get_g34(cfg["wrist_flex"])
                @ fk.get_g45(cfg["wrist_roll"]) @ fk.get_g5t())
        position, rotation = fk.get_forward_kinematics(cfg)
        np.testing.assert_allclose(position, g_wt[:3, 3], rtol=0, atol=1e-14)
        np.testing.assert_allclose(rotation, g_wt[:3, :3], rtol=0, atol=1e-14)
        np.testing.assert_allclose(get_frame_chain(cfg)["t"], g_wt, rtol=0, atol=1e-14)


def test_elementary_rotations_follow_the_right_hand_rule():
    np.testing.assert_allclose(Rz(90.0) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(Rx(90.0) @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(Ry(90.0) @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], atol=1e-15)
    for rot in (Rx, Ry, Rz):
        r = rot(33.3)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        np.testing.assert_allclose(rot(-33.3), r.T, atol=1e-15)


def test_gripper_mount_tilt_is_the_upstream_quaternion(model):
    # The gripper body's fixed rotation in MuJoCo is the normalised upstream quaternion.
    quat = model.body("gripper").quat
    expected = np.empty(9)
    mujoco.mju_quat2Mat(expected, quat)
    g45 = fk.get_g45(0.0)
    np.testing.assert_allclose(g45[:3, :3], expected.reshape(3, 3), rtol=0, atol=1e-15)
    assert -2.8 < GRIPPER_MOUNT_TILT_DEG < -2.78


def test_starting_configuration_holds_the_cube_just_above_the_table(model):
    position, rotation = fk.get_forward_kinematics(STARTING_CONFIGURATION)
    assert 0.010 <= position[2] <= 0.025, f"object height {position[2]:.4f} m"
    # Top-down grasp in the course's convention: the object frame is Rz(yaw), z up, with
    # yaw = wrist_roll - shoulder_pan + the gripper mount's tilt (upstream quaternion).
    np.testing.assert_allclose(rotation[:, 2], [0.0, 0.0, 1.0], atol=1e-12)
    tilt = math.degrees(2.0 * math.atan2(-0.0172091, 0.706897))
    yaw = math.radians(STARTING_CONFIGURATION["wrist_roll"]
                       - STARTING_CONFIGURATION["shoulder_pan"] + tilt)
    c, s = math.cos(yaw), math.sin(yaw)
    np.testing.assert_allclose(rotation, [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], atol=1e-12)
    # The acceptance: within 3 deg of Rz(roll - pan), the course's diagram (no tilt).
    course = math.radians(STARTING_CONFIGURATION["wrist_roll"]
                          - STARTING_CONFIGURATION["shoulder_pan"])
    off = math.degrees(abs(math.atan2(rotation[1, 0], rotation[0, 0]) - course))
    assert 2.7 < off < 3.0
    # ... and so is the gripper body's (wrist_roll) axis: the gripper is vertical.
    g_w5 = get_frame_chain(STARTING_CONFIGURATION)["5"]
    assert abs(abs(g_w5[2, 2]) - 1.0) < 1e-12
    # Heights are above the table: the scene's table top is the plane z = 0.
    assert model.geom("table").pos[2] == 0.0
    # The final configuration (pan +45) places the cube at the same height.
    final_position, _ = fk.get_forward_kinematics(dict(STARTING_CONFIGURATION, shoulder_pan=45.0))
    assert final_position[2] == pytest.approx(position[2], abs=1e-12)


@pytest.fixture
def posed(model):
    """MuJoCo data at a few configurations (the start and random ones)."""
    data = mujoco.MjData(model)
    angles = np.vstack([[STARTING_CONFIGURATION[j] for j in fk.ARM_JOINTS],
                        random_configurations(model, 8, seed=5)])
    return data, angles


def test_object_z_axis_points_from_the_fingertips_to_the_wrist(model, posed):
    data, angles = posed
    for a in angles:
        set_arm(model, data, a)
        _, rotation = fk.get_forward_kinematics(as_dict(a))
        z = rotation[:, 2]
        # Parallel to the wrist_roll axis (the gripper's long axis) ...
        roll_axis = data.joint("wrist_roll").xaxis
        assert abs(abs(z @ roll_axis) - 1.0) < 1e-9
        # ... and pointing from the fixed jaw's tip back toward the wrist (up when top-down).
        toward_wrist = data.body("wrist").xpos - data.site("gripperframe").xpos
        assert z @ toward_wrist / np.linalg.norm(toward_wrist) > 0.9


def test_object_x_axis_points_from_the_fixed_jaw_to_the_moving_one(model, posed):
    data, angles = posed
    lower, upper = model.joint("gripper").range
    adr = model.joint("gripper").qposadr[0]
    pad = model.geom("moving_jaw_pad").id
    for a in angles:
        position, rotation = fk.get_forward_kinematics(as_dict(a))
        x = rotation[:, 0]
        # Close the jaw from fully open to fully closed: the pad moves in the x-z plane of the
        # object frame, always toward -x (the fixed jaw), near the grasp (the last 30 %) along x.
        previous = None
        for percent in np.linspace(100.0, 0.0, 11):
            data.qpos[adr] = lower + (upper - lower) * percent / 100.0
            set_arm(model, data, a)
            current = data.geom_xpos[pad].copy()
            if previous is not None:
                step = (current - previous) / np.linalg.norm(current - previous)
                assert step @ x < 0.0
                assert abs(step @ rotation[:, 1]) < 1e-9
                if percent < 30.0:
                    assert step @ x < -0.9, f"closing at {percent:.0f} % is not along -x"
            previous = current
        # The fixed jaw's pad face holds the cube's near side: half a cube along -x.
        fixed = model.geom("fixed_jaw_pad")
        centre = data.geom_xpos[fixed.id]
        inner_face = (position - centre) @ x - fixed.size[0]
        assert inner_face == pytest.approx(0.013, abs=1e-4)


def test_object_frame_is_right_handed(samples):
    _, fk_chain, _ = samples
    r = fk_chain[:, -1, :3, :3]
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(r[:, :, 0], r[:, :, 1]), r[:, :, 2], atol=1e-12)


# --- Bad input -------------------------------------------------------------------------

GOOD = {"shoulder_pan": 0.0, "shoulder_lift": 0.0, "elbow_flex": 0.0, "wrist_flex": 0.0,
        "wrist_roll": 0.0}
FK_FUNCTIONS = (fk.get_forward_kinematics, get_frame_chain, joint_angles)


@pytest.mark.parametrize("function", FK_FUNCTIONS, ids=lambda f: f.__name__)
@pytest.mark.parametrize("joint", fk.ARM_JOINTS)
def test_missing_joint_is_named(function, joint):
    cfg = {k: v for k, v in GOOD.items() if k != joint}
    with pytest.raises(ValueError, match=f"'{joint}'"):
        function(cfg)


@pytest.mark.parametrize("function", FK_FUNCTIONS, ids=lambda f: f.__name__)
@pytest.mark.parametrize("value", ["45", None, [1.0], True, float("nan"), float("inf"),
                                   -float("inf"), 10**400],
                         ids=["text", "None", "list", "bool", "nan", "inf", "-inf", "huge-int"])
def test_bad_value_is_refused_naming_the_joint(function, value):
    cfg = dict(GOOD, elbow_flex=value)
    with pytest.raises(ValueError, match="'elbow_flex'"):
        function(cfg)


def test_numpy_and_integer_values_are_accepted():
    cfg = dict(GOOD, shoulder_pan=np.float32(-45.0), shoulder_lift=np.int64(45),
               elbow_flex=-45, wrist_flex=np.float64(90.0))
    position, _ = fk.get_forward_kinematics(cfg)
    expected, _ = fk.get_forward_kinematics(
        dict(GOOD, shoulder_pan=-45.0, shoulder_lift=45.0, elbow_flex=-45.0, wrist_flex=90.0))
    np.testing.assert_array_equal(position, expected)


def test_not_a_mapping_is_refused():
    with pytest.raises(ValueError, match="'shoulder_pan'"):
        fk.get_forward_kinematics([0.0] * 5)


def test_gripper_is_ignored():
    a, ra = fk.get_forward_kinematics(dict(GOOD, gripper=0.0))
    b, rb = fk.get_forward_kinematics(dict(GOOD, gripper=100.0))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ra, rb)


@pytest.mark.parametrize("bad", [np.zeros((3, 4)), np.zeros(5), np.zeros((2, 5, 1))])
def test_batch_refuses_wrong_shape(bad):
    with pytest.raises(ValueError, match=r"\(N, 5\)"):
        fk.get_forward_kinematics_batch(bad)


def test_batch_names_the_non_finite_joint_and_row():
    angles = np.zeros((4, 5))
    angles[2, 3] = np.nan
    with pytest.raises(ValueError, match=r"'wrist_flex' of configuration 2"):
        fk.get_forward_kinematics_batch(angles)
    with pytest.raises(ValueError, match="numbers"):
        fk.get_forward_kinematics_batch([["a"] * 5])


def test_module_docstring_example_runs():
    result = doctest.testmod(fk, verbose=False)
    assert result.attempted >= 2
    assert result.failed == 0


def test_closed_form_guard_notices_a_changed_fixed_rotation(monkeypatch):
    from so101_kinematics import fast_fk

    changed = dict(FIXED_ROTATION, **{"34": Rz(-90.0) @ Rx(1.0)})
    monkeypatch.setattr(fast_fk, "FIXED_ROTATION", changed)
    with pytest.raises(RuntimeError, match="g_34"):
        fast_fk._closed_form_assumptions()
