"""Stacking (the course's assignment 8) and the table below the base frame (--base-height).

Expected heights are the hand calculation for the model's 26 mm cubes: a cube
resting on the table has its centre 13 mm up, the one on top of it 26 mm
higher (0.039 m), the third 0.065 m; with the lab's 15 mm mount the table is at
z = -0.015 m in the base frame, so every centre is 15 mm lower.
"""

from __future__ import annotations

import json
import math
import re

import mujoco
import numpy as np
import pytest

import pick_place_sim
from so101_kinematics.errors import PlanError
from so101_kinematics.planning.stacking import block_height, default_starts, stack_plan
from so101_kinematics.sim.cube import build_model
from so101_kinematics.sim.stack import run_stack, stack_report

STACK = (0.15, 0.10)  # [m] a stack to the side of the arm's rest pose, well inside the reach


def assert_stacked(report, heights, horizontal_mm=5.0, height_mm=3.0, tilt_deg=10.0):
    """Each block over the one below (the bottom one over the stack), at its height, upright."""
    finals = np.array(report.blocks_final_position_m)
    assert finals.shape == (len(heights), 3)
    assert np.linalg.norm(finals[0, :2] - STACK) <= horizontal_mm / 1e3, finals[0]
    for below, above in zip(finals, finals[1:], strict=False):
        assert np.linalg.norm(above[:2] - below[:2]) <= horizontal_mm / 1e3, (below, above)
    for final, height in zip(finals, heights, strict=True):
        assert abs(final[2] - height) <= height_mm / 1e3, (final, height)
    assert max(report.blocks_tilt_deg) <= tilt_deg
    assert report.success


def test_two_blocks_stack_from_the_default_starts():
    report = run_stack(stack_plan(STACK, 2), progress=False)
    assert_stacked(report, (0.013, 0.039))
    assert report.lean_deg < 10.0


def test_three_blocks_stack_where_the_third_level_is_reachable():
    report = run_stack(stack_plan(STACK, 3), progress=False)
    assert_stacked(report, (0.013, 0.039, 0.065))


def test_blocks_stack_on_a_table_15_mm_below_the_base():
    report = run_stack(stack_plan(STACK, 2, base_height=0.015), progress=False)
    assert_stacked(report, (-0.002, 0.024))
    assert report.base_height_m == 0.015


def test_given_starts_and_yaw_are_used():
    starts = [(0.22, -0.12, 20.0), (0.12, 0.22)]
    stack = stack_plan(STACK, 2, starts)
    assert [b.start[:2] for b in stack.blocks] == [(0.22, -0.12), (0.12, 0.22)]
    assert stack.blocks[0].start_yaw_deg == 20.0
    assert_stacked(run_stack(stack, progress=False), (0.013, 0.039))


def test_the_levels_are_one_cube_edge_apart():
    assert [round(block_height(k), 4) for k in range(4)] == [0.013, 0.039, 0.065, 0.091]
    assert round(block_height(0, base_height=0.015), 4) == -0.002


def test_a_level_out_of_top_down_reach_is_refused_naming_its_height():
    # The 4th block's centre, 0.091 m up, needs wrist_flex beyond its 95 deg limit.
    with pytest.raises(PlanError, match=r"block 4's centre at z = 0\.091 m.*at most 3"):
        stack_plan(STACK, 4)


def test_a_stack_in_the_rest_pose_s_gripper_is_refused():
    # The folded rest pose holds the jaws at about (0.24, 0, 0.07) m: three blocks right
    # in front of the base would be knocked over by the return at the end.
    with pytest.raises(PlanError, match="rest pose"):
        stack_plan((0.22, 0.0), 3)


def test_starts_too_close_are_refused_and_defaults_keep_clear():
    with pytest.raises(PlanError, match="--block 2"):
        stack_plan(STACK, 2, [(0.22, -0.12), (0.16, 0.13)])
    starts = default_starts((0.23, 0.17), 3)  # next to the first default start: it is skipped
    assert (0.230, 0.190) not in starts and len(starts) == 3
    for i, a in enumerate(starts):  # two cube edges and the open jaws between any two
        assert math.dist(a, (0.23, 0.17)) >= 0.06
        assert all(math.dist(a, b) >= 0.06 for b in starts[i + 1:])


@pytest.mark.parametrize("where", [(0.25, 0.10), (0.20, -0.15), (0.12, -0.16), (0.28, -0.04)])
def test_two_blocks_stack_across_the_workspace(where):
    report = run_stack(stack_plan(where, 2), progress=False)
    finals = np.array(report.blocks_final_position_m)
    assert np.linalg.norm(finals[0, :2] - where) <= 0.005
    assert np.linalg.norm(finals[1, :2] - finals[0, :2]) <= 0.005
    assert finals[1, 2] == pytest.approx(0.039, abs=0.003) and report.success


