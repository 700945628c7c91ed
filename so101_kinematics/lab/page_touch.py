"""The page's marks touched with the pen's tip on an arm made limp: the tip's positions read.

The half of ``register_page.py --port PORT`` that uses an arm (the real one, or the virtual
arm moved by its hand): torque off on every servo, as ``read_position.py`` does; for each
mark the student puts the pen's tip on it and confirms; the servos' present positions are
read and turned into the tip's position by the pen's FK (``drawing/pen.py``: the holder in
the jaws, the tip ``PEN_TIP_BELOW_CENTRE`` below its centre, the spring at rest).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from so101_kinematics.drawing.pen import tip_position
from so101_kinematics.drawing.registration import MARK_NAMES
from so101_kinematics.hw.bus import connect, disconnect, read_pose

__all__ = ["TOUCH_READ_RETRIES", "touch_marks"]

TOUCH_READ_RETRIES = 3
"""Reads of the present positions retried at one touch (the arm is in a hand: no hurry)."""


def touch_marks(port: str, calibration: Mapping[str, Any], count: int,
                confirm: Callable[[str], object]) -> np.ndarray:
    """The pen tip's (x, y) [m] at each of ``count`` marks, touched by hand, torque off.

    Args:
        port: the arm's serial port.
        calibration: its lerobot calibration (``calibration.load_calibration``).
        count: how many marks (3 or 4), touched in ``MARK_NAMES``' order.
        confirm: called with a prompt for each mark; returns when the tip is on it
            (``input`` at a terminal).

    Returns:
        (count, 2) the tip's base-frame (x, y) [m] at each mark, in order.
    """
    bus = connect(port, calibration)
    try:
        bus.disable_torque()
        touched = []
        for index, name in enumerate(MARK_NAMES[:count]):
            confirm(f"Put the pen's tip on mark {index + 1} ({name}) and press Enter: ")
            touched.append(tip_position(read_pose(bus, TOUCH_READ_RETRIES))[:2])
    finally:
        disconnect(bus)
    return np.array(touched)
