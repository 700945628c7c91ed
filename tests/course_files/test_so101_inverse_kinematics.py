"""Inverse kinematics: FK round trips, reachability, errors, Jacobian and the Cartesian plan."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

import so101_inverse_kinematics as ik
import so101_kinematics.planning.cartesian_plan as cp
import so101_kinematics.planning.plans as plans
from so101_forward_kinematics import ARM_JOINTS, JOINTS, get_forward_kinematics, get_gw1
from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINT_LIMITS, JOINT_RANGES_RAD
from so101_kinematics.ik.geometry import MIN_HEIGHT, get_jacobian
from so101_kinematics.ik.solver import sample_top_down_targets

POSITION_TOL = 1e-6   # [m], the acceptance
ANGLE_TOL = 1e-6      # [rad]
UP = np.array([0.0, 0.0, 1.0])  # the object frame's z at a top-down grasp (the course's)


def cfg_from(angles_deg) -> dict[str, float]:
    return {joint: float(value) for joint, value in zip(ARM_JOINTS, angles_deg, strict=True)}


def yaw_of(rotation) -> float:
    """Cube yaw [rad] of a tool rotation (angle of the jaw axis from world x)."""
    return math.atan2(rotation[1, 0], rotation[0, 0])


def yaw_error(rotation, yaw_deg: float) -> float:
    """Angle [rad] from the jaw axis to the nearest face normal of a cube at ``yaw_deg``."""
    delta = yaw_of(rotation) - math.radians(yaw_deg)
    return abs((delta + math.pi / 4) % (math.pi / 2) - math.pi / 4)


def tilt(rotation, wanted=UP) -> float:
    """Angle [rad] between the object frame's z axis and ``wanted``."""
    z_t = rotation[:, 2]
    return math.atan2(np.linalg.norm(np.cross(z_t, wanted)), float(z_t @ wanted))


def assert_in_limits(cfg):
    for joint in ARM_JOINTS:
        lower, upper = JOINT_LIMITS[joint]
        assert lower <= cfg[joint] <= upper, f"{joint} = {cfg[joint]} outside [{lower}, {upper}]"


