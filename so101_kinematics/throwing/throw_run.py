"""Throws in the simulator: the swing rehearsed, the release timed, the ball thrown and checked.

One throw (:func:`throw_at`):

1. the plan (``throw_plan.plan_throw``): pan, release speed, the joints' rate, the swing;
2. a rehearsal: the swing run with the ball kept in the gripper, the ball's state recorded at
   every physics step around the planned release; the forward model (``ball.flight``) gives
   each state's landing, and the release is timed at the step whose landing is nearest the
   cup (the servos lag and cap their speed, so the speed reached is the rehearsal's, not the
   plan's); if no step in the window reaches the cup, the joints' rate is scaled and the
   swing rehearsed again, never beyond the servos' top speed;
3. the throw: the same commands, the gripper's open command sent the opening delay
   (:func:`opening_delay`, measured) before the chosen step; the ball flies from where the
   jaw has opened enough (``throw_scene.Flight``) and its first touch and resting place
   are recorded;
4. the figures: the forward model run from the simulated release state to the height of
   the first touch, against the touch (``model_error_m``), and in the cup or not.

Every command runs on the arm's 100 Hz control period, each leading the plan by the servo's
lag (``servo.lag``), with the gravity feed-forward on (the simulator's default servo).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics import servo
from so101_kinematics.errors import PlanError
from so101_kinematics.planning.straight_line import CONTROL_DT
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import send_position_command, set_initial_pose
from so101_kinematics.throwing.ball import Ball, flight
from so101_kinematics.throwing.throw_plan import (
    GRIPPER_HOLD,
    ThrowPlan,
    joint_speed_limits,
    plan_throw,
)
from so101_kinematics.throwing.throw_scene import (
    CUP_HEIGHT,
    Flight,
    hold_ball,
    in_cup,
    place_cup,
)

__all__ = [
    "AIM_TOLERANCE_M", "OPEN", "RELEASE_WINDOW", "SETTLE_S", "ThrowRun", "TunedThrow", "fly",
    "opening_delay", "throw_at", "tune_throw",
]

AIM_TOLERANCE_M = 0.015
"""A rehearsed release whose landing is this near the cup's centre, and nearer than its
neighbours' (one physics step earlier or later), is good [m]; the earliest good one is chosen
(the ball thrown upwards, not a late throw down at the cup). A 4 ms step moves the landing
1.0-1.7 cm, so the nearest of a pass can be 8 mm away."""
SETTLE_S = 0.5
"""The arm rests at the wind-up this long before the swing [s]."""
RELEASE_WINDOW = (0.4, 0.85)
"""The release is timed within this part of the swing (0.5: the planned release)."""
REHEARSALS = 6
"""The most rehearsals of one throw."""
AFTER_TOUCH_S = 0.6
"""The simulation runs on this long after the ball's first touch [s] (where it rests)."""
OPEN = 100.0
"""The gripper's command at the release [%]: fully open, the fastest opening."""


