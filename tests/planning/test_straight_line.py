"""Straight lines in task space (issue 27, part 6): the planned path, --approach straight.

Expected values are hand calculations: the cubic time scaling f(s) = 3 s^2 - 2 s^3 (the
course's a2 = 3 / T^2, a3 = -2 / T^3 per unit of the way), so after the first of n cycles
the object frame has gone f(1/n) = 3/n^2 - 2/n^3 of the segment, and the segment's own
geometry (distances from a line). The measured bounds are this branch's measurements
(README, "Straight lines") with a margin.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from so101_kinematics.errors import PlanError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINT_RANGES_RAD
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.planning.cartesian_plan import cartesian_plan
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.straight_line import (
    SEGMENTS,
    max_path_deviation_mm,
    path_deviations,
    straight_path,
    straighten_plan,
)

PICK, PLACE = (0.2, 0.1, 0.013), (0.2, -0.1, 0.013)  # [m]: top-down reachable 5 cm above
ABOVE = (0.2, 0.1, 0.063)  # [m]
BELOW = get_inverse_kinematics(list(PICK), gripper=50.0)
TOP = get_inverse_kinematics(list(ABOVE), initial=BELOW, gripper=50.0)
DURATION, DT = 1.0, 0.01  # [s]: n = 100 cycles
SIM_BOUND_MM = 3.5  # measured 2.18 (ik) and 2.20 (resolved_rate) mm on the faithful servo
HW_BOUND_MM = 2.5  # measured 0.99 (ik), 1.12 (resolved_rate) mm on the virtual arm; margin: load


def _positions(path):
    return np.array([forward_kinematics(cfg)[0] for cfg in path])


@pytest.mark.parametrize("method, on_line_m, top_down_rad", [
    ("ik", 1e-6, 1e-6),  # the IK converges at every cycle
    ("resolved_rate", 2e-5, 1e-6),  # one linearised step per cycle: measured 9.6 um off
])
def test_every_sample_is_on_the_segment_top_down_within_the_limits(method, on_line_m,
                                                                   top_down_rad):
    path = straight_path(TOP, BELOW, DURATION, method, DT)
    assert len(path) == 100
    p = _positions(path)
    assert max_path_deviation_mm(p, ABOVE, PICK) < on_line_m * 1e3
    for cfg in path:
        approach = -forward_kinematics(cfg)[1][:, 2]
        assert math.acos(min(1.0, -approach[2])) < top_down_rad  # top-down all the way
        for joint in ARM_JOINTS:
            low, high = (math.degrees(v) for v in JOINT_RANGES_RAD[joint])
            assert low - 1e-9 <= cfg[joint] <= high + 1e-9
    assert abs(path[-1]["wrist_roll"] - TOP["wrist_roll"]) < 0.5  # the jaws do not turn


def test_the_ik_line_follows_the_cubic_time_scaling_with_zero_end_speeds():
    p = _positions(straight_path(TOP, BELOW, DURATION, "ik", DT))
    length = 0.05  # [m], ABOVE to PICK
    gone = np.linalg.norm(p - np.array(ABOVE), axis=1)
    n = 100
    first = 3 / n**2 - 2 / n**3  # f(1/n): 2.98e-4 of the way after the first cycle
    assert gone[0] == pytest.approx(first * length, abs=1e-8)
    assert length - gone[-2] == pytest.approx(first * length, abs=1e-8)  # and before the end
    assert gone[49] == pytest.approx(0.5 * length, abs=1e-8)  # f(1/2) = 1/2
    # Speeds [m/s] from the samples: ~0 at the ends, 1.5 L / T (the cubic's peak) mid-way.
    speed = np.diff(np.concatenate([[0.0], gone])) / DT
    assert speed[0] < 0.002 and speed[-1] < 0.002
    assert speed.max() == pytest.approx(1.5 * length / DURATION, rel=1e-3)


def test_an_unknown_method_is_refused():
    with pytest.raises(PlanError, match="ik or resolved_rate"):
        straight_path(TOP, BELOW, DURATION, "jacobian", DT)


def test_straighten_plan_makes_each_vertical_move_a_line_and_leaves_the_rest():
    plan = cartesian_plan(PICK, PLACE)
    straight = straighten_plan(plan, "ik", DT)
    names = [step.name for step in straight.steps]
    original = {step.name: step for step in plan.steps}
    kept = [name for name in names if "~" not in name]
    assert kept == [step.name for step in plan.steps]
    for first, last in SEGMENTS:
        samples = [s for s in straight.steps if s.name.startswith(last + "~")]
        assert len(samples) + 1 == round(original[last].duration / DT)
        assert all(s.duration == DT and s.hold == 0.0 for s in samples)
        end = next(s for s in straight.steps if s.name == last)
        assert end.hold == original[last].hold
        # The line ends where the joint-space move did (the IK converged on the same pose).
        assert np.allclose(forward_kinematics(end.configuration)[0],
                           forward_kinematics(original[last].configuration)[0], atol=1e-6)
        p0 = forward_kinematics(original[first].configuration)[0]
        pf = forward_kinematics(original[last].configuration)[0]
        along = _positions([s.configuration for s in samples])
        assert max_path_deviation_mm(along, p0, pf) < 1e-3
    for name in ("approach", "carry", "start_open"):  # the joint-space moves stay as they were
        assert next(s for s in straight.steps if s.name == name).configuration == \
            original[name].configuration


def test_the_arm_s_plan_table_shows_each_line_as_one_waypoint():
    from so101_kinematics.hw.teach import format_plan
    from so101_kinematics.hw.timing import speed_caps

    text = format_plan(straighten_plan(cartesian_plan(PICK, PLACE)), rate_hz=100.0,
                       profile="minimum_jerk", max_speed=speed_caps())
    assert "Plan: 10 waypoints" in text and "lift~" not in text
    lift = next(line for line in text.splitlines() if line.split()[1:2] == ["lift"])
    assert lift.split()[2] == "2.00~"  # the 2 s move, 200 cycles of 10 ms, as a line
    assert "~ a straight line in task space" in text


def test_a_plan_without_vertical_moves_is_refused():
    plan = Plan([Step("somewhere", dict(TOP), 1.0, 0.0)])
    with pytest.raises(PlanError, match="Fix: use --approach joint"):
        straighten_plan(plan)


def test_the_measured_deviation_is_per_line_and_by_hand():
    plan = Plan([Step("approach", dict(TOP), 1.0, 0.0), Step("pre_grasp~001", dict(TOP), DT, 0),
                 Step("pre_grasp", dict(BELOW), DT, 0.5)])
    # 3 mm beside the segment, then 4 mm: the largest is 4 mm; other steps are ignored.
    samples = [("pre_grasp~001", np.add(ABOVE, [0.003, 0.0, -0.01])),
               ("pre_grasp", np.add(PICK, [0.0, 0.004, 0.0])),
               ("approach", np.add(ABOVE, [0.05, 0.0, 0.0]))]
    assert path_deviations(plan, samples) == {"pre_grasp": pytest.approx(4.0, abs=1e-3)}


# --- the simulated pick-and-place ------------------------------------------------------------
@pytest.mark.parametrize("method", ["ik", "resolved_rate"])
def test_pick_place_sim_places_the_cube_with_straight_lines(tmp_path, capsys, method):
    import pick_place_sim

    report = tmp_path / "run.json"
    rc = pick_place_sim.main(["--headless", "--no-progress", "--approach", "straight",
                              "--straight-method", method, "--json", str(report)])
    out = capsys.readouterr().out
    assert rc == 0
    written = json.loads(report.read_text())
    assert written["success"] and written["placement_error_m"] <= 0.010
    lines = written["straight_path_deviation_mm"]
    assert set(lines) == {last for _, last in SEGMENTS}
    assert 0.0 < max(lines.values()) < SIM_BOUND_MM
    assert "Straight lines (measured): largest distance from the segment" in out
    assert not any("~" in name for name in written["waypoint_errors_deg"])


def test_a_bad_approach_is_one_line_with_exit_2(capsys):
    import pick_place_sim

    assert pick_place_sim.main(["--headless", "--approach", "sideways"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "--approach" in err and "sideways" in err and "straight" in err and "Fix:" in err


# --- the virtual arm through lerobot's bus -----------------------------------------------------
@pytest.mark.hw
@pytest.mark.slow
def test_pick_place_hw_runs_a_straight_lift_on_the_virtual_arm(tmp_path, capsys):
    pytest.importorskip("lerobot")
    import pick_place_hw
    from so101_kinematics.hw.log import sidecar_path
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    grasp = dict(BELOW, gripper=5.0)
    plan = {"steps": [{"name": "start_closed", "configuration": grasp, "duration": 1.5,
                       "hold": 0.3},
                      {"name": "lift", "configuration": TOP | {"gripper": 5.0},
                       "duration": 1.5, "hold": 0.3}], "return_duration": 1.5}
    plan_path, log = tmp_path / "lift.json", tmp_path / "lift.csv"
    plan_path.write_text(json.dumps(plan))
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as arm:
        rc = pick_place_hw.main(["--port", arm.port, "--calibration",
                                 str(DEFAULT_CALIBRATION_PATH), "--yes", "--plan",
                                 str(plan_path), "--approach", "straight", "--log", str(log)])
    out, err = capsys.readouterr()
    assert rc == 0, out + err
    assert "Straight lines (ik): largest distance from the segment" in out
    measured = json.loads(sidecar_path(log).read_text())["straight_path_deviation_mm"]
    assert set(measured) == {"lift"}
    assert 0.0 < measured["lift"] < HW_BOUND_MM