def random_configurations(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lower = [JOINT_LIMITS[j][0] for j in ARM_JOINTS]
    upper = [JOINT_LIMITS[j][1] for j in ARM_JOINTS]
    return rng.uniform(lower, upper, size=(n, len(ARM_JOINTS)))


# --- Limits and independence from MuJoCo ------------------------------------------------
def test_joint_limits_are_the_models(model):
    from so101_mujoco_utils import joint_limits

    model_limits = joint_limits(model)
    for joint in ARM_JOINTS:
        assert JOINT_LIMITS[joint] == pytest.approx(model_limits[joint], abs=1e-12)
        assert JOINT_RANGES_RAD[joint] == pytest.approx(tuple(model.joint(joint).range), abs=0)


def test_solving_does_not_import_mujoco():
    code = ("import sys; import so101_inverse_kinematics as ik; "
            "ik.get_inverse_kinematics((0.25, 0.0, 0.013)); "
            "ik.get_inverse_kinematics((0.25, 0.0, 0.1), approach=None); "
            "assert 'mujoco' not in sys.modules, 'mujoco was imported'")
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


# --- The course's configurations ---------------------------------------------------------
@pytest.mark.parametrize("configuration", [plans.STARTING_CONFIGURATION,
                                           plans.FINAL_CONFIGURATION])
def test_assignment_configurations_come_back(configuration):
    position, rotation = get_forward_kinematics(configuration)
    for yaw in (None, math.degrees(yaw_of(rotation))):
        cfg = ik.get_inverse_kinematics(position, approach="down", yaw_deg=yaw)
        for joint in ARM_JOINTS:
            assert cfg[joint] == pytest.approx(configuration[joint], abs=1e-9), joint
    assert cfg["gripper"] == ik.GRIPPER_OPEN


def test_closed_form_is_exact_without_refinement(monkeypatch):
    """Every offset is in the closed form: it hits the targets without the numerical step."""
    def no_refinement(*args, **kwargs):
        raise AssertionError("the closed form needed a numerical refinement")

    from so101_kinematics.ik import refine, solver

    monkeypatch.setattr(refine, "_refine", no_refinement)  # both places that call it
    monkeypatch.setattr(solver, "_refine", no_refinement)
    _, positions, yaws = sample_top_down_targets(3000, seed=11)
    assert len(positions) > 100
    for position, yaw in zip(positions[:200], yaws[:200], strict=True):
        cfg = ik.get_inverse_kinematics(position, approach="down", yaw_deg=float(yaw))
        got, rotation = get_forward_kinematics(cfg)
        assert np.abs(got - position).max() < 1e-12
        assert tilt(rotation) < 1e-12
        assert yaw_error(rotation, yaw) < 1e-12


# --- Round trips over the table ---------------------------------------------------------
def table_grid(height: float, step: float = 0.02):
    xs = np.arange(-0.12, 0.38 + 1e-9, step)
    ys = np.arange(-0.34, 0.34 + 1e-9, step)
    return [(x, y, height) for x in xs for y in ys]


@pytest.mark.parametrize("height", [CUBE_HALF_SIZE, 0.06])
def test_top_down_round_trip_over_the_table(height):
    """FK(IK(p)) = p and the approach is vertical with the asked yaw, over a grid of the table."""
    rng = np.random.default_rng(7)
    solved = 0
    for point in table_grid(height):
        yaw = float(rng.uniform(-180.0, 180.0))
        try:
            cfg = ik.get_inverse_kinematics(point, approach="down", yaw_deg=yaw)
        except ik.UnreachableError:
            # On the table, the course's working area (the ring below) is all reachable.
            assert height > CUBE_HALF_SIZE or not in_working_ring(point), point
            continue
        solved += 1
        assert_in_limits(cfg)
        position, rotation = get_forward_kinematics(cfg)
        assert np.abs(position - point).max() < POSITION_TOL
        assert tilt(rotation) < ANGLE_TOL
        assert yaw_error(rotation, yaw) < ANGLE_TOL
    assert solved > 200  # the grid covers the reachable area (see docs/workspace.png)


PAN_AXIS_XY = get_gw1(0.0)[:2, 3]  # the shoulder_pan axis, from the course's first factor


def in_working_ring(point) -> bool:
    """The course's working area: 14-26 cm from the pan axis, within 100 deg of straight ahead."""
    dx, dy = point[0] - PAN_AXIS_XY[0], point[1] - PAN_AXIS_XY[1]
    return 0.14 <= math.hypot(dx, dy) <= 0.26 and abs(math.degrees(math.atan2(dy, dx))) <= 100.0


def test_a_ring_around_the_base_is_reachable_top_down():
    """The course's working area: 14-26 cm from the pan axis, within 100 deg of straight ahead."""
    rng = np.random.default_rng(3)
    centre = PAN_AXIS_XY
    for _ in range(300):
        radius, azimuth = rng.uniform(0.14, 0.26), math.radians(rng.uniform(-100.0, 100.0))
        point = (*(centre + radius * np.array([math.cos(azimuth), math.sin(azimuth)])),
                 CUBE_HALF_SIZE)
        cfg = ik.get_inverse_kinematics(point, approach="down", yaw_deg=None)
        position, rotation = get_forward_kinematics(cfg)
        assert np.abs(position - point).max() < POSITION_TOL
        assert tilt(rotation) < ANGLE_TOL


# --- Targets known to be reachable: FK of random in-limit configurations -----------------
def test_every_reachable_top_down_target_is_solved():
    angles, positions, yaws = sample_top_down_targets(20000, seed=1)
    assert len(positions) > 400
    for angle, position, yaw in zip(angles, positions, yaws, strict=True):
        for wanted_yaw in (float(yaw), None):
            cfg = ik.get_inverse_kinematics(position, approach="down", yaw_deg=wanted_yaw,
                                            initial=None)
            assert_in_limits(cfg)
            got, rotation = get_forward_kinematics(cfg)
            assert np.abs(got - position).max() < POSITION_TOL, angle
            assert tilt(rotation) < ANGLE_TOL, angle
            if wanted_yaw is not None:
                assert yaw_error(rotation, wanted_yaw) < ANGLE_TOL, angle


def test_every_reachable_position_is_solved():
    for angles in random_configurations(4000, seed=2):
        position, _ = get_forward_kinematics(cfg_from(angles))
        if position[2] < MIN_HEIGHT:
            continue
        cfg = ik.get_inverse_kinematics(position, approach=None)
        assert_in_limits(cfg)
        got, _ = get_forward_kinematics(cfg)
        assert np.abs(got - position).max() < POSITION_TOL, angles


def test_every_reachable_pitched_target_is_solved():
    """Position plus the approach's pitch (from the arm's own pitch and facing)."""
    centre = PAN_AXIS_XY
    for angles in random_configurations(3000, seed=4):
        cfg = cfg_from(angles)
        position, rotation = get_forward_kinematics(cfg)
        if position[2] < MIN_HEIGHT:
            continue
        arm_pitch = angles[1] + angles[2] + angles[3]
        heading = np.array([math.cos(math.radians(angles[0])), -math.sin(math.radians(angles[0]))])
        pitch = arm_pitch if heading @ (position[:2] - centre) >= 0.0 else 180.0 - arm_pitch
        pitch = (pitch + 180.0) % 360.0 - 180.0  # the same approach, within ANGLE_RANGE_DEG
        solved = ik.get_inverse_kinematics(position, approach="pitch", yaw_deg=None,
                                           pitch_deg=pitch)
        assert_in_limits(solved)
        got, got_rotation = get_forward_kinematics(solved)
        assert np.abs(got - position).max() < POSITION_TOL, angles
        # The approach has the asked elevation (the z component of tool z).
        assert abs(got_rotation[2, 2] - rotation[2, 2]) < ANGLE_TOL, angles


def test_pitch_90_is_the_top_down_grasp():
    point = (0.25, -0.05, 0.03)
    for yaw in (None, 30.0):
        down = ik.get_inverse_kinematics(point, approach="down", yaw_deg=yaw)
        pitched = ik.get_inverse_kinematics(point, approach="pitch", yaw_deg=yaw, pitch_deg=90.0)
        assert down == pytest.approx(pitched, abs=1e-9)


def test_initial_picks_the_nearest_solution():
    """Both elbow branches reach this target in limits; the one nearest ``initial`` wins."""
    point = (0.36, 0.0, 0.013)
    lifts = []
    for lift, elbow, wrist in ((55.0, -60.0, 80.0), (70.0, -88.0, 93.0)):
        hint = {"shoulder_pan": 0.0, "shoulder_lift": lift, "elbow_flex": elbow,
                "wrist_flex": wrist, "wrist_roll": 0.0, "gripper": 20.0}
        cfg = ik.get_inverse_kinematics(point, approach="pitch", yaw_deg=None, pitch_deg=75.0,
                                        initial=hint)
        assert cfg["shoulder_lift"] == pytest.approx(lift, abs=1.0)
        assert cfg["elbow_flex"] == pytest.approx(elbow, abs=1.0)
        assert cfg["gripper"] == 20.0
        got, rotation = get_forward_kinematics(cfg)
        assert np.abs(got - point).max() < POSITION_TOL
        assert rotation[2, 2] == pytest.approx(math.sin(math.radians(75.0)), abs=ANGLE_TOL)
        lifts.append(cfg["shoulder_lift"])
    assert lifts[1] - lifts[0] > 10.0


# --- Unreachable targets ---------------------------------------------------------------
def test_too_far_says_by_how_much():
    with pytest.raises(ik.UnreachableError, match=r"mm beyond the arm's reach") as near:
        ik.get_inverse_kinematics((0.40, 0.0, 0.013))
    with pytest.raises(ik.UnreachableError) as far:
        ik.get_inverse_kinematics((0.45, 0.0, 0.013))
    assert near.value.reason == far.value.reason == "too_far"
    assert near.value.distance > 0.0
    # 5 cm further along the arm's plane is 5 cm further out of reach.
    assert far.value.distance - near.value.distance == pytest.approx(0.05, abs=2e-3)
    assert f"{far.value.distance * 1e3:.1f} mm" in str(far.value)


@pytest.mark.parametrize("target, way, not_way", [
    ((0.0, 0.0, 0.60), "lower (down)", "closer"),  # straight above the base, too high
    ((0.1, 0.0, 0.60), "lower (down)", "closer"),
    ((0.45, 0.0, 0.013), "closer to the base", "lower"),  # on the table, too far out
    ((0.30, 0.0, 0.40), "lower and closer to the base", "higher"),  # both
])
def test_too_far_says_which_way_to_move_the_target(target, way, not_way):
    """Issue 28: a target too high, even straight above the base, was told to come closer."""
    with pytest.raises(ik.UnreachableError) as error:
        ik.get_inverse_kinematics(target)
    fix = str(error.value).split("Fix: ")[1]
    assert error.value.reason == "too_far"
    assert fix.startswith(f"move the target {way}") and not_way not in fix, fix


def test_position_only_too_far():
    with pytest.raises(ik.UnreachableError, match="beyond the arm's reach") as error:
        ik.get_inverse_kinematics((0.70, 0.1, 0.2), approach=None)
    assert error.value.reason == "too_far"
    assert 0.1 < error.value.distance < 0.4


def test_below_the_table():
    with pytest.raises(ik.UnreachableError, match=r"5\.0 mm below") as error:
        ik.get_inverse_kinematics((0.25, 0.0, MIN_HEIGHT - 0.005))
    assert error.value.reason == "below_table"
    assert error.value.distance == pytest.approx(0.005)
    cfg = ik.get_inverse_kinematics((0.25, 0.0, 0.005), min_height=0.0)  # allowed when asked
    assert get_forward_kinematics(cfg)[0][2] == pytest.approx(0.005)


def test_too_close_to_the_pan_axis():
    # 0.1 mm from the pan axis: the arm's plane, offset sideways by the
    # shoulder, wrist and tool, cannot pass through the target with any of
    # the rolls a cube yaw of 45 deg asks for (about 3.6 mm off the axis).
    point = (PAN_AXIS_XY[0] + 1e-4, PAN_AXIS_XY[1], 0.25)
    with pytest.raises(ik.UnreachableError, match="too close to the shoulder_pan axis") as error:
        ik.get_inverse_kinematics(point, approach="down", yaw_deg=45.0)
    assert error.value.reason == "too_close"
    assert error.value.distance == pytest.approx(0.0035, abs=0.0005)


def test_near_the_base_the_wrist_cannot_fold_enough():
    with pytest.raises(ik.UnreachableError, match="wrist_flex") as error:
        ik.get_inverse_kinematics((0.09, 0.0, 0.05), approach=None)
    assert error.value.reason == "joint_limit"
    assert error.value.joint == "wrist_flex"
    assert error.value.distance > 0.0


def test_joint_limit_names_joint_value_and_limit():
    # Behind the base: shoulder_pan would have to turn past its limit.
    with pytest.raises(ik.UnreachableError) as error:
        ik.get_inverse_kinematics((-0.15, 0.1, 0.05))
    message = str(error.value)
    assert error.value.reason == "joint_limit"
    joint = error.value.joint
    assert joint in ARM_JOINTS and joint in message
    assert "deg" in message and "limit" in message and "Fix:" in message
    assert error.value.distance > 0.0
    # Near the base, top-down: the wrist cannot fold far enough.
    with pytest.raises(ik.UnreachableError) as error:
        ik.get_inverse_kinematics((0.07, 0.0, 0.013))
    assert error.value.reason == "joint_limit"
    assert error.value.joint in str(error.value)
    limits = JOINT_LIMITS[error.value.joint]
    printed = [f"{limit:.5f}".rstrip("0").rstrip(".") for limit in limits]  # to 5 decimals
    assert any(f"beyond its limit {text} deg" in str(error.value) for text in printed)


def test_unreachable_error_is_a_plan_error():
    assert issubclass(ik.UnreachableError, PlanError)
    assert issubclass(ik.UnreachableError, ValueError)


@pytest.mark.parametrize("kwargs, match", [
    ({"position": (0.2, 0.0)}, "three numbers"),
    ({"position": (0.2, 0.0, float("nan"))}, "finite"),
    ({"position": (0.2, 0.0, 0.05), "approach": "sideways"}, "approach must be"),
    ({"position": (0.2, 0.0, 0.05), "approach": "pitch"}, "pitch_deg"),
    ({"position": (0.2, 0.0, 0.05), "pitch_deg": 45.0}, "approach='pitch'"),
    ({"position": (0.2, 0.0, 0.05), "yaw_deg": float("inf")}, "yaw_deg"),
])
def test_malformed_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ik.get_inverse_kinematics(**kwargs)


# --- Jacobian --------------------------------------------------------------------------
def rotation_log(rotation) -> np.ndarray:
    """Rotation vector [rad] of a small rotation."""
    skew = 0.5 * (rotation - rotation.T)
    return np.array([skew[2, 1], skew[0, 2], skew[1, 0]])


def test_jacobian_matches_finite_differences_of_the_fk():
    step = 1e-6  # [rad]
    for angles in random_configurations(25, seed=5):
        cfg = cfg_from(angles)
        jac = get_jacobian(cfg)
        assert jac.shape == (6, 5)
        _, rotation = get_forward_kinematics(cfg)
        for j, joint in enumerate(ARM_JOINTS):
            plus = dict(cfg, **{joint: cfg[joint] + math.degrees(step)})
            minus = dict(cfg, **{joint: cfg[joint] - math.degrees(step)})
            (p_plus, r_plus), (p_minus, r_minus) = (get_forward_kinematics(plus),
                                                    get_forward_kinematics(minus))
            linear = (p_plus - p_minus) / (2 * step)
            angular = (rotation_log(r_plus @ rotation.T)
                       - rotation_log(r_minus @ rotation.T)) / (2 * step)
            np.testing.assert_allclose(jac[:3, j], linear, atol=1e-8, err_msg=joint)
            np.testing.assert_allclose(jac[3:, j], angular, atol=1e-8, err_msg=joint)


def test_jacobian_matches_mujoco(model, data):
    import mujoco

    site = model.site("object_frame").id
    qpos = [int(model.joint(j).qposadr[0]) for j in ARM_JOINTS]
    dofs = [int(model.joint(j).dofadr[0]) for j in ARM_JOINTS]
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    for angles in random_configurations(25, seed=6):
        data.qpos[:] = 0.0
        data.qpos[qpos] = np.radians(angles)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        jac = get_jacobian(cfg_from(angles))
        np.testing.assert_allclose(jac[:3], jacp[:, dofs], atol=1e-12)
        np.testing.assert_allclose(jac[3:], jacr[:, dofs], atol=1e-12)


# --- Cartesian pick-and-place ------------------------------------------------------------
def assignment_positions():
    pick, _ = get_forward_kinematics(plans.STARTING_CONFIGURATION)
    place, _ = get_forward_kinematics(plans.FINAL_CONFIGURATION)
    return pick, place


def test_cartesian_plan_has_the_default_plans_waypoints():
    plan = cp.cartesian_plan(*assignment_positions())
    default = plans.default_plan()
    assert [s.name for s in plan.steps] == [s.name for s in default.steps]
    timing = [(s.duration, s.hold) for s in plan.steps]
    assert timing == [(s.duration, s.hold) for s in default.steps]
    assert plan.return_to_start == default.return_to_start
    assert plan.return_duration == default.return_duration
    plans.validate_plan(plan, {**JOINT_LIMITS, "gripper": (0.0, 100.0)})
    for step in plan.steps:
        assert list(step.configuration) == list(JOINTS)


@pytest.mark.parametrize("cube_yaw", [None, "assignment"])
def test_cartesian_plan_reproduces_the_assignment(cube_yaw):
    pick, place = assignment_positions()
    if cube_yaw == "assignment":  # the yaw the course's cubes have (FK of its configuration)
        _, rotation = get_forward_kinematics(plans.STARTING_CONFIGURATION)
        cube_yaw = math.degrees(yaw_of(rotation))
    plan = cp.cartesian_plan(pick, place, cube_yaw_deg=cube_yaw).configurations()
    default = plans.default_plan().configurations()
    for name in ("start_open", "start_closed", "final_closed", "final_open"):
        for joint in JOINTS:
            assert plan[name][joint] == pytest.approx(default[name][joint], abs=1e-6), (name, joint)


def test_cartesian_plan_waypoints_are_where_asked():
    pick, place = np.array([0.20, 0.12, 0.013]), np.array([0.24, -0.10, 0.013])
    lift_height = 0.07
    plan = cp.cartesian_plan(pick, place, cube_yaw_deg=20.0, lift_height=lift_height,
                             move_duration=3.0, hold_duration=0.2).configurations()
    expected = {"start_open": pick, "start_closed": pick, "lift": pick + [0, 0, lift_height],
                "carry": place + [0, 0, lift_height], "final_closed": place, "final_open": place}
    for name, target in expected.items():
        position, rotation = get_forward_kinematics(plan[name])
        assert np.abs(position - target).max() < POSITION_TOL, name
    for name in ("start_open", "final_open"):
        rotation = get_forward_kinematics(plan[name])[1]
        assert tilt(rotation) < ANGLE_TOL
        assert yaw_error(rotation, 20.0) < ANGLE_TOL  # the cube keeps its yaw
    # pre_grasp and retreat: beside the grasps at the same height, still top-down.
    for name, grasp in (("pre_grasp", "start_open"), ("retreat", "final_open")):
        offset = get_forward_kinematics(plan[name])[0] - get_forward_kinematics(plan[grasp])[0]
        assert np.linalg.norm(offset) == pytest.approx(cp.PRE_GRASP_SLIDE, abs=1e-9)
        assert abs(offset[2]) < 1e-9
    assert plan["start_closed"]["gripper"] == plans.GRIPPER_CLOSED
    assert plan["start_open"]["gripper"] == ik.GRIPPER_OPEN


def test_cartesian_plan_names_the_unreachable_waypoint():
    with pytest.raises(ik.UnreachableError, match="Waypoint 'final_open'") as error:
        cp.cartesian_plan((0.22, 0.1, 0.013), (0.5, 0.0, 0.013))
    assert error.value.reason == "too_far"
    with pytest.raises(ValueError, match="lift_height"):
        cp.cartesian_plan((0.22, 0.1, 0.013), (0.22, -0.1, 0.013), lift_height=-0.1)


# --- Command line ----------------------------------------------------------------------
def parse(argv, cube_yaw=True):
    import argparse

    parser = argparse.ArgumentParser()
    parser.add_argument("--plan")
    parser.add_argument("--move-duration", type=float, default=2.0)
    parser.add_argument("--hold", type=float, default=0.5)
    cp.add_cartesian_arguments(parser, cube_yaw=cube_yaw)
    return parser.parse_args(argv)


def test_command_line_builds_the_cartesian_plan():
    pick, place = assignment_positions()
    argv = ["--pick", *map(str, pick), "--place", *map(str, place), "--hold", "0.25"]
    plan = cp.plan_from_arguments(parse(argv))
    expected = cp.cartesian_plan(pick, place, hold_duration=0.25)
    assert plan.configurations() == expected.configurations()
    assert [s.hold for s in plan.steps] == [s.hold for s in expected.steps]
    turned = cp.plan_from_arguments(parse(argv + ["--cube-yaw", "10", "--lift-height", "0.05"]))
    rotation = get_forward_kinematics(turned.configurations()["start_open"])[1]
    assert yaw_error(rotation, 10.0) < ANGLE_TOL
    lift = get_forward_kinematics(turned.configurations()["lift"])[0]
    assert lift[2] == pytest.approx(pick[2] + 0.05, abs=POSITION_TOL)
    assert cp.plan_from_arguments(parse([])) is None


@pytest.mark.parametrize("argv, match", [
    (["--pick", "0.2", "0.1", "0.013"], "go together"),
    (["--pick", "0.2", "0.1", "0.013", "--place", "0.2", "-0.1", "0.013", "--plan", "x.json"],
     "give one of them"),
])
def test_command_line_mistakes(argv, match):
    with pytest.raises(PlanError, match=match):
        cp.plan_from_arguments(parse(argv))