class ThrowRun:
    """One simulated swing of a plan: commands at the control period, the ball stepped.

    Args:
        m: the throwing model (``throw_scene.build_throw_model``).
        ball: the ball in it.
        plan: the planned throw.
        open_at: the time [s] from the swing's start at which the gripper is told to open
            (None: it stays closed, a rehearsal).
        cup: where the cup stands (x, y) [m] (default the plan's target; the throw aimed at
            a cup the camera saw stands where it truly is).
    """

    def __init__(self, m: mujoco.MjModel, ball: Ball, plan: ThrowPlan, open_at: float | None,
                 cup=None):
        self.m, self.ball, self.plan, self.open_at = m, ball, plan, open_at
        self.d = d = mujoco.MjData(m)
        self.cup = tuple(plan.target if cup is None else cup)
        place_cup(m, d, *self.cup)
        set_initial_pose(d, plan.configuration(0.0))
        hold_ball(m, d)
        spec = actuation.servo_spec(m)
        faithful = spec is not None and spec.mode != "ideal"
        self.lead = (servo.lag(1.0, spec.settings[0], spec.volts, spec.variant)
                     if faithful else 0.0)
        self.steps = max(1, round(CONTROL_DT / m.opt.timestep))
        self.flight: Flight | None = None
        self.start = SETTLE_S

    def command(self, t: float) -> dict[str, float]:
        """The configuration [deg] sent at time ``t`` [s]: the plan led by the servo's lag."""
        fraction = (t - self.start) / self.plan.duration
        cfg = self.plan.configuration(fraction)
        for joint, rate in self.plan.rates_deg(fraction).items():
            cfg[joint] += self.lead * rate
        cfg["gripper"] = OPEN if self._opened(t) else GRIPPER_HOLD
        return cfg

    def _opened(self, t: float) -> bool:
        """Whether the gripper has been told to open by time ``t`` [s]."""
        return self.open_at is not None and t >= self.start + self.open_at - 1e-9

    def run(self, until: float, record=None) -> None:
        """Run to ``until`` [s] of simulation time; ``record(self)`` after each physics step."""
        d = self.d
        while d.time < until - 1e-9:
            send_position_command(d, self.command(d.time))
            for _ in range(self.steps):
                if self._opened(d.time):  # the open command is written when due, off the cycle
                    send_position_command(d, {"gripper": OPEN})
                if self.flight is None and d.time >= self.start - 1e-9:
                    self.flight = Flight(self.m, d, self.ball,
                                         float(d.qpos[self.m.joint("gripper").qposadr[0]]))
                if self.flight is None:
                    actuation.step(self.m, d, 1)
                else:
                    self.flight.step()
                if record is not None:
                    record(self)


def _rehearse(m, ball: Ball, plan: ThrowPlan) -> tuple[np.ndarray, np.ndarray]:
    """The swing rehearsed with the ball held: its states in the release window, their landings.

    Returns:
        ``(states, landings)``: (n, 7) rows t [s from the swing's start], x, y, z [m], vx, vy,
        vz [m/s]; and each one's landing at the rim's height, (n, 4) rows (x, y, z, flight time).
    """
    run = ThrowRun(m, ball, plan, None)
    low, high = (run.start + f * plan.duration for f in RELEASE_WINDOW)
    rows = []

    def record(r: ThrowRun) -> None:
        if low <= r.d.time <= high:
            position, velocity = r.flight.ball_state()
            rows.append((r.d.time - r.start, *position, *velocity))

    run.run(high + 1e-6, record)
    states = np.array(rows)
    return states, flight(states[:, 1:4], states[:, 4:7], ball, CUP_HEIGHT)


def _best_release(landings, target) -> tuple[int, float]:
    """The row whose landing is nearest ``target``; how far [m] the farthest falls short of it.

    The shortfall is 0 when some landing reaches the target's distance from the base.
    """
    target = np.asarray(target, dtype=float)
    miss = np.linalg.norm(landings[:, :2] - target, axis=1)
    if np.isnan(miss).all():
        return 0, math.inf
    filled = np.where(np.isnan(miss), np.inf, miss)
    before, after = np.r_[np.inf, filled[:-1]], np.r_[filled[1:], np.inf]
    good = np.flatnonzero((filled <= before) & (filled <= after) & (filled <= AIM_TOLERANCE_M))
    best = int(good[0]) if len(good) else int(np.nanargmin(miss))  # the earliest: thrown up
    farthest = float(np.nanmax(np.hypot(landings[:, 0], landings[:, 1])))
    return best, max(0.0, float(np.linalg.norm(target)) - farthest)


def opening_delay(m: mujoco.MjModel, ball: Ball, plan: ThrowPlan) -> float:
    """The time [s] from the gripper's open command until the ball is free, the arm at rest.

    Measured in the simulator with the model's servo: the wind-up held, the gripper told to
    open, stepped until the moving jaw has opened ``throw_scene.RELEASE_OPENING_DEG``.
    """
    still = ThrowPlan(plan.pan_deg, plan.release_point, plan.release_velocity, plan.rate,
                      1e9, plan.target)
    run = ThrowRun(m, ball, still, open_at=0.0)
    run.run(run.start + 1.0)
    if run.flight is None or run.flight.release is None:
        raise PlanError("the gripper did not open far enough to let the ball go in 1 s. Fix: "
                        "check the gripper's servo settings (its torque limit).")
    return run.flight.release[0] - run.start


