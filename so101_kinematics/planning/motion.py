"""Joint-space motion shared by the simulated and the real SO-101.

One place for what both backends must agree on: the interpolation between
two configurations (:class:`Trajectory`, with one of ``profiles.py``'s time
scalings: direct, linear, cubic, quintic, minimum-jerk), the plan's shape
(:class:`Step`, :class:`Plan`) and the runner that executes a plan through a
backend's ``move_to_pose`` / ``hold_position`` (:func:`run_plan`). The plans
themselves are ``plans.py``'s; the checks ``inputs.py``'s. The backends
(``sim/stepping.py`` for MuJoCo, ``hw/control.py`` for a lerobot bus) only
decide how time passes and how a command reaches the arm.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from so101_kinematics.errors import PlanError
from so101_kinematics.inputs import Configuration, check_number
from so101_kinematics.planning.profiles import PROFILES

__all__ = ["Plan", "Step", "Trajectory", "run_plan"]


@dataclass(frozen=True)
class Trajectory:
    """Joint-space path from ``start`` to ``goal`` in ``duration`` [s].

    Example:
        >>> path = Trajectory({"gripper": 0.0}, {"gripper": 100.0}, 2.0, "minimum_jerk")
        >>> path.at(1.0)  # halfway in time is halfway in space for this profile
        {'gripper': 50.0}
    """

    start: Mapping[str, float]
    goal: Mapping[str, float]
    duration: float
    profile: str = "minimum_jerk"

    def __post_init__(self):
        if not isinstance(self.profile, str) or self.profile not in PROFILES:
            raise PlanError(f"Unknown profile {self.profile!r}; use one of {', '.join(PROFILES)}.")
        # Finite and >= 0; no upper bound here: a trajectory only stores its ends.
        object.__setattr__(self, "duration", check_number(self.duration, "Trajectory duration",
                                                          0.0, math.inf, "s"))

    def fraction(self, t: float) -> float:
        """Fraction of the way from start to goal at time ``t`` [s] (0 before, 1 after)."""
        s = 1.0 if self.duration <= 0.0 else min(max(t / self.duration, 0.0), 1.0)
        return PROFILES[self.profile](s)

    def fractions(self, times: np.ndarray) -> np.ndarray:
        """:meth:`fraction` for an array of times [s] at once."""
        if self.duration <= 0.0:
            return np.ones(np.shape(times))
        return PROFILES[self.profile](np.clip(np.asarray(times, dtype=float) / self.duration,
                                              0.0, 1.0))

    def at(self, t: float) -> Configuration:
        """Configuration at time ``t`` [s] after the start (held at the ends)."""
        alpha = self.fraction(t)
        return {j: self.start[j] + alpha * (self.goal[j] - self.start[j]) for j in self.goal}

    def rates(self, times: np.ndarray) -> np.ndarray:
        """d(fraction)/dt [1/s] at each time [s]: 0 before the start and after the end."""
        times = np.asarray(times, dtype=float)
        if self.duration <= 0.0:
            return np.zeros(np.shape(times))
        s = times / self.duration
        inside = (s >= 0.0) & (s <= 1.0)
        return np.where(inside, PROFILES[self.profile].velocity(np.clip(s, 0.0, 1.0)),
                        0.0) / self.duration

    def velocity_at(self, t: float) -> Configuration:
        """Velocity at time ``t`` [s] ([deg/s], gripper [%/s]); zero outside the move.

        Example:
            >>> Trajectory({"gripper": 0.0}, {"gripper": 100.0}, 2.0, "cubic").velocity_at(1.0)
            {'gripper': 75.0}
        """
        rate = float(self.rates(np.array([t]))[0])
        return {j: rate * (self.goal[j] - self.start[j]) for j in self.goal}

    def acceleration_at(self, t: float) -> Configuration:
        """Acceleration at time ``t`` [s] ([deg/s^2], gripper [%/s^2]); zero outside the move."""
        if self.duration <= 0.0 or not 0.0 <= t <= self.duration:
            return dict.fromkeys(self.goal, 0.0)
        rate = float(PROFILES[self.profile].acceleration(t / self.duration)) / self.duration**2
        return {j: rate * (self.goal[j] - self.start[j]) for j in self.goal}


@dataclass
class Step:
    """One waypoint: move to ``configuration`` in ``duration`` [s], then hold ``hold`` [s]."""

    name: str
    configuration: Configuration
    duration: float = 2.0
    hold: float = 0.5


@dataclass
class Plan:
    """A named sequence of steps; ``return_to_start`` ends back at the initial pose."""

    steps: list[Step] = field(default_factory=list)
    return_to_start: bool = True
    return_duration: float = 2.0

    def configurations(self) -> dict[str, Configuration]:
        """Step name -> configuration."""
        return {step.name: step.configuration for step in self.steps}



def run_plan(
    plan: Plan,
    move_to_pose: Callable[[Mapping[str, float], float], None],
    hold_position: Callable[[float], None],
    initial: Mapping[str, float] | None = None,
    on_step: Callable[[Step], None] | None = None,
    then: Callable[[], None] | None = None,
) -> None:
    """Execute a validated plan through a backend.

    Args:
        plan: the plan (already validated).
        move_to_pose: ``move_to_pose(cfg, duration)`` of the backend.
        hold_position: ``hold_position(duration)`` of the backend.
        initial: the pose to return to at the end (if ``plan.return_to_start``).
        on_step: called with each step before it starts (progress reporting).
        then: called after the steps, before the return: a closed loop that moves through
            the same backend (the tag follower, ``lab/follow_tag_arm.py``).
    """
    for step in plan.steps:
        if on_step is not None:
            on_step(step)
        move_to_pose(step.configuration, step.duration)
        if step.hold > 0:
            hold_position(step.hold)
    if then is not None:
        then()
    if plan.return_to_start and initial is not None:
        if on_step is not None:
            on_step(Step("return_to_start", dict(initial), plan.return_duration, 0.0))
        move_to_pose(initial, plan.return_duration)