def test_report_measures_offsets_lean_and_tilt():
    stack = stack_plan(STACK, 2)
    turned = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # on its side
    tilted = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(0.3), -math.sin(0.3)],
                       [0.0, math.sin(0.3), math.cos(0.3)]])
    geometry = stack_report([(0.151, 0.1, 0.013), (0.151, 0.126, 0.039)], [turned, tilted],
                            stack)
    assert geometry["blocks_offset_m"] == pytest.approx([0.001, 0.026])
    assert geometry["blocks_tilt_deg"] == pytest.approx([0.0, math.degrees(0.3)])
    assert geometry["lean_deg"] == pytest.approx(45.0)
    assert not geometry["success"]


def test_a_cube_on_a_15_mm_lower_table_rests_at_its_centre_height():
    m = build_model(physics_only=True, cubes_at=[(0.2, 0.1, 30.0)], base_height=0.015)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    while d.time < 1.0:
        mujoco.mj_step(m, d)
    # resting on the table: -0.015 + 0.013; MuJoCo's soft contact sinks it < 0.5 mm
    assert d.body("cube").xpos[2] == pytest.approx(-0.002, abs=0.0005)
    assert d.body("cube").xpos[:2] == pytest.approx([0.2, 0.1], abs=1e-4)


def test_pick_place_sim_stack_writes_each_block_s_final_position(tmp_path, capsys):
    path = tmp_path / "stack.json"
    code = pick_place_sim.main(["--stack", "0.15", "0.1", "--headless", "--json", str(path),
                                "--no-progress", "--strict"])
    assert code == 0, capsys.readouterr()
    report = json.loads(path.read_text())
    finals = report["blocks_final_position_m"]
    assert len(finals) == 2 and all(len(p) == 3 for p in finals)
    assert finals[1][2] == pytest.approx(0.039, abs=0.003)
    assert "Stack lean" in capsys.readouterr().out


def test_pick_place_sim_refuses_an_unreachable_stack_in_one_line(capsys):
    code = pick_place_sim.main(["--stack", "0.2", "0", "--blocks", "4", "--headless"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "z = 0.091 m" in err and "Traceback" not in err


def test_pick_place_hw_dry_run_shows_where_the_blocks_go(capsys):
    import pick_place_hw

    assert pick_place_hw.main(["--stack", "0.15", "0.1", "--blocks", "3", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "Stack of 3 blocks at x = 15.0 cm, y = 10.0 cm" in out
    assert "block3_final_open" in out and "centre at z = 6.5 cm" in out
    assert pick_place_hw.main(["--stack", "0.2", "0", "--blocks", "4", "--dry-run"]) == 2
    assert "z = 0.091 m" in capsys.readouterr().err


def test_the_placement_sheet_of_a_stack_on_the_mount(tmp_path):
    from so101_kinematics.lab.sheet import write_sheet

    stack = stack_plan(STACK, 2, base_height=0.015)
    info = write_sheet(stack.plan, tmp_path / "sheet.pdf", stack=stack, base_height=0.015)
    assert [c.role for c in info.cubes] == ["block 1", "block 2", "stack"]
    assert (info.cubes[-1].x_cm, info.cubes[-1].y_cm) == pytest.approx((15.0, 10.0))
    assert "15 mm mount" in info.summary() and "z = -0.2 cm" in info.summary()
    assert (tmp_path / "sheet.pdf").stat().st_size > 0


def test_pick_and_place_on_a_lower_table_with_ik_targets_below_the_base(capsys):
    # --pick/--place at a resting cube's centre on a 15 mm lower table: z = -0.002 m,
    # which the IK refuses without --base-height (below its table)
    where = ["--pick", "0.23", "0.19", "-0.002", "--place", "0.229", "-0.191", "-0.002",
             "--headless", "--no-progress", "--strict"]
    assert pick_place_sim.main(where) == 2
    assert pick_place_sim.main([*where, "--base-height", "0.015"]) == 0
    final = re.search(r"Cube final position:  \(([-\d.]+), ([-\d.]+),", capsys.readouterr().out)
    assert math.dist((float(final[1]), float(final[2])), (0.229, -0.191)) <= 0.005


def test_the_virtual_arm_shell_lists_every_cube_on_one_line():
    from so101_kinematics.sensors.cube_wire import CubeReading
    from so101_kinematics.virtual import shell

    class TwoCubes:
        def cube(self, index=0):
            return [CubeReading((0.15, 0.1, 0.013), 0.5, False),
                    CubeReading((0.15, 0.1, 0.039), 1.0, True)][index] if index < 2 else None

    assert shell.COMMANDS["cube"].handler(TwoCubes(), []) == (
        "cube 0.1500 0.1000 0.0130 tilt 0.5 free | cube_2 0.1500 0.1000 0.0390 tilt 1.0 held")
