"""How well the real-arm path tracks its plan: the velocity lead, without it, the registers.

Measured on the virtual SO-101 through lerobot's bus.

Week 9 asks for a velocity on the arm, where lerobot sends only ``Goal_Position``.
Three ways, each the whole hardware path (``hw.run.run_on_arm``: the fault policy,
the gravity feed-forward, the speed cap) on a fresh virtual arm whose servos are the
STS3215 model (``sim/sts3215.py``, lerobot's P = 16, the kit's 5 V):

- ``plain``: the planned position is the goal (the course's ``move_to_pose_cubic``);
- ``lead``: the goal leads the plan by the servo's lag times the planned velocity
  (``hw/lead.py``, ``--velocity-ff``);
- ``registers``: as students do by hand, each move writes ``Goal_Velocity`` (the
  cubic's peak speed) and ``Acceleration`` (its peak acceleration) and sends the
  move's goal at once; the servo's firmware ramps its own target there.

:func:`tracking_figures` judges every run against the same plan: the measured arm
joints against the planned position of the same cycle, over the moves.
``python -m so101_kinematics.lab.tracking_hw`` prints the table of docs/trajectories.md
("Velocity on the real arm").
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from so101_kinematics import servo
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.planning.motion import Plan, Trajectory
from so101_kinematics.planning.plans import default_plan
from so101_kinematics.planning.profiles import PROFILES

__all__ = ["measure", "move_cycles", "move_segments"]

MODES = ("plain", "lead", "registers")
"""The ways of getting the velocity to the arm, compared (the module's docstring)."""

COUNTS_PER_DEG = servo.COUNTS_PER_TURN / 360.0
"""Encoder counts per degree [MEM] (``servo.COUNTS_PER_RAD`` in degrees)."""

ACCELERATION_MAX = 254
"""The largest Acceleration lerobot writes (its value, [LR] in ``servo.py``) [100 counts/s^2]."""


class RegisterProfile:
    """The students' way: per move, Goal_Velocity and Acceleration, then the goal at once.

    Stands where the session's velocity lead goes (``ArmSession.velocity_lead``): for each
    move it writes the registers of every joint that moves and makes the goal written each
    cycle the move's goal, while the session's checks keep judging the plan.

    Args:
        bus: the session's lerobot bus.
    """

    enabled = True

    def __init__(self, bus):
        self.bus = bus
        self.written: list[dict[str, tuple[int, int]]] = []  # per move: joint -> (vel, acc)

    def registers(self, path: Trajectory) -> dict[str, tuple[int, int]]:
        """Joint -> (Goal_Velocity [counts/s], Acceleration [100 counts/s^2]) for ``path``.

        The profile's peak speed ``peak f' |delta| / T`` and peak acceleration
        ``peak f'' |delta| / T^2`` (6 for the cubic), rounded up; a joint that stays
        gets lerobot's values (0: the fastest, 254).
        """
        profile = PROFILES[path.profile]
        peak_accel = float(np.max(np.abs(profile.acceleration(np.linspace(0.0, 1.0, 101)))))
        out = {}
        for joint in path.goal:
            delta = abs(path.goal[joint] - path.start[joint]) * COUNTS_PER_DEG
            if delta < 1.0 or path.duration <= 0.0:
                out[joint] = (0, ACCELERATION_MAX)
                continue
            speed = math.ceil(profile.peak_speed * delta / path.duration)
            accel = math.ceil(peak_accel * delta / path.duration**2 / servo.ACCELERATION_UNIT)
            out[joint] = (max(1, min(speed, int(servo.TARGET_RATE_MAX))),
                          max(1, min(accel, ACCELERATION_MAX)))
        return out

    def along(self, path: Trajectory, velocity_ff=None):
        """Write this move's registers; the goal written every cycle is the move's goal."""
        values = self.registers(path)
        self.bus.sync_write("Goal_Velocity", {j: v for j, (v, _) in values.items()},
                            normalize=False)
        self.bus.sync_write("Acceleration", {j: a for j, (_, a) in values.items()},
                            normalize=False)
        self.written.append(values)
        goal = dict(path.goal)
        return lambda t, planned: goal

    def record(self) -> dict:
        """For a log's sidecar: what was written."""
        return {"enabled": True, "mode": "registers", "moves": len(self.written)}


def move_segments(result) -> list:
    """The run's moves (``timing.Segment``), in order."""
    return [s for s in result.segments if s.kind == "move"]


def move_cycles(result, segment) -> list:
    """The cycles of one move: from its start to the next segment's (its hold, the next move).

    (By the segments' starts, not their durations: the plan's clock may have paused.)
    """
    later = [s.t_start_s for s in result.segments if s.t_start_s > segment.t_start_s]
    end = min(later, default=float("inf"))
    return [c for c in result.cycles
            if segment.t_start_s < c.t_s <= end + 1e-9 and c.step == segment.step]


def tracking_figures(result, plan: Plan) -> dict:
    """The tracking of a run against its plan: RMS and max over the moves, the final errors.

    Args:
        result: ``hw.run.RunResult`` of the run.
        plan: its plan (the held steps are the goals whose final error is reported).

    Returns:
        ``tracking_rms_deg``, ``tracking_max_deg``: |measured - planned| of the arm joints
        over every cycle of every move but the first (the ramp from wherever the arm stood,
        before :func:`measure`'s ``registers`` mode is in place) [deg];
        ``final_error_deg``: held step -> the largest |measured - goal| of an arm joint
        at the end of its hold [deg];
        ``final_error_max_deg``: the largest of those; ``peak_lead_deg``: the largest
        |goal written - plan| the cycles show (the lead; in ``registers`` mode the rest of
        the move) [deg].
    """
    errors, leads = [], [0.0]
    for segment in move_segments(result)[1:]:  # not the ramp from the start
        for cycle in move_cycles(result, segment):
            if cycle.measured:
                errors.extend(cycle.measured[j] - cycle.command[j] for j in ARM_JOINTS)
            if cycle.lead:
                leads.extend(abs(cycle.lead[j]) for j in ARM_JOINTS)
    final = {}
    for step in plan.steps:
        if step.hold <= 0:
            continue
        cycles = [c for c in result.cycles if c.step == step.name and c.measured]
        if cycles:
            final[step.name] = max(abs(cycles[-1].measured[j] - step.configuration[j])
                                   for j in ARM_JOINTS)
    errors = np.abs(np.array(errors or [0.0]))
    return {"tracking_rms_deg": float(np.sqrt(np.mean(errors**2))),
            "tracking_max_deg": float(errors.max()), "final_error_deg": final,
            "final_error_max_deg": max(final.values(), default=0.0),
            "peak_lead_deg": max(leads), "cycles": len(result.cycles),
            "aborted": result.aborted}


def measure(mode: str, plan: Plan | None = None, profile: str = "cubic",
            supply: float | None = None, **run_options) -> dict:
    """One run of ``plan`` (default: the course's pick-and-place) on a fresh virtual arm.

    Args:
        mode: one of :data:`MODES`.
        plan: the plan.
        profile: its time scaling.
        supply: the virtual arm's supply [V] (None: its default, the course's 12 V follower).
        run_options: more of ``run_on_arm``'s options (``on_cycle``, ...).

    Returns:
        :func:`tracking_figures`, plus ``mode``, ``profile`` and ``result`` (the RunResult).
    """
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw import run as hw_run
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    if mode not in MODES:
        raise ValueError(f"mode {mode!r} is not one of {', '.join(MODES)}. Fix: choose one.")
    plan = plan or default_plan()
    calibration = load_calibration(DEFAULT_CALIBRATION_PATH)
    on_cycle = run_options.pop("on_cycle", None)
    installed = []

    def hook(session, cycle):
        if mode == "registers" and not installed:
            installed.append(RegisterProfile(session.bus))
            session.velocity_lead = installed[0]
        if on_cycle is not None:
            on_cycle(session, cycle)

    volts = {} if supply is None else {"supply": supply}
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, **volts) as arm:
        try:
            result = hw_run.run_on_arm(arm.port, calibration, plan, profile=profile,
                                       velocity_ff=mode == "lead", on_cycle=hook, **run_options)
        except hw_run.MotionAborted as error:
            result = error.result
        slip = arm.reply_stats()
    figures = tracking_figures(result, plan)
    figures.update(mode=mode, profile=profile, result=result,
                   emulator_slip_s=slip["wall_time_s"] - slip["sim_time_s"])
    return figures


def main(argv: list[str] | None = None) -> int:
    """Print docs/trajectories.md's table (and write ``--json PATH``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="cubic", choices=sorted(PROFILES))
    parser.add_argument("--json", help="write the figures there too")
    args = parser.parse_args(argv)
    rows = {}
    for mode in MODES:
        figures = measure(mode, profile=args.profile)
        figures.pop("result")
        rows[mode] = figures
        finals = ", ".join(f"{k} {v:.2f}" for k, v in figures["final_error_deg"].items())
        print(f"{mode:10s} RMS {figures['tracking_rms_deg']:.2f} deg, max "
              f"{figures['tracking_max_deg']:.2f} deg, largest |goal - plan| "
              f"{figures['peak_lead_deg']:.2f} deg, final at each goal: {finals} (aborted: "
              f"{figures['aborted']}; emulator slip {figures['emulator_slip_s']:.2f} s)")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
