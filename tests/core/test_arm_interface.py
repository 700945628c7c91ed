"""The seams (so101_kinematics/interfaces.py): every backend is an Arm, every sensor a Sensor.

Each backend is checked twice: it has the protocol's operations (``isinstance`` on the
runtime-checkable protocol) and it behaves as one (a goal sent is read back, reached).
Two simulated arms in one program share no state: moving one leaves the other still.
The virtual arm is reached through lerobot's bus, as the real one is (hw).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import pytest
from hw_fakes import HOME, FakeBus

from so101_kinematics.calibration import load_calibration
from so101_kinematics.errors import InputError, JointLimitError, PlanError
from so101_kinematics.hw.bus_arm import BusArm
from so101_kinematics.interfaces import Arm, Camera, Sensor
from so101_kinematics.sensors.cube_reader import CubeSensor, read_cubes
from so101_kinematics.sensors.cube_wire import MAX_CUBES, SENSOR_ID, SIZE, address, encode
from so101_kinematics.sim.cube import build_model
from so101_kinematics.sim.sim_arm import SimArm, SimCubeSensor

FOLDED = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
          "wrist_roll": 0.0, "gripper": 10.0}
"""The arm folded at rest (the model's ``home`` keyframe, rounded): a start clear of the table."""
PAN_GOAL = 20.0
"""A pan of 20 deg from the folded pose: the pan axis is vertical, so gravity does not pull it."""
CALIBRATION = load_calibration(Path(__file__).resolve().parents[2] / "calibration"
                               / "virtual_so101.json")
BARE_STEP_DEG = 100.0 / 20.0
"""The largest step between two goals on a bare bus [deg]: one cycle of the slowest loop the
hardware path runs (20 Hz) at its speed cap (100 deg/s), by hand (docs/hardware_safety.md)."""


class FakeSensorBus:
    """A bus whose cube sensor answers what the test sets (``block``: the cubes' replies)."""

    def __init__(self, cubes=()):
        self.cubes = list(cubes)
        self.reads = 0

    def __call__(self, device_id: int, address_: int, size: int) -> bytes | None:
        self.reads += 1
        index = address_ // SIZE
        if device_id != SENSOR_ID or size != SIZE or index >= len(self.cubes):
            return None
        return encode(self.cubes[index], 0.0, False)


# --- the protocols ---------------------------------------------------------------------------
def test_each_backend_and_sensor_has_the_protocols_operations():
    sim = SimArm(name="left", pose=FOLDED)
    assert isinstance(sim, Arm) and not isinstance(sim, Sensor)
    cube = CubeSensor(FakeSensorBus())
    assert isinstance(cube, Sensor) and not isinstance(cube, Arm)
    assert isinstance(SimCubeSensor(sim), Sensor)
    assert not isinstance(cube, Camera)  # a camera also has intrinsics and a size
    assert all(hasattr(BusArm, op) for op in ("read_positions", "send_goal", "torque_enabled",
                                              "advance", "close"))


def test_the_protocols_have_teeth():
    """An object missing one operation is not an Arm (isinstance would pass anything else)."""

    class NoTorque:
        name = "x"

        def read_positions(self): ...
        def send_goal(self, goal): ...
        def advance(self, seconds): ...
        def close(self): ...

    assert not isinstance(NoTorque(), Arm)


# --- the simulator ---------------------------------------------------------------------------
def test_a_goal_sent_to_the_simulated_arm_is_read_back_moving_there_then_reached():
    arm = SimArm(pose=FOLDED)
    assert arm.read_positions()["shoulder_pan"] == pytest.approx(0.0, abs=1e-9)
    arm.send_goal({"shoulder_pan": PAN_GOAL})  # the other joints keep their goals
    arm.advance(0.1)
    early = arm.read_positions()["shoulder_pan"]
    assert 0.5 < early < PAN_GOAL  # on its way (the servo takes time: not a jump)
    arm.advance(2.0)
    late = arm.read_positions()
    assert late["shoulder_pan"] == pytest.approx(PAN_GOAL, abs=1.0)
    assert late["elbow_flex"] == pytest.approx(FOLDED["elbow_flex"], abs=5.0)  # kept its goal
    assert arm.data.time == pytest.approx(2.1, abs=arm.model.opt.timestep)
    assert all(arm.torque_enabled().values())


def test_the_simulated_arm_refuses_a_goal_off_limits_and_a_bad_time_in_one_line():
    arm = SimArm(pose=FOLDED)
    with pytest.raises(JointLimitError, match="shoulder_pan"):
        arm.send_goal({"shoulder_pan": 400.0})
    with pytest.raises(PlanError, match="advance"):
        arm.advance(math.nan)
    assert arm.read_positions()["shoulder_pan"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("shared_model", [False, True], ids=["two models", "one model"])
def test_two_simulated_arms_in_one_program_share_no_state(shared_model):
    left = SimArm(name="left", pose=FOLDED)
    right = (SimArm(left.model, mujoco.MjData(left.model), name="right", pose=FOLDED)
             if shared_model else SimArm(name="right", pose=FOLDED))
    right.advance(0.5)  # both servo banks exist before the other one moves
    before = right.read_positions()
    left.send_goal({"shoulder_pan": PAN_GOAL})
    left.advance(1.0)
    assert left.read_positions()["shoulder_pan"] > PAN_GOAL - 2.0  # the left arm moved
    assert right.read_positions() == before  # the right one did not, nor did its clock
    assert right.data.time == pytest.approx(0.5, abs=right.model.opt.timestep)
    right.send_goal({"shoulder_pan": -PAN_GOAL})
    right.advance(1.0)  # and the right one still tracks its own goal, not the left's
    assert right.read_positions()["shoulder_pan"] < -PAN_GOAL + 2.0
    assert left.read_positions()["shoulder_pan"] > PAN_GOAL - 2.0


def test_the_courses_move_to_pose_drives_one_simulated_arm_of_two():
    import so101_mujoco_utils

    left, right = SimArm(name="left", pose=FOLDED), SimArm(name="right", pose=FOLDED)
    so101_mujoco_utils.move_to_pose(left.model, left.data, None,
                                    dict(FOLDED, shoulder_pan=PAN_GOAL), 1.5)
    assert left.read_positions()["shoulder_pan"] == pytest.approx(PAN_GOAL, abs=1.0)
    assert right.read_positions() == pytest.approx(FOLDED, abs=1e-6) and right.data.time == 0.0


def test_the_simulated_cube_sensor_reads_the_cube_where_it_is_now():
    arm = SimArm(build_model(cube_at=(0.22, -0.05, 0.0), physics_only=True), pose=FOLDED)
    sensors = arm.cube_sensors()
    assert list(sensors) == ["cube"]
    reading = sensors["cube"].read()
    assert reading.position_m[:2] == pytest.approx((0.22, -0.05), abs=1e-6)
    assert reading.tilt_deg == pytest.approx(0.0, abs=0.1) and not reading.held
    joint = arm.model.joint("cube")
    arm.data.qpos[joint.qposadr[0]:joint.qposadr[0] + 2] = (0.18, 0.07)  # moved by hand
    mujoco.mj_forward(arm.model, arm.data)
    assert sensors["cube"].read().position_m[:2] == pytest.approx((0.18, 0.07), abs=1e-6)
    assert SimCubeSensor(arm, 1).read() is None  # no second cube in this scene
    assert SimArm(pose=FOLDED).cube_sensors() == {}


# --- the bus (a fake lerobot bus here; the virtual arm's below) ----------------------------
def test_a_bare_bus_takes_small_steps_and_refuses_a_jump_with_nothing_sent():
    bus = FakeBus(CALIBRATION, HOME)
    arm = BusArm(bus, "left")
    assert isinstance(arm, Arm) and arm.name == "left"
    with pytest.raises(PlanError, match="shoulder_pan .* full speed.*nothing sent"):
        arm.send_goal({"shoulder_pan": PAN_GOAL})  # at once: the servos would jump there
    assert bus.goals == []
    for k in range(1, 5):  # 20 deg in four steps of 5: a 20 Hz loop at the speed cap
        arm.send_goal({"shoulder_pan": k * BARE_STEP_DEG})
    assert [g["shoulder_pan"] for g in bus.goals] == [5.0, 10.0, 15.0, 20.0]
    assert bus.goals[-1]["elbow_flex"] == pytest.approx(HOME["elbow_flex"])  # kept its goal
    with pytest.raises(PlanError, match="gripper"):
        arm.send_goal({"gripper": HOME["gripper"] + BARE_STEP_DEG + 0.5})
    with pytest.raises(JointLimitError):
        arm.send_goal({"shoulder_pan": 400.0})
    assert len(bus.goals) == 4 and arm.read_positions()["shoulder_pan"] == 20.0
    bus.torque["wrist_roll"] = False
    assert arm.torque_enabled() == {**dict.fromkeys(HOME, True), "wrist_roll": False}


def test_the_guarded_bus_ramps_a_far_goal_itself_so_it_is_passed_on():
    bus = FakeBus(CALIBRATION, HOME)
    bus.raw = bus  # as setup_motors' GuardedBus: its goal writes are ramped moves
    arm = BusArm(bus)
    arm.send_goal({"shoulder_pan": PAN_GOAL})
    assert bus.goals[-1]["shoulder_pan"] == PAN_GOAL
    closed = []
    bus.is_connected, bus.disconnect = True, lambda **kwargs: closed.append(kwargs)
    arm.close()  # the guarded bus stays open: it ends with the course's ending
    assert closed == []
    bare = FakeBus(CALIBRATION, HOME)
    bare.is_connected, bare.disconnect = True, lambda **kwargs: closed.append(kwargs)
    BusArm(bare).close()  # a bare one is closed, the torque left as it is (holding)
    assert closed == [{"disable_torque": False}]


# --- the cube sensor over a bus --------------------------------------------------------------
def test_the_cube_sensor_asks_the_bus_at_every_read_never_a_stale_reading():
    bus = FakeSensorBus([(0.2, 0.1, 0.013)])
    sensor = CubeSensor(bus)
    assert sensor.name == "cube" and sensor.read().position_m == (0.2, 0.1, 0.013)
    bus.cubes[0] = (0.25, -0.05, 0.013)  # the cube moved: the next read says so
    assert sensor.read().position_m == (0.25, -0.05, 0.013)
    bus.cubes.clear()  # gone (or a real arm: nothing answers)
    assert sensor.read() is None and bus.reads == 3


def test_every_cube_is_read_at_its_own_address_and_the_list_ends_at_the_first_absent():
    asked = []

    def bus(device_id, address_, size):
        asked.append(address_)
        return FakeSensorBus([(0.2, 0.0, 0.013), (0.25, 0.05, 0.039)])(device_id, address_, size)

    cubes = read_cubes(bus)
    assert [c.position_m for c in cubes] == [(0.2, 0.0, 0.013), (0.25, 0.05, 0.039)]
    assert asked == [address(0), address(1), address(2)] == [0, SIZE, 2 * SIZE]
    assert CubeSensor(bus, 1).name == "cube_2"
    with pytest.raises(InputError, match="cube index"):
        CubeSensor(bus, MAX_CUBES)


# --- the virtual arm, through lerobot's bus (as the real arm) --------------------------------
@pytest.mark.hw
def test_the_virtual_arm_through_the_bus_is_an_arm_that_reaches_its_goal():
    pytest.importorskip("lerobot")
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.bus import connect, enable_torque_in_place
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, cube=(0.22, -0.05, 0.0)) as virtual:
        arm = BusArm(connect(virtual.port, load_calibration(DEFAULT_CALIBRATION_PATH)), "left")
        try:
            assert isinstance(arm, Arm) and isinstance(arm.cube_sensor(), Sensor)
            enable_torque_in_place(arm.bus)
            assert all(arm.torque_enabled().values())
            start = arm.read_positions()
            assert start["shoulder_pan"] == pytest.approx(virtual.joint_positions()["shoulder_pan"],
                                                          abs=0.5)
            goal = start["shoulder_pan"] + PAN_GOAL
            with pytest.raises(JointLimitError):
                arm.send_goal({"shoulder_pan": 400.0})  # refused: nothing sent
            with pytest.raises(PlanError, match="full speed"):
                arm.send_goal({"shoulder_pan": goal})  # a jump: refused too
            assert virtual.commanded_positions()["shoulder_pan"] == pytest.approx(
                start["shoulder_pan"], abs=0.5)
            for k in range(1, 21):  # the course's loop: 1 deg per 20 ms cycle (50 deg/s)
                arm.send_goal({"shoulder_pan": start["shoulder_pan"] + k})
                arm.advance(0.02)
            arm.advance(1.0)
            assert arm.read_positions()["shoulder_pan"] == pytest.approx(goal, abs=1.5)
            reading = arm.cube_sensor().read()
            assert reading.position_m[:2] == pytest.approx((0.22, -0.05), abs=2e-4)
        finally:
            arm.close()
        assert not arm.bus.is_connected  # closed; the torque was left on (holding)