def _tune(m, ball: Ball, plan: ThrowPlan, limits: Mapping[str, float]):
    """Rehearse, scaling the joints' rate until a release in the window reaches the cup."""
    for _ in range(REHEARSALS):
        states, landings = _rehearse(m, ball, plan)
        best, shortfall = _best_release(landings, plan.target)
        if shortfall <= 0.0 or not math.isfinite(shortfall):
            return plan, states, landings, best
        rate = plan.rate * (1.0 + 0.6 * shortfall / float(np.linalg.norm(plan.target)))
        top = min(limits.values())
        if rate > top:
            raise PlanError(f"the cup at {np.linalg.norm(plan.target):.3f} m needs the swing at "
                            f"{rate:.2f} rad/s, above the servos' {top:.2f} rad/s (the STS3215 "
                            "model, loaded). Fix: a nearer cup, or a higher supply (--supply).")
        plan = ThrowPlan(plan.pan_deg, plan.release_point, plan.release_velocity * rate / plan.rate,
                         rate, plan.duration * plan.rate / rate, plan.target)
    return plan, states, landings, best


@dataclass(frozen=True)
class TunedThrow:
    """A throw rehearsed in the simulator: the commands the arm runs, and when it opens.

    Attributes:
        planned_speed: the Jacobian plan's release speed [m/s] (before the rehearsal).
        plan: the rehearsed plan (its rate scaled until a release reaches the cup).
        limits: the swinging servos' top speeds at the release [rad/s].
        release_at: the release the throw is timed on [s from the swing's start].
        resting_delay: the gripper's opening delay at rest [s] (:func:`opening_delay`).
        delay: the opening delay in the swing [s]: the gripper is told to open this long
            before ``release_at``.
        aimed: the rehearsed release's landing at the rim's height (x, y, z, t).
    """

    planned_speed: float
    plan: ThrowPlan
    limits: Mapping[str, float]
    release_at: float
    resting_delay: float
    delay: float
    aimed: np.ndarray

    @property
    def open_at(self) -> float:
        """When the gripper is told to open [s from the swing's start]."""
        return self.release_at - self.delay


def tune_throw(m: mujoco.MjModel, ball: Ball, target, volts: float = servo.DEFAULT_SUPPLY_V,
               variant: str = servo.DEFAULT_VARIANT, delay: float | None = None) -> TunedThrow:
    """Plan, rehearse and time a throw at ``target`` (x, y) [m] (steps 1-2 of the module).

    Raises:
        PlanError: the cup out of range, a speed the servos cannot reach.
    """
    plan = plan_throw(m, target, ball, volts, variant)
    limits = joint_speed_limits(m, plan.pan_deg, volts, variant)
    planned_speed = float(np.linalg.norm(plan.release_velocity))
    tuned, states, landings, best = _tune(m, ball, plan, limits)
    resting_delay = opening_delay(m, ball, tuned) if delay is None else delay
    release_at = float(states[best, 0])
    probe = ThrowRun(m, ball, tuned, open_at=release_at - resting_delay)
    probe.run(probe.start + tuned.duration)
    delay = resting_delay
    if probe.flight is not None and probe.flight.release is not None:
        delay = probe.flight.release[0] - probe.start - (release_at - resting_delay)
    return TunedThrow(planned_speed, tuned, limits, release_at, resting_delay, delay,
                      landings[best])


