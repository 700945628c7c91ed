"""Stacking through the real hardware path: lerobot's bus against the virtual arm with two cubes.

The virtual arm's cubes are the simulator's (friction only); the stacking plan
(so101_kinematics.planning.stacking) runs through run_on_arm as pick_place_hw.py --stack
does, and the bus's cube sensor tells where every cube ended.
"""

from __future__ import annotations

import math

import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.errors import CubePositionError  # noqa: E402
from so101_kinematics.hw import run as hw  # noqa: E402
from so101_kinematics.hw.bus import connect, disconnect, read_block  # noqa: E402
from so101_kinematics.planning.stack_report import stack_outcome  # noqa: E402
from so101_kinematics.planning.stacking import stack_plan  # noqa: E402
from so101_kinematics.sensors import cube_wire as cube_sensor  # noqa: E402
from so101_kinematics.sensors.cube_reader import read_cubes  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

CALIBRATION = load_calibration(DEFAULT_CALIBRATION_PATH)
STACK = (0.15, 0.10)  # [m]
STARTS = [(0.22, -0.12, 0.0), (0.12, 0.22, 0.0)]  # [m, m, deg] where the blocks stand


@pytest.mark.slow
def test_two_blocks_are_stacked_on_the_virtual_arm_through_the_bus():
    stack = stack_plan(STACK, 2, STARTS, move_duration=1.5, hold_duration=0.2)
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=STARTS) as arm:
        result = hw.run_on_arm(arm.port, CALIBRATION, stack.plan)
        truth = [arm.cube(0), arm.cube(1)]
    assert result.aborted is None and result.torque_released
    assert result.cubes == truth  # what the script read through the bus is the arm's truth
    bottom, top = sorted(truth, key=lambda c: c.position_m[2])
    assert math.dist(bottom.position_m[:2], STACK) <= 0.005
    assert math.dist(top.position_m[:2], bottom.position_m[:2]) <= 0.005
    # hand calculation, 26 mm cubes on the table: centres at 13 and 39 mm
    assert bottom.position_m[2] == pytest.approx(0.013, abs=0.003)
    assert top.position_m[2] == pytest.approx(0.039, abs=0.003)
    assert max(bottom.tilt_deg, top.tilt_deg) <= 10.0 and not top.held
    lines = stack_outcome(stack, result.cubes)
    assert lines.count("\n") == 2 and lines.endswith("stacked.")


def test_the_sensor_reports_each_cube_and_the_table_below_the_base():
    cubes = [(0.25, -0.05, 30.0), (0.2, 0.1)]
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=cubes,
                      base_height=0.015) as arm:
        bus = connect(arm.port, CALIBRATION)
        try:
            readings = read_cubes(lambda *block: read_block(bus, *block))
            arm.remove_cube(1)
            after = read_cubes(lambda *block: read_block(bus, *block))
        finally:
            disconnect(bus)
    assert [r.position_m[:2] for r in readings] == [pytest.approx((0.25, -0.05), abs=2e-4),
                                                    pytest.approx((0.2, 0.1), abs=2e-4)]
    # resting on a table 15 mm below the base frame: centre at -0.015 + 0.013 m
    assert [r.position_m[2] for r in readings] == [pytest.approx(-0.002, abs=5e-4)] * 2
    assert len(after) == 1


def test_two_cubes_closer_than_their_size_are_refused_in_one_line(capsys):
    """Issue 28: two --cube at one spot were accepted; the physics pushed them 13 mm apart."""
    import virtual_so101
    from so101_kinematics.virtual.cubes import check_cubes

    code = virtual_so101.main(["--cube", "0.2", "0.05", "--cube", "0.2", "0.05"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "cube 2 at (0.2, 0.05) m is 0.0 mm from cube 1" in err[0] and "Fix:" in err[0]
    with pytest.raises(CubePositionError, match="25.0 mm from cube 1"):
        check_cubes([(0.2, 0.0), (0.2, 0.025)])
    assert len(check_cubes([(0.2, 0.0), (0.2, 0.026)])) == 2  # side by side: 26 mm, touching


def test_too_many_cubes_and_a_bad_base_height_are_refused():
    with pytest.raises(CubePositionError, match="at most"):
        VirtualSO101(cube=[(0.1 + 0.01 * i, 0.0) for i in range(cube_sensor.MAX_CUBES + 1)])
    with pytest.raises(CubePositionError, match="--base-height"):
        VirtualSO101(base_height=0.2)
