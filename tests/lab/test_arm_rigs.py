"""An arm from its configuration (so101_kinematics/lab/arms.py): the simulator, the virtual arm.

Two configs make a two-arm program; each rig's sensors read its own table.
"""

from __future__ import annotations

import pytest

from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import InputError
from so101_kinematics.interfaces import Arm, Sensor
from so101_kinematics.lab.arms import ArmConfig, open_arm


def test_two_simulated_arms_from_their_configs_each_with_its_own_table():
    with open_arm(ArmConfig("left", "sim", cubes=((0.2, 0.1), (0.25, -0.05, 30.0)))) as left, \
            open_arm(ArmConfig("right", "sim")) as right:
        assert isinstance(left.arm, Arm) and left.arm.name == "left"
        assert list(left.sensors) == ["cube", "cube_2"] and right.sensors == {}
        assert all(isinstance(sensor, Sensor) for sensor in left.sensors.values())
        assert left.sensors["cube_2"].read().position_m[:2] == pytest.approx((0.25, -0.05),
                                                                             abs=1e-6)
        assert left.arm.read_positions() == pytest.approx(HOME_POSE, abs=1e-6)
        left.arm.send_goal({"shoulder_pan": 20.0})
        left.arm.advance(1.5)
        assert left.arm.read_positions()["shoulder_pan"] == pytest.approx(20.0, abs=1.0)
        assert right.arm.read_positions() == pytest.approx(HOME_POSE, abs=1e-6)


def test_the_real_arm_and_an_unknown_kind_are_refused_in_one_line_with_the_fix():
    with pytest.raises(InputError, match=r"real arm .* Fix: BusArm\(so101_utils.setup_motors"):
        open_arm(ArmConfig("left", "real"))
    with pytest.raises(InputError, match="kind 'mujoco' is not one of sim, virtual"):
        open_arm(ArmConfig("left", "mujoco"))


@pytest.mark.hw
def test_a_virtual_arm_from_its_config_reads_its_cube_and_follows_small_steps():
    pytest.importorskip("lerobot")
    with open_arm(ArmConfig("left", "virtual", cubes=((0.22, -0.05),))) as rig:
        virtual = rig.owned[0]
        assert isinstance(rig.arm, Arm) and list(rig.sensors) == ["cube"]
        assert rig.sensors["cube"].read().position_m[:2] == pytest.approx((0.22, -0.05), abs=2e-4)
        start = rig.arm.read_positions()["shoulder_pan"]
        for k in range(1, 11):  # 10 deg at 1 deg per 20 ms cycle
            rig.arm.send_goal({"shoulder_pan": start + k})
            rig.arm.advance(0.02)
        rig.arm.advance(1.0)
        assert virtual.joint_positions()["shoulder_pan"] == pytest.approx(start + 10, abs=1.5)
    assert not rig.arm.bus.is_connected and virtual._process is None  # its process ended