def throw_at(m: mujoco.MjModel, ball: Ball, target, volts: float = servo.DEFAULT_SUPPLY_V,
             variant: str = servo.DEFAULT_VARIANT, delay: float | None = None,
             record=None, cup=None) -> dict:
    """Throw ``ball`` at a cup standing at ``target`` (x, y) [m]; the trial's figures.

    Args:
        m: the throwing model.
        ball: its ball.
        target: the cup's (x, y) [m].
        volts: the servos' supply [V] (for the plan's speed check).
        variant: the servos' variant.
        delay: the gripper's opening delay [s] (default: measured, :func:`opening_delay`).
        record: called with the :class:`ThrowRun` after every physics step of the throw.
        cup: where the cup truly stands (x, y) [m], when the throw aims at ``target`` as a
            camera saw it (default: at ``target``); "in the cup" is this cup's.

    Raises:
        PlanError: the cup out of range, a speed the servos cannot reach.
    """
    return fly(m, ball, tune_throw(m, ball, target, volts, variant, delay), record, cup)


def fly(m: mujoco.MjModel, ball: Ball, throw: TunedThrow, record=None, cup=None) -> dict:
    """Run a tuned throw in the simulator (steps 3-4 of the module); the trial's figures.

    ``cup``: where the cup truly stands (x, y) [m] (default: the plan's target), as
    :func:`throw_at`'s.
    """
    tuned = throw.plan
    run = ThrowRun(m, ball, tuned, open_at=throw.open_at, cup=cup)
    run.run(run.start + tuned.duration + 0.2, record)
    flight_ = run.flight
    end = run.start + tuned.duration + 3.0
    while (flight_.touch is None or run.d.time < flight_.touch[0] + AFTER_TOUCH_S) \
            and run.d.time < end:
        run.run(run.d.time + CONTROL_DT, record)
    report = _trial(run, tuned, throw.planned_speed, throw.release_at, throw.delay,
                    throw.limits, throw.aimed)
    report["opening_delay_at_rest_s"] = round(throw.resting_delay, 4)
    return report


def _trial(run: ThrowRun, plan: ThrowPlan, planned_speed: float, release_at: float,
           delay: float, limits: Mapping[str, float], aimed) -> dict:
    """The trial's figures (JSON-ready)."""
    flight_, ball = run.flight, run.ball
    report = {"cup": [round(v, 4) for v in run.cup],
              "cup_distance_m": round(float(np.hypot(*run.cup)), 4),
              "pan_deg": round(plan.pan_deg, 2),
              "planned_release_speed_m_s": round(planned_speed, 3),
              "swing_rate_rad_s": round(plan.rate, 3),
              "servo_top_rad_s": {j: round(v, 3) for j, v in limits.items()},
              "opening_delay_s": round(delay, 4),
              "release_timed_s": round(release_at, 4),
              "aimed_landing": [round(float(v), 4) for v in aimed[:2]]}
    if flight_.release is None or flight_.touch is None:
        return {**report, "in_cup": False, "model_error_m": None,
                "failure": "the ball was never released" if flight_.release is None else
                "the ball never came down"}
    t_release, p0, v0 = flight_.release
    t_touch, touch, touched = flight_.touch
    model = flight(p0, v0, ball, float(touch[2]))[0]
    resting = flight_.ball_state()[0]
    return {**report,
            "in_cup": in_cup(resting, run.cup, ball),
            "model_error_m": round(float(np.hypot(*(model[:2] - touch[:2]))), 5),
            "release_s": round(t_release - run.start, 4),
            "release_point": [round(float(v), 4) for v in p0],
            "release_velocity": [round(float(v), 4) for v in v0],
            "release_speed_m_s": round(float(np.linalg.norm(v0)), 3),
            "release_elevation_deg": round(math.degrees(math.atan2(v0[2], np.hypot(*v0[:2]))),
                                           2),
            "first_touch": [round(float(v), 4) for v in touch], "touched": touched,
            "model_landing": [round(float(v), 4) for v in model[:3]],
            "flight_s": round(t_touch - t_release, 4),
            "resting": [round(float(v), 4) for v in resting],
            "miss_m": round(float(np.hypot(*(touch[:2] - np.asarray(run.cup)))), 4)}
