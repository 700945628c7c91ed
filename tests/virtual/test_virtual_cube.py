"""The virtual arm's table has the cube: the whole hardware run rehearsed, cube included.

The cube is the simulator's (one definition, so101_kinematics.sim.cube), resting on
the virtual arm's table; the hardware path (lerobot's bus, run_on_arm) does the
course's pick-and-place, and the bus's cube sensor (so101_kinematics.sensors)
tells where the cube ended.
"""

from __future__ import annotations

import math

import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

from so101_forward_kinematics import ARM_JOINTS, get_forward_kinematics  # noqa: E402
from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.hw import run as hw  # noqa: E402
from so101_kinematics.hw.bus import connect, disconnect, read_block  # noqa: E402
from so101_kinematics.hw.teach import cube_outcome, grasp_outcome  # noqa: E402
from so101_kinematics.planning.plans import GRIPPER_CLOSED, default_plan, pick_and_place_steps  # noqa: E402
from so101_kinematics.sensors.cube_reader import CubeSensor  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

CALIBRATION = load_calibration(DEFAULT_CALIBRATION_PATH)
PICK, PLACE = (get_forward_kinematics({j: s.configuration[j] for j in ARM_JOINTS})[0]
               for s in pick_and_place_steps(default_plan()))
"""Where the course's FK says the cube stands and where it must end [m]."""


def run_with_cube(offset_m=(0.0, 0.0)):
    """The course's plan on a virtual arm whose cube stands at the FK pick position + offset."""
    start = (PICK[0] + offset_m[0], PICK[1] + offset_m[1])
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=start) as arm:
        plan = default_plan()
        result = hw.run_on_arm(arm.port, CALIBRATION, plan)
        return plan, result, arm.cube()


@pytest.mark.slow
def test_the_course_plan_places_the_cube_where_the_fk_says():
    plan, result, cube = run_with_cube()
    assert result.aborted is None and result.torque_released
    x, y, z = cube.position_m
    assert math.hypot(x - PLACE[0], y - PLACE[1]) <= 0.010  # the 10 mm
    assert cube.tilt_deg <= 10.0 and not cube.held and z == pytest.approx(0.013, abs=0.002)
    assert result.cube == cube  # what the script read through the bus is the arm's truth
    # the gripper stopped on the cube (26 mm between the jaws), not at its closed command
    held = [c.measured["gripper"] for c in result.cycles if c.step in ("lift", "carry")]
    assert min(held) > GRIPPER_CLOSED + 10.0
    assert "closed on the cube" in grasp_outcome(plan, result.cycles)
    line = cube_outcome(plan, result.cube)
    assert line.startswith("Cube (the virtual arm's sensor)") and "mm from the FK place" in line


@pytest.mark.slow
def test_a_cube_5_mm_off_is_still_placed():
    _, result, cube = run_with_cube((0.005, 0.0))
    x, y, _ = cube.position_m
    assert result.aborted is None and math.hypot(x - PLACE[0], y - PLACE[1]) <= 0.010


@pytest.mark.slow
def test_a_cube_3_cm_off_is_not_picked_and_the_script_says_so():
    plan, result, cube = run_with_cube((0.0, 0.03))
    assert result.aborted is None and result.torque_released  # the run itself ends normally
    x, y, _ = cube.position_m
    assert math.hypot(x - PICK[0], y - PICK[1] - 0.03) <= 0.02  # it never left the pick area
    assert "closed on nothing" in grasp_outcome(plan, result.cycles)


def test_the_cube_sensor_reads_the_cube_and_a_silent_bus_has_none():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=(0.25, -0.05, 30.0)) as arm:
        bus = connect(arm.port, CALIBRATION)
        sensor = CubeSensor(lambda *block: read_block(bus, *block))
        try:
            reading = sensor.read()
            assert reading.position_m[:2] == pytest.approx((0.25, -0.05), abs=2e-4)
            assert not reading.held
            arm.remove_cube()
            assert sensor.read() is None and arm.cube() is None
            arm.place_cube(0.2, 0.1)
            assert sensor.read().position_m[:2] == pytest.approx((0.2, 0.1), abs=2e-4)
            arm.inject("outage:300")  # nothing answers: as on a real arm, which has no sensor
            assert sensor.read() is None
        finally:
            disconnect(bus)


def test_an_arm_without_a_cube_reports_none_and_refuses_a_placement():
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as arm:
        assert arm.cube() is None
        with pytest.raises(ValueError, match="--cube"):
            arm.place_cube(0.2, 0.1)
