"""An arm from its configuration, with its sensors: one call for the simulator or the virtual arm.

As lerobot builds a robot from a config dataclass (its ``cameras: dict[str,
CameraConfig]`` beside the motors), :func:`open_arm` builds an
:class:`ArmRig` from an :class:`ArmConfig`: the arm (``interfaces.Arm``) and
its sensors by name (``interfaces.Sensor``: the cube sensor now; issue 36's
cameras join the same dict). A two-arm program is two configs::

    left = open_arm(ArmConfig("left", "virtual", cubes=((0.2, 0.1),)))
    right = open_arm(ArmConfig("right", "sim"))
    ...
    left.close(); right.close()

The real arm is not built here: its set-up decides how it ends (released at the
pose it started from, ``so101_utils.setup_motors``), so it is
``BusArm(so101_utils.setup_motors(calibration, port))``, refused here in one
line that says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from so101_kinematics.calibration import load_calibration
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import InputError
from so101_kinematics.hw.bus import connect
from so101_kinematics.hw.bus_arm import BusArm
from so101_kinematics.interfaces import Arm, Sensor
from so101_kinematics.sim.cube import build_model
from so101_kinematics.sim.sim_arm import SimArm
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

__all__ = ["KINDS", "ArmConfig", "ArmRig", "open_arm"]

KINDS = ("sim", "virtual")
"""The backends :func:`open_arm` builds (the real arm: ``BusArm(setup_motors(...))``)."""


@dataclass(frozen=True)
class ArmConfig:
    """One arm of a program: its name, its backend and its table.

    Attributes:
        name: the arm's name (``"left"``, ``"right"``).
        kind: one of :data:`KINDS`.
        cubes: cubes resting on the table, each (x [m], y [m][, yaw [deg]]) in the base frame.
        base_height: the table this far below the base frame [m] (the lab's mount: 0.015).
        calibration: the virtual arm's calibration file.
    """

    name: str = "arm"
    kind: str = "sim"
    cubes: Sequence[Sequence[float]] = ()
    base_height: float = 0.0
    calibration: str | Path = DEFAULT_CALIBRATION_PATH


@dataclass
class ArmRig:
    """An arm and its sensors by name; :meth:`close` lets go of both (and of a virtual arm)."""

    arm: Arm
    sensors: dict[str, Sensor] = field(default_factory=dict)
    owned: list = field(default_factory=list)  # what closes after the arm (a virtual arm)

    def close(self) -> None:
        """Close the sensors, the arm, then what the rig started (the virtual arm's process)."""
        for sensor in self.sensors.values():
            sensor.close()
        self.arm.close()
        for thing in reversed(self.owned):
            thing.close()

    def __enter__(self) -> ArmRig:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_arm(config: ArmConfig) -> ArmRig:
    """The arm ``config`` describes, holding at the home pose, with a sensor for each cube.

    Raises:
        InputError: an unknown kind, or the real arm (one line with the way to set it up).
    """
    if config.kind == "real":
        raise InputError(f"arm {config.name!r}: the real arm is set up by the course's helpers, "
                         "which end it safely. Fix: BusArm(so101_utils.setup_motors(calibration, "
                         "PORT), name) (so101_kinematics.hw.bus_arm).")
    if config.kind not in KINDS:
        raise InputError(f"arm {config.name!r}: kind {config.kind!r} is not one of "
                         f"{', '.join(KINDS)}. Fix: kind='sim' or kind='virtual'.")
    cubes = [tuple(cube) for cube in config.cubes]
    if config.kind == "sim":
        model = build_model(cubes_at=cubes, base_height=config.base_height) if cubes else None
        arm = SimArm(model, name=config.name, pose=HOME_POSE)  # where the virtual arm starts
        return ArmRig(arm, arm.cube_sensors())
    virtual = VirtualSO101(calibration=config.calibration, cube=cubes or None,
                           base_height=config.base_height)
    try:
        bus = connect(virtual.port, load_calibration(config.calibration), robot_id=config.name)
    except BaseException:
        virtual.close()
        raise
    arm = BusArm(bus, config.name, base_height=config.base_height)
    sensors = {sensor.name: sensor for sensor in (arm.cube_sensor(i) for i in range(len(cubes)))}
    return ArmRig(arm, sensors, [virtual])
