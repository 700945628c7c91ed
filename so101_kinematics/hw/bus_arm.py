"""The real and the virtual SO-101 behind ``interfaces.Arm``: one lerobot bus, its arm's operations.

:class:`BusArm` wraps a connected ``FeetechMotorsBus`` (``hw/bus.py``'s
:func:`~so101_kinematics.hw.bus.connect`: the port taken for this program
alone, the calibration checked) or the guarded bus ``so101_utils.setup_motors``
hands out. The real arm and the virtual one are the same code here: the
virtual SO-101 is a serial port too (``virtual/arm.py``). Each ``BusArm``
owns its bus and port, so two arms in one program are two ``BusArm`` on two
ports.

What a goal does depends on the bus: on the guarded bus it is ramped at the
speed cap and checked against the table, returning when the arm arrived; on a
bare bus it is written as it is, after the checks every commanded path passes
(inside the calibrated range, :func:`~so101_kinematics.hw.goals.guard`; clear of
the table from the last goal, ``clearance.check_path``) and one more: a goal at
most one step of the slowest control loop at the speed cap from the last one
(:func:`max_steps`: 5 deg, gripper 5 %), since the servos go to a goal at their
own full speed. A bare bus is for a loop that sends a planned path in small
steps, one goal per cycle; a far goal there is refused, never jumped to.

The cube sensor rides on the same bus (:meth:`BusArm.cube_sensor`): on a real
arm it answers nothing and reads None.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

from so101_kinematics.calibration import calibrated_limits
from so101_kinematics.clearance import check_path
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINTS
from so101_kinematics.hw.bus import disconnect, read_block, read_pose
from so101_kinematics.hw.goals import guard
from so101_kinematics.hw.timing import MIN_RATE_HZ, speed_caps
from so101_kinematics.inputs import check_configuration, check_number
from so101_kinematics.sensors.cube_reader import CubeSensor

__all__ = ["BusArm", "max_steps"]

MAX_ADVANCE_S = 3600.0
"""The longest :meth:`BusArm.advance` in one call [s] (the course's longest hold, an hour)."""


def max_steps() -> dict[str, float]:
    """Joint -> the largest step between two goals on a bare bus ([deg], gripper [%]).

    One cycle of the slowest control loop (``timing.MIN_RATE_HZ``) at the speed cap
    (``timing.speed_caps``): a loop at that rate or faster, along a path within the
    cap, never takes a larger step.
    """
    return {joint: cap / MIN_RATE_HZ for joint, cap in speed_caps().items()}


class BusArm:
    """An SO-101 on a lerobot Feetech bus (``interfaces.Arm``), real or virtual.

    Args:
        bus: a connected lerobot ``FeetechMotorsBus`` (arm joints in degrees, gripper
            0-100, as ``hw.bus.make_bus`` builds it) or the guarded bus of ``setup_motors``.
        name: the arm's name (default: its port).
        base_height: the table is this far below the base frame [m] (the clearance check).
    """

    def __init__(self, bus, name: str | None = None, *, base_height: float = 0.0):
        self.bus = bus
        self.name = name or str(getattr(bus, "port", "arm"))
        self.base_height = base_height
        self._limits = calibrated_limits(bus.calibration)
        self._goal: dict[str, float] | None = None

    def read_positions(self) -> dict[str, float]:
        """Present_Position of every joint [deg], gripper [0, 100], as the servos report it."""
        return read_pose(self.bus, retries=1)

    def send_goal(self, goal: Mapping[str, float]) -> None:
        """Write Goal_Position; a joint left out keeps its goal; refused off the calibrated range.

        Raises:
            PlanError: a joint unknown or not a number; JointLimitError: outside the range;
                ClearanceError: the way there from the last goal goes into the table;
                PlanError: on a bare bus, a step from the last goal beyond :func:`max_steps`.
                Nothing is sent then.
        """
        partial = {j: self._limits[j] for j in goal if j in self._limits}
        checked = check_configuration(goal, partial, f"{self.name}: goal")
        if self._goal is None:
            self._goal = read_pose(self.bus, retries=1)  # the goals left out: where it stands
        merged = guard({**self._goal, **checked}, self._limits)
        check_path([self._goal, merged], [f"{self.name}: goal"], base_height=self.base_height)
        if getattr(self.bus, "raw", None) is None:  # a bare bus: the servos jump there
            self._check_step(merged)
        self.bus.sync_write("Goal_Position", {j: merged[j] for j in JOINTS})
        self._goal = merged

    def _check_step(self, goal: Mapping[str, float]) -> None:
        """Refuse a goal farther from the last one than one step of the slowest loop."""
        for joint, most in max_steps().items():
            step = goal[joint] - self._goal[joint]
            if abs(step) > most:
                unit = "%" if joint == "gripper" else "deg"
                raise PlanError(
                    f"{self.name}: goal {joint} {goal[joint]:.1f} {unit} is {abs(step):.1f} "
                    f"{unit} from the last goal ({self._goal[joint]:.1f}): more than "
                    f"{most:g} {unit} in one goal jumps the arm at the servos' full speed; "
                    "nothing sent. Fix: send the path in small steps, one goal per cycle "
                    "(a 50 Hz loop along a planned trajectory), or move with the helpers' "
                    "move_to_pose, which ramps.")

    def torque_enabled(self) -> dict[str, bool]:
        """Torque_Enable of every servo, read back."""
        raw = self.bus.sync_read("Torque_Enable", num_retry=1)
        return {j: bool(raw[j]) for j in JOINTS}

    def advance(self, seconds: float) -> None:
        """Wait ``seconds`` (the servos move on their own, in real time)."""
        time.sleep(check_number(seconds, f"{self.name}: advance", 0.0, MAX_ADVANCE_S, "s"))

    def read_block(self, device_id: int, address: int, size: int) -> bytes | None:
        """A block read from another device on this arm's bus (``hw.bus.read_block``)."""
        return read_block(self.bus, device_id, address, size)

    def cube_sensor(self, index: int = 0) -> CubeSensor:
        """The virtual lab's cube sensor on this bus (``sensors.cube_reader``), cube ``index``."""
        return CubeSensor(self.read_block, index)

    def close(self) -> None:
        """Close the port, torque left as it is (``hw.bus.disconnect``; release it first).

        The guarded bus of ``setup_motors`` stays open: it ends as the course's helpers end
        (``bus.disable_torque()``, or when the script exits).
        """
        if getattr(self.bus, "raw", None) is None:
            disconnect(self.bus)

    def __repr__(self) -> str:
        return f"BusArm({self.name!r})"
