"""Velocity feed-forward on the real arm: each goal leads the plan by the servo's lag.

The course's week 9 asks how to feed a velocity forward when lerobot sends only
``Goal_Position``. A position servo tracks a moving goal with a lag: at a steady
speed ``v`` its P loop needs the error that balances the motor's back-EMF and
viscous damping, ``servo.lag``: ``tau v`` with ``tau`` = (kt^2/R + viscous) /
stiffness, 0.10 s at lerobot's P = 16 on the kit's 5 V supply. Sending the planned
position plus ``tau v`` puts the servo's goal where it has to be for the joint to
be on the plan. The planned velocity is zero at both ends of every move (every
speed-capped profile but ``linear`` starts and stops at rest), so the lead vanishes
there and the arm still ends at the goal.

Bounds (``LEAD_CAP_DEG`` and the move's own segment):

- the lead is scaled down, the same factor for every joint, so no joint leads by
  more than ``LEAD_CAP_DEG``;
- each joint's led goal is clamped between the move's start and goal: a goal
  never overshoots its move. With the same lag on every joint (lerobot writes the
  same P to every servo) the lead is then a fraction of ``goal - start`` for all of
  them, so the led goal stays on the straight joint-space segment the clearance
  check (``clearance.check_path``) judged; with unequal lags it stays in the box
  of that segment.

The checks (tracking, stall, faults) keep judging the *planned* position: the
session's ``command`` is the plan, the lead is only added on the wire.

Example (the shoulder at 50 deg/s on 5 V at P = 16: a 5.1 deg lead)::

    >>> lead = VelocityLead.for_settings(dict.fromkeys(["shoulder_lift"], servo.LEROBOT), 5.0)
    >>> round(lead.lag_s["shoulder_lift"], 3)  # [s]
    0.103
    >>> round(lead_for({"shoulder_lift": 50.0}, lead.lag_s)["shoulder_lift"], 2)  # [deg]
    5.15
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping

from so101_kinematics import servo
from so101_kinematics.frames import JOINTS
from so101_kinematics.gravity import Feedforward
from so101_kinematics.planning.motion import Trajectory

__all__ = ["VelocityLead", "add_velocity_ff_argument", "lag_time", "lead_for"]

LEAD_CAP_DEG = 10.0
"""The largest lead of any joint [deg] (gripper [%]). The lag the servo model gives at the
default speed cap (``hw/timing.py``: 100 deg/s at the profile's peak) at lerobot's P = 16
on 5 V is 0.103 s x 100 deg/s = 10.3 deg: the cap leaves that whole, and keeps a joint
whose real lag is smaller than the model's (a stronger supply misread, a lighter load)
from running ahead of its plan by more than 10 deg, inside the 15 deg tracking tolerance,
so the lead alone never trips the stall check."""


def add_velocity_ff_argument(parser: argparse.ArgumentParser) -> None:
    """``--velocity-ff`` / ``--no-velocity-ff`` (default off) of ``pick_place_hw.py``."""
    lag = lag_time(servo.LEROBOT, servo.DEFAULT_SUPPLY_V, servo.DEFAULT_VARIANT)
    parser.add_argument("--velocity-ff", action=argparse.BooleanOptionalAction, default=False,
                        help="lead each goal by the servos' lag (read from them: "
                             f"{lag:.2f} s at P = 16 on the course's 12 V C018s) times the "
                             f"planned velocity, at most {LEAD_CAP_DEG:g} deg: the arm lags "
                             "the plan less (default off: the plain plan, the course's baseline)")


def lag_time(settings: servo.Settings, volts: float, variant: str = "C001") -> float:
    """The servo's lag per unit of speed [s]: ``servo.lag`` at 1 rad/s."""
    return servo.lag(1.0, settings, volts, variant)


def lead_for(velocity: Mapping[str, float], lag_s: Mapping[str, float],
             cap: float = LEAD_CAP_DEG) -> dict[str, float]:
    """Each joint's lead [deg]: its lag [s] times its planned velocity [deg/s], bounded.

    Args:
        velocity: joint -> planned velocity [deg/s] (gripper [%/s]).
        lag_s: joint -> the servo's lag [s] (a joint missing here gets no lead).
        cap: the largest lead [deg]; the whole lead is scaled down, one factor for every
            joint, so that none exceeds it (the led goal keeps the plan's direction).

    Example:
        >>> lead_for({"elbow_flex": 80.0, "wrist_flex": -40.0}, {"elbow_flex": 0.1,
        ...          "wrist_flex": 0.1}, cap=4.0)  # 8 and -4 deg, halved
        {'elbow_flex': 4.0, 'wrist_flex': -2.0}
    """
    lead = {j: lag_s.get(j, 0.0) * v for j, v in velocity.items()}
    largest = max((abs(x) for x in lead.values()), default=0.0)
    scale = cap / largest if largest > cap else 1.0
    return {j: x * scale for j, x in lead.items()}


def led_goal(planned: Mapping[str, float], lead: Mapping[str, float],
             start: Mapping[str, float], goal: Mapping[str, float]) -> dict[str, float]:
    """``planned + lead``, each joint clamped between its move's ``start`` and ``goal``."""
    out = {}
    for joint, value in planned.items():
        low, high = sorted((start.get(joint, value), goal.get(joint, value)))
        out[joint] = min(high, max(low, value + lead.get(joint, 0.0)))
    return out


class VelocityLead:
    """The lead of one arm: each joint's lag, the cap, and what was led (for the log).

    Args:
        lag_s: joint -> the servo's lag [s] (:func:`lag_time`).
        enabled: lead the goals (``False``: the session sends the plan as it is).
        cap: :data:`LEAD_CAP_DEG`.
        source: where the lags come from, for the log.
    """

    def __init__(self, lag_s: Mapping[str, float], enabled: bool = True,
                 cap: float = LEAD_CAP_DEG, source: str = "servo model"):
        self.lag_s = {j: float(t) for j, t in lag_s.items()}
        self.enabled = bool(enabled)
        self.cap = float(cap)
        self.source = source
        self.peak = dict.fromkeys(self.lag_s, 0.0)
        """Joint -> the largest |lead| sent so far [deg]."""

    @classmethod
    def for_settings(cls, settings: Mapping[str, servo.Settings], volts: float,
                     variant: str | None = None, enabled: bool = True) -> VelocityLead:
        """The lead from the servos' registers and supply (as read from the bus)."""
        variant = variant or servo.default_variant(volts)
        lags = {j: lag_time(s, volts, variant) for j, s in settings.items()}
        return cls(lags, enabled, source=f"servo.lag ({variant}, {volts:.1f} V, P = "
                   + "/".join(str(p) for p in sorted({s.p for s in settings.values()})) + ")")

    def goal(self, planned: Mapping[str, float], velocity: Mapping[str, float],
             start: Mapping[str, float], goal: Mapping[str, float]) -> dict[str, float]:
        """The goal to send at a point of a move: planned + bounded lead, within the move."""
        led = led_goal(planned, lead_for(velocity, self.lag_s, self.cap), start, goal)
        for joint, value in led.items():
            if joint in self.peak:
                self.peak[joint] = max(self.peak[joint], abs(value - planned[joint]))
        return led

    @classmethod
    def for_feedforward(cls, feedforward: Feedforward | None,
                        enabled: bool = True) -> VelocityLead:
        """The lead from what the gravity feed-forward read from the bus (``hw/feedforward.py``).

        Without it (nothing read): lerobot's registers on the course's follower's supply
        (``servo.DEFAULT_SUPPLY_V``, 12 V: C018s).
        """
        if feedforward is None:
            return cls.for_settings(dict.fromkeys(JOINTS, servo.LEROBOT), servo.DEFAULT_SUPPLY_V,
                                    enabled=enabled)
        return cls.for_settings(feedforward.settings, feedforward.volts, feedforward.variant,
                                enabled)

    def along(self, path: Trajectory, velocity_ff: bool | None = None
              ) -> Callable[[float, Mapping[str, float]], dict[str, float]] | None:
        """The goal to send at time ``t`` [s] of ``path`` with the plan there, or None.

        Args:
            path: the move.
            velocity_ff: lead this move (None: when :attr:`enabled`).
        """
        if not (self.enabled if velocity_ff is None else velocity_ff):
            return None
        start, goal = path.start, path.goal
        return lambda t, planned: self.goal(planned, path.velocity_at(t), start, goal)

    def record(self) -> dict:
        """What the log's sidecar keeps: on or off, the lags, the cap, the largest leads."""
        return {"enabled": self.enabled, "lag_s": {j: round(t, 4) for j, t in self.lag_s.items()},
                "cap_deg": self.cap, "source": self.source,
                "peak_lead_deg": {j: round(x, 3) for j, x in self.peak.items()}}

    def describe(self) -> str:
        """One line for the log: on or off, the lag and the cap."""
        if not self.enabled:
            return "no velocity feed-forward (goals follow the plan; the arm lags it)"
        lags = sorted(set(round(t, 3) for t in self.lag_s.values()))
        shown = "/".join(f"{t:g}" for t in lags) if lags else "?"
        return (f"velocity feed-forward: each goal leads the plan by {shown} s x its velocity "
                f"({self.source}), at most {self.cap:g} deg")

