"""Time on the real arm: the deadline scheduler, the loop's timeline records, the speed cap.

:class:`RateLoop` runs the control loop on a fixed grid of deadlines, on the wall
clock or on any :class:`TimeSource` (the virtual arm's simulated clock,
``virtual/sim_clock.py``);
:func:`capped_duration` stretches a move that would exceed a joint's speed
cap; :func:`check_rate` bounds the loop's rate.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import NamedTuple, Protocol

from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINTS
from so101_kinematics.inputs import Configuration, check_number, unit
from so101_kinematics.planning.profiles import PROFILES, SPEED_CAPPED_PROFILES

__all__ = [
    "Cycle", "DEFAULT_RATE_HZ", "MAX_GRIPPER_SPEED_PCT_S", "MAX_JOINT_SPEED_DEG_S",
    "MAX_RATE_HZ", "MIN_RATE_HZ", "RateLoop", "SPEED_CAP_LIMIT_DEG_S", "SPIN_S", "Segment",
    "TRACKING_TOLERANCE_DEG", "TimeSource", "capped_duration", "check_profile", "check_rate",
    "loop_timing_stats", "peak_speed_factor", "speed_caps", "stretch_warning",
    "tracking_tolerances",
]

DEFAULT_RATE_HZ = 100.0            # control loop rate [Hz]
MIN_RATE_HZ = 20.0                 # slower, one cycle's step at the speed cap exceeds 5 deg
MAX_RATE_HZ = 500.0                # a 6-motor cycle takes about 1.1 ms on the wire and host
MAX_JOINT_SPEED_DEG_S = 100.0      # speed cap of each arm joint [deg/s] (peak of the profile)
SPEED_CAP_LIMIT_DEG_S = 180.0      # the highest cap accepted: 2/3 of the STS3215's no-load
                                   # speed at 7.4 V (0.222 s/60 deg = 270 deg/s) [deg/s]
MAX_GRIPPER_SPEED_PCT_S = 100.0    # speed cap of the gripper [%/s]
TRACKING_TOLERANCE_DEG = 15.0      # measured vs commanded, arm joints [deg]
SPIN_S = 0.0005                    # busy-wait this last part of each period [s]
IDLE_RESTART_S = 0.25              # a loop idle for longer starts a fresh deadline grid [s]


# --- Speed cap ---------------------------------------------------------------
PEAK_SPEED_FACTOR = {name: p.peak_speed for name, p in PROFILES.items()
                     if name in SPEED_CAPPED_PROFILES}
"""Peak of d(fraction)/ds of each time scaling a speed cap can stretch (``profiles.py``): 1 for
linear; 6 s (1 - s) peaks at s = 1/2 for the cubic: 3/2; 30 s^2 (1 - s)^2 for minimum jerk
(the quintic): 15/8. ``direct`` (a step) has none: the real arm refuses it."""


def check_profile(profile: str) -> str:
    """``profile`` if the real arm runs it (a speed cap can stretch it), else a PlanError."""
    if profile in SPEED_CAPPED_PROFILES:
        return profile
    why = (" is a step, which no speed cap can slow" if profile == "direct" else
           " is not a profile")
    raise PlanError(f"profile {profile!r}{why}. "
                    f"Fix: use one of {', '.join(SPEED_CAPPED_PROFILES)}.")


def peak_speed_factor(profile: str) -> float:
    """Peak speed of a move over its mean speed, for a time-scaling profile (exact)."""
    return PEAK_SPEED_FACTOR[profile]


def speed_caps(max_joint_speed: float = MAX_JOINT_SPEED_DEG_S,
               max_gripper_speed: float = MAX_GRIPPER_SPEED_PCT_S) -> dict[str, float]:
    """Joint -> speed cap ([deg/s]; gripper [%/s])."""
    return {j: (max_gripper_speed if j == "gripper" else max_joint_speed) for j in JOINTS}


def tracking_tolerances(arm_tolerance: float = TRACKING_TOLERANCE_DEG) -> dict[str, float | None]:
    """Joint -> tracking tolerance [deg].

    The gripper is not checked: it squeezes the cube by design, and lerobot's
    configuration limits its torque and current instead.
    """
    return {j: (None if j == "gripper" else arm_tolerance) for j in JOINTS}


def capped_duration(start: Mapping[str, float], goal: Mapping[str, float], duration: float,
                    profile: str, max_speed: Mapping[str, float]) -> float:
    """The shortest duration >= ``duration`` [s] that keeps every joint under its speed cap.

    Args:
        start: configuration at the start ([deg], gripper [0, 100]).
        goal: configuration at the end.
        duration: the requested duration [s].
        profile: time scaling of the move (one of ``SPEED_CAPPED_PROFILES``).
        max_speed: joint -> cap ([deg/s]; gripper [%/s]).

    Example:
        >>> capped_duration({"shoulder_pan": 0.0}, {"shoulder_pan": 90.0}, 1.0, "linear",
        ...                 {"shoulder_pan": 45.0})
        2.0
    """
    factor = peak_speed_factor(profile)
    needed = max((abs(goal[j] - start[j]) * factor / max_speed[j] for j in goal), default=0.0)
    return max(float(duration), needed)


def stretch_warning(step: str, start: Mapping[str, float], goal: Mapping[str, float],
                    requested: float, duration: float, max_speed: Mapping[str, float]) -> str:
    """The warning for a move the speed cap stretched from ``requested`` to ``duration`` [s]."""
    fastest = max(goal, key=lambda j: abs(goal[j] - start[j]) / max_speed[j])
    return (f"'{step}': {requested:.2f} s is too fast for the speed cap ({fastest} moves "
            f"{abs(goal[fastest] - start[fastest]):.1f} {unit(fastest)}); stretched to "
            f"{duration:.2f} s.")


# --- Deadline scheduler ----------------------------------------------------------
class TimeSource(Protocol):
    """Where a run's time comes from, when not from the wall clock.

    ``clock()`` [s] and ``sleep(seconds)`` as ``time.perf_counter`` and ``time.sleep``;
    ``spin`` [s]: the last part of each wait the loop busy-waits (``SPIN_S`` on the wall
    clock, whose sleep wakes late; 0 where a sleep is exact, as the virtual arm's simulated
    clock: ``virtual/sim_clock.py``'s ``SimClock``).
    """

    spin: float

    def clock(self) -> float:
        """Now [s]."""

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` [s] pass."""


class RateLoop:
    """Fixed-rate, deadline-scheduled loop: ``next_deadline += period``, sleep, spin the last bit.

    A late cycle is counted as an overrun and the loop runs on at once; when
    more than a whole period late, the missed deadlines are skipped (never
    replayed in a burst).

    Args:
        rate_hz: loop rate [Hz].
        clock: monotonic clock [s].
        sleep: sleep function [s].
        spin: busy-wait this last part of each wait [s].
    """

    def __init__(self, rate_hz: float, clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep, spin: float = SPIN_S):
        if not (isinstance(rate_hz, (int, float)) and 0 < rate_hz <= MAX_RATE_HZ):
            raise ValueError(f"rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}.")
        self.period = 1.0 / float(rate_hz)
        self.clock, self.sleep, self.spin = clock, sleep, spin
        self.deadline: float | None = None
        self.woke = 0.0  # when the last wait returned [s]
        self.cycles = self.overruns = self.skipped = 0

    def start(self) -> float:
        """Make now the current deadline; returns it [s]."""
        self.deadline = self.woke = self.clock()
        return self.deadline

    def resume(self) -> float:
        """The grid point a new segment starts from: the latest deadline not in the future.

        Continues the grid (skipping missed deadlines) when the loop was busy
        until now; starts afresh after an idle gap longer than ``IDLE_RESTART_S``.
        """
        if self.deadline is None:
            return self.start()
        behind = self.clock() - self.deadline
        if behind > IDLE_RESTART_S:
            return self.start()
        if behind >= self.period:
            missed = int(behind // self.period)
            self.skipped += missed
            self.deadline += missed * self.period
        return self.deadline

    def wait(self) -> float:
        """Wait for the next deadline and return it (the cycle's scheduled time [s])."""
        if self.deadline is None:
            self.start()
        self.deadline += self.period
        now = self.clock()
        late = now - self.deadline
        if late > 0.0:
            self.overruns += 1
            if late >= self.period:
                missed = int(late // self.period)
                self.skipped += missed
                self.deadline += missed * self.period
        else:
            remaining = -late
            if remaining > self.spin:
                self.sleep(remaining - self.spin)
            while self.clock() < self.deadline:
                pass
        self.cycles += 1
        self.woke = self.clock()
        return self.deadline


def loop_timing_stats(wake_times: list[float], rate_hz: float) -> dict[str, float]:
    """Period statistics of a loop from the times its cycles started [s].

    Returns:
        ``achieved_hz``, ``period_p50_ms``, ``period_p99_error_ms`` (99th percentile
        of |period - nominal|), ``period_max_error_ms`` and ``cycles``.
    """
    import numpy as np

    times = np.asarray(wake_times, dtype=float)
    if times.size < 3:
        raise ValueError("need at least 3 cycles for timing statistics")
    periods = np.diff(times)
    error = np.abs(periods - 1.0 / rate_hz)
    return {
        "rate_hz": float(rate_hz),
        "achieved_hz": float((times.size - 1) / (times[-1] - times[0])),
        "period_p50_ms": float(np.median(periods) * 1e3),
        "period_p99_error_ms": float(np.percentile(error, 99) * 1e3),
        "period_max_error_ms": float(error.max() * 1e3),
        "cycles": int(times.size),
    }


def check_rate(rate_hz) -> float:
    """The control loop's rate [Hz], refused outside [MIN_RATE_HZ, MAX_RATE_HZ]."""
    return check_number(rate_hz, "--rate", MIN_RATE_HZ, MAX_RATE_HZ, "Hz")


# --- The loop's timeline ------------------------------------------------------------
class Cycle(NamedTuple):
    """One control cycle: scheduled and wake time since start [s], step, command, measurement.

    ``lead``: joint -> how far the goal written led ``command`` (the velocity feed-forward,
    ``hw/lead.py``) [deg], or None when the plan was written as it is.
    """

    t_s: float
    wall_s: float
    step: str
    command: Configuration
    measured: Configuration | None
    lead: Configuration | None = None


@dataclass
class Segment:
    """A move or a hold as executed, on the session's timeline."""

    kind: str  # "move" or "hold"
    step: str
    t_start_s: float  # [s] since the session's first cycle was scheduled
    start: Configuration
    goal: Configuration
    duration: float  # [s], after the speed cap
    requested: float  # [s], as asked
