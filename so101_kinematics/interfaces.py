"""The seams: what any arm, any sensor and any camera offers the program that drives it.

An :class:`Arm` is the simulator (``sim/sim_arm.py``: ``SimArm``), the virtual
SO-101 or the real one (both through lerobot's bus: ``hw/bus_arm.py``:
``BusArm``); a :class:`Sensor` is anything read once per cycle beside the arm
(the virtual lab's cube sensor: ``sensors/cube_reader.py``); a :class:`Camera`
is the sensor whose reading is an image (issue 36 implements them: the
simulator's rendered cameras, the virtual arm's, a real webcam). A program
written against these runs on each backend unchanged, and two of them (two
arms, each with its own sensors) live in one process side by side: every
object here owns its state (docs/architecture.md, "Parts that plug in").

The units are the course's and lerobot's: arm joints in degrees, the gripper
0-100 (``inputs.py``). The protocols are ``runtime_checkable``: ``isinstance``
checks that the methods are there (not their signatures; the tests check the
behaviour).

Example:
    >>> class Still:
    ...     name = "still"
    ...     def read(self):
    ...         return 1.0
    ...     def close(self):
    ...         pass
    >>> isinstance(Still(), Sensor), isinstance(Still(), Camera)
    (True, False)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["Arm", "Camera", "Sensor"]


@runtime_checkable
class Arm(Protocol):
    """One SO-101, whatever drives it: what the course's control loop needs from a backend.

    The loop is ``read_positions`` -> compute -> ``send_goal`` -> ``advance`` (one
    cycle), as the course's 50 Hz hardware loop and its ``mj_step`` loop both are.
    """

    name: str
    """Which arm (``"left"``, ``"right"``, ``"follower-1"``): its messages say it."""

    def read_positions(self) -> dict[str, float]:
        """Where the arm is now: every joint of ``frames.JOINTS`` [deg], gripper [0, 100]."""
        ...

    def send_goal(self, goal: Mapping[str, float]) -> None:
        """Set the goal positions ([deg], gripper [0, 100]); a joint left out keeps its goal.

        Refused (one line, nothing sent) outside the arm's range; on a bare bus also a
        goal the servos would jump to (``hw/bus_arm.py``: send a path in small steps).
        It returns at once (the servos move on their own; :meth:`advance` lets time
        pass), except on a guarded bus (``so101_utils.setup_motors``), which ramps
        there and returns when the arm arrived.
        """
        ...

    def torque_enabled(self) -> dict[str, bool]:
        """Whether each joint's servo holds (torque on), as the arm reports it."""
        ...

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` pass for the arm: the simulator steps its physics; a bus waits."""
        ...

    def close(self) -> None:
        """Let go of the arm's connection; torque stays as it is (holding is safer)."""
        ...


@runtime_checkable
class Sensor(Protocol):
    """Anything read beside the arm: one reading per :meth:`read`, fresh each time."""

    name: str
    """Which sensor (``"cube"``, ``"wrist"``, ``"overhead"``): its key in a program's dict."""

    def read(self) -> Any:
        """The reading now (a sensor's own type; None when it sees nothing)."""
        ...

    def close(self) -> None:
        """Let go of what the sensor holds (a device, a thread); the arm it rides on stays."""
        ...


@runtime_checkable
class Camera(Sensor, Protocol):
    """A sensor whose reading is an image, with the numbers that turn pixels into rays.

    The seam issue 36's cameras implement (the simulator's, the virtual arm's, a
    real one through OpenCV); one detection path reads them all.
    """

    width: int
    """Image width [pixels]."""
    height: int
    """Image height [pixels]."""

    def read(self) -> np.ndarray:
        """The image now: ``height`` x ``width`` x 3, uint8, RGB (not OpenCV's BGR)."""
        ...

    def intrinsics(self) -> np.ndarray:
        """The camera matrix, OpenCV's 3x3 ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` [pixels]."""
        ...
