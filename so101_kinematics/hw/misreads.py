"""A reading no servo could give is a misread, not a pose: the control loop never acts on it.

A reply that passes the bus's checksum can still be misparsed (a late reply read as the
next one, a byte lost on a half-duplex line): seen once on the virtual arm through
lerobot 0.4.4's bus on a loaded machine, every arm joint read about -2900 deg for one
cycle (values 256 counts apart, the servo IDs landing in the high byte). Acted on, such
a pose is dangerous: a controlled stop commands "the present position" clamped to the
calibrated range, which would drive every joint at full speed to its lower limit.

:class:`ReadingCheck` refuses a pose that is

- outside the calibrated range by more than :data:`RANGE_MARGIN` (a joint cannot be far
  past the stops its calibration recorded), or
- further from the last accepted pose than :data:`MAX_PLAUSIBLE_SPEED_DEG_S` allows in
  the time between them (arm joints; the gripper's unit is not degrees). A servo samples its
  position somewhere between the request and the reply, so that time is the longest the two
  samples can be apart: from the start of the last accepted read to the end of this one. (The
  ends alone were once 1 ms apart for a 2.8 deg step of a swinging shoulder_pan: the last
  read's end stamped late on a loaded machine, CI's slow leg, 2026-12-04.)

A refused reading raises :class:`Misread`, which the loop handles as a failed read (the
plan pauses, the servos hold their last goals, the next read decides).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.servo import VARIANTS

__all__ = ["Misread", "ReadingCheck"]

RANGE_MARGIN = 30.0
"""How far past its calibrated range [deg; gripper: 0-100 units] a reading may be.

Calibration records the stops a hand reached; a joint pushed a little further, or a
trim, reads a few degrees past them. 30 is ten times that, and a hundredth of the
misread above."""

MAX_PLAUSIBLE_SPEED_DEG_S = 2.0 * max(
    math.degrees(variant.no_load_speed(variant.nominal_volts)) for variant in VARIANTS.values())
"""Twice the fastest STS3215's no-load speed (the C001's datasheet: 52 rpm = 312 deg/s at
7.4 V, ``servo.VARIANTS``): no joint of the arm moves faster, driven or back-driven."""

NOISE_DEG = 2.0
"""Allowed on top of the speed: a count or two of encoder noise and gear play [deg]."""


class Misread(ConnectionError):
    """A reading no servo could give (a misparsed reply): handled as a failed read."""


class ReadingCheck:
    """Accepts a pose only when the servos could be there (see the module's docstring)."""

    def __init__(self, limits: Mapping[str, tuple[float, float]]):
        self.limits = dict(limits)
        self.last: dict[str, float] | None = None
        self.last_time: float | None = None  # [s] when the last accepted read began
        self.refused = 0

    def __call__(self, pose: Mapping[str, float], now: float,
                 started: float | None = None) -> Mapping[str, float]:
        """``pose`` if plausible; raises :class:`Misread` otherwise.

        Args:
            pose: the reading.
            now: [s] when the read ended (its reply in).
            started: [s] when the read began (its request sent; default ``now``).
        """
        for joint, value in pose.items():
            lower, upper = self.limits[joint]
            if not (lower - RANGE_MARGIN <= value <= upper + RANGE_MARGIN):
                self._refuse(f"{joint} read {value:.1f}, outside its calibrated range "
                             f"[{lower:.1f}, {upper:.1f}] by more than {RANGE_MARGIN:g}")
        if self.last is not None:
            elapsed = max(0.0, now - self.last_time)
            allowed = MAX_PLAUSIBLE_SPEED_DEG_S * elapsed + NOISE_DEG
            for joint in ARM_JOINTS:
                jump = abs(pose[joint] - self.last[joint])
                if jump > allowed:
                    # Either this reading or the last accepted one was wrong: the next
                    # is judged by the range alone, so one bad pose never locks out the rest.
                    self.forget()
                    self._refuse(f"{joint} read {pose[joint]:.1f}, {jump:.1f} deg from "
                                 f"{elapsed * 1e3:.0f} ms before (at most {allowed:.1f})")
        self.last, self.last_time = dict(pose), now if started is None else min(started, now)
        return pose

    def forget(self) -> None:
        """Drop the last pose (after the arm was let go or moved by hand)."""
        self.last = self.last_time = None

    def _refuse(self, why: str) -> None:
        self.refused += 1
        raise Misread(f"a reading no servo could give, not acted on: {why}")
