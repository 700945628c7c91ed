"""The control loop's options of ``pick_place_hw.py``.

The profile, the velocity lead, the rate, the speed cap and the tracking tolerance; their
ranges are ``hw/control.py``'s.
"""

from __future__ import annotations

import argparse

from so101_kinematics.hw.control import TRACKING_TIMEOUT_S, TRACKING_TOLERANCE_LIMIT_DEG
from so101_kinematics.hw.lead import add_velocity_ff_argument
from so101_kinematics.hw.timing import (
    DEFAULT_RATE_HZ,
    MAX_JOINT_SPEED_DEG_S,
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    SPEED_CAP_LIMIT_DEG_S,
    TRACKING_TOLERANCE_DEG,
)
from so101_kinematics.planning.profiles import SPEED_CAPPED_PROFILES

__all__ = ["add_loop_arguments"]


def add_loop_arguments(parser: argparse.ArgumentParser) -> None:
    """``--profile``, ``--velocity-ff``, ``--rate``, ``--max-speed``, ``--tracking-tolerance``."""
    parser.add_argument("--profile", choices=sorted(SPEED_CAPPED_PROFILES),
                        default="minimum_jerk",
                        help="time scaling of each move (default minimum_jerk, as the simulator)")
    add_velocity_ff_argument(parser)
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ,
                        help=f"control loop rate [Hz] ({MIN_RATE_HZ:g}-{MAX_RATE_HZ:g}, "
                             f"default {DEFAULT_RATE_HZ:g})")
    parser.add_argument("--max-speed", type=float, default=MAX_JOINT_SPEED_DEG_S,
                        help=f"speed cap of each arm joint [deg/s] (up to "
                             f"{SPEED_CAP_LIMIT_DEG_S:g}, default {MAX_JOINT_SPEED_DEG_S:g}); "
                             "too-short moves are stretched")
    parser.add_argument("--tracking-tolerance", type=float, default=TRACKING_TOLERANCE_DEG,
                        help=f"stop when a joint is this far from its command [deg] for "
                             f"{TRACKING_TIMEOUT_S:g} s (up to {TRACKING_TOLERANCE_LIMIT_DEG:g}, "
                             f"default {TRACKING_TOLERANCE_DEG:g})")
