"""The two-arm scene: two arms from the course's model, prefixed, placed by the layout."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINTS
from so101_kinematics.sim.scene import load_model
from so101_kinematics.two_arms.two_arm_scene import (
    BASE_RADIUS,
    ArmBase,
    Piece,
    arm_bases,
    base_from_world,
    build_two_arm_model,
    check_bases,
    world_from_base,
)


@pytest.fixture(scope="module")
def model():
    bases = arm_bases("facing", 0.46)
    return build_two_arm_model(bases, (Piece("x_1", 0.0, 0.1, (1.0, 0.0, 0.0, 1.0)),))


def test_each_arm_has_the_courses_joints_and_servos_under_its_prefix(model):
    one = load_model()
    for prefix in ("left_", "right_"):
        for joint in JOINTS:
            assert model.actuator(prefix + joint).trnid[0] == model.joint(prefix + joint).id
            np.testing.assert_allclose(model.joint(prefix + joint).range, one.joint(joint).range)
    assert model.nu == 2 * len(JOINTS)


def test_the_physics_options_are_the_arms_own(model):
    one = load_model()  # model/so101.xml's options: 4 ms, elliptic cones, impratio 100
    assert model.opt.timestep == one.opt.timestep == 0.004
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert model.opt.impratio == one.opt.impratio == 100.0
    assert model.opt.integrator == one.opt.integrator


@pytest.mark.parametrize(("layout", "expected"), [
    ("facing", ((-0.23, 0.0, 0.0), (0.23, 0.0, 180.0))),
    ("side", ((0.0, 0.23, 0.0), (0.0, -0.23, 0.0))),
])
def test_a_layout_places_the_bases_spacing_apart(layout, expected):
    bases = arm_bases(layout, 0.46)
    assert [(b.x, b.y, b.yaw) for b in bases] == [pytest.approx(e) for e in expected]


def test_the_models_bases_stand_where_the_layout_puts_them(model):
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    np.testing.assert_allclose(d.body("left_base").xpos, [-0.23, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(d.body("right_base").xpos, [0.23, 0.0, 0.0], atol=1e-12)
    # the right arm turned half a turn: its base x axis is the world's -x
    np.testing.assert_allclose(d.body("right_base").xmat.reshape(3, 3)[:, 0], [-1.0, 0.0, 0.0],
                               atol=1e-12)


def test_base_frame_and_world_are_inverse_at_seeded_points():
    rng = np.random.default_rng(0)
    for _ in range(20):
        base = ArmBase("left", *rng.uniform(-0.3, 0.3, 2), rng.uniform(-180, 180))
        point = rng.uniform(-0.3, 0.3, 3)
        np.testing.assert_allclose(base_from_world(base, world_from_base(base, point)), point,
                                   atol=1e-12)


def test_the_base_frame_matches_the_models_base_body(model):
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    base = arm_bases("facing", 0.46)[1]
    point = np.array([0.1, 0.05, 0.02])
    g_wb = d.body("right_base")
    np.testing.assert_allclose(world_from_base(base, point),
                               g_wb.xpos + g_wb.xmat.reshape(3, 3) @ point, atol=1e-12)


def test_the_footprint_covers_the_base_meshes():
    m = load_model()
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    farthest = 0.0
    for g in range(m.ngeom):
        if m.geom_bodyid[g] != m.body("base").id or m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        mesh = m.geom_dataid[g]
        start = m.mesh_vertadr[mesh]
        vertices = m.mesh_vert[start:start + m.mesh_vertnum[mesh]]
        points = d.geom_xpos[g] + vertices @ d.geom_xmat[g].reshape(3, 3).T
        farthest = max(farthest, float(np.hypot(points[:, 0], points[:, 1]).max()))
    assert farthest <= BASE_RADIUS < farthest + 0.002


def test_bases_that_overlap_are_refused_in_one_line():
    with pytest.raises(PlanError) as error:
        check_bases(arm_bases("facing", 0.10))
    message = str(error.value)
    assert "\n" not in message and "0.100 m apart" in message and "Fix:" in message
    check_bases(arm_bases("facing", 2 * BASE_RADIUS + 1e-9))  # just apart: accepted


def test_an_unknown_layout_is_refused():
    with pytest.raises(PlanError, match="facing, side"):
        arm_bases("stacked")


def test_a_piece_rests_on_the_table_at_its_place(model):
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    assert d.body("x_1").xpos[:2] == pytest.approx([0.0, 0.1])
    assert math.isclose(d.body("x_1").xpos[2], 0.013)
