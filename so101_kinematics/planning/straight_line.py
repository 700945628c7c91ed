"""Straight lines in task space: the joint path that moves the object frame along a segment.

Assignment 9's optional part, planned here once for the simulator and the arm (no MuJoCo).
The object frame goes from ``p0`` (the start's FK) to ``pf`` with the cubic time scaling
``s(t)`` (``p = (1 - s) p0 + s pf``, zero speed at both ends), one joint configuration per
control period ``dt``. The orientation goes along with ``s`` as the course's
``R0 exp(s log(R0^T Rf))`` does, in the terms a five-joint arm can follow: the approach axis
(the tool's -z) turns from the start's to the end's along the great circle between them
(held, top-down, when both ends are top-down, as at every grasp), and wrist_roll goes from
the start's to the end's. Two ways (``ik.refine.line_task``: 7 rows, analytic Jacobian):

- ``"ik"``: the IK at every cycle: damped least squares iterated to convergence
  (``SOLVE_TOL``) from the last answer, so the arm stays on one branch;
- ``"resolved_rate"``: resolved-rate control, one step per cycle:
  ``dq = J^T (J J^T + lambda^2 I)^-1 (v + K e) dt``, the line's velocity ``v`` over the
  cycle (its displacement, turn and roll over ``dt``) fed forward, the task error ``e`` at
  the cycle's start fed back, the damping keeping it finite near a singularity.
  It integrates on the *planned* joint state (open loop on the commanded path, the Jacobian
  of the commanded configuration), not on the measured one: the real arm's positions are
  quantised and noisy, and its sag would be fed back as a path error.

Joint limits are enforced by clipping in both. :func:`straighten_plan` turns a
pick-and-place plan's vertical moves (``SEGMENTS``) into such paths: one short step per
control period, which every backend's runner already executes (``motion.run_plan``) with
its checks (limits, clearance, speed cap, the arm's fault policy) on every sample.
:func:`max_path_deviation_mm` measures a path's largest distance from its segment.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from so101_kinematics.errors import PlanError, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINT_RANGES_RAD
from so101_kinematics.ik.geometry import SOLVE_TOL
from so101_kinematics.ik.refine import line_task
from so101_kinematics.inputs import Configuration
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.profiles import PROFILES

__all__ = [
    "CONTROL_DT", "METHODS", "SEGMENTS", "add_approach_arguments", "cycle_deviations",
    "describe", "is_path_sample", "max_path_deviation_mm", "path_deviations",
    "plan_for_approach", "straight_path", "straighten_plan",
]

METHODS = ("ik", "resolved_rate")
APPROACHES = ("joint", "straight")
"""``--approach``: today's joint-space moves, or the vertical moves straight in task space."""
CONTROL_DT = 0.01  # [s]: one sample per cycle of the arm's 100 Hz loop (hw.timing.DEFAULT_RATE_HZ)
RATE_GAIN = 20.0  # [1/s]: K, the task error's feedback (a 50 ms time constant: 5 cycles)
DAMPING = 1e-3  # lambda of the resolved rate's damped least squares
IK_DAMPING = 1e-5  # lambda of the IK's iterations (ik/refine.py's)
IK_ITERATIONS = 50  # the IK's iteration cap per cycle (from the last answer: 2-3 suffice)
SEGMENTS = (("approach", "pre_grasp"), ("start_closed", "lift"), ("carry", "final_closed"),
            ("retreat", "depart"))
"""The pick-and-place's vertical moves (``plans.pick_and_place_plan``): (from, to) step names,
the descent to the pick, the lift, the descent to the place and the rise after the release."""
SAMPLE_MARK = "~"
"""A path's samples are named ``<step>~<k>``; its last keeps the step's own name."""


def approach_axis(cfg: Mapping[str, float]) -> np.ndarray:
    """The approach axis (the tool's -z: wrist to fingertips) at ``cfg``, a unit (3,) vector."""
    return -forward_kinematics(cfg)[1][:, 2]


def _turn(a0: np.ndarray, af: np.ndarray, f: float) -> np.ndarray:
    """The unit vector ``f`` of the way from ``a0`` to ``af`` along their great circle."""
    angle = math.acos(min(1.0, max(-1.0, float(a0 @ af))))
    if angle < 1e-9:
        return a0
    return (math.sin((1.0 - f) * angle) * a0 + math.sin(f * angle) * af) / math.sin(angle)


def straight_path(start: Mapping[str, float], goal: Mapping[str, float], duration: float,
                  method: str = "ik", dt: float = CONTROL_DT) -> list[Configuration]:
    """Configurations [deg] that move the object frame straight from ``start``'s to ``goal``'s.

    Args:
        start: where the arm is [deg], gripper [0, 100]; its FK is ``p0``.
        goal: the end's configuration; its FK is ``pf``, its approach axis and wrist_roll
            the end's orientation, its gripper the end's opening (reached along ``s``).
        duration: the move's time [s]; ``n = max(1, round(duration / dt))`` samples.
        method: "ik" or "resolved_rate" (see the module's docstring).
        dt: the control period [s] (one sample each).

    Returns:
        The samples at ``t = dt, 2 dt, ..., n dt`` (the start itself left out).

    Raises:
        PlanError: an unknown method; UnreachableError: the IK did not converge at a
            point of the line (a joint limit in the way).

    Example (the course's lift, 2 s: 200 samples, every one on the segment)::

        >>> from so101_kinematics.planning.plans import LIFT, STARTING_CONFIGURATION as grasp
        >>> lift = dict(grasp, **LIFT)
        >>> up = straight_path(grasp, lift, 2.0)
        >>> p0, pf = forward_kinematics(grasp)[0], forward_kinematics(lift)[0]
        >>> len(up), round(max_path_deviation_mm([forward_kinematics(c)[0] for c in up], p0, pf), 4)
        (200, 0.0)
    """
    if method not in METHODS:
        raise PlanError(f"straight-line method {method!r} is not one of {', '.join(METHODS)}. "
                        "Fix: use ik or resolved_rate.")
    p0, pf = forward_kinematics(start)[0], forward_kinematics(goal)[0]
    a0, af = approach_axis(start), approach_axis(goal)
    r0, rf = (math.radians(cfg["wrist_roll"]) for cfg in (start, goal))
    g0 = float(start.get("gripper", 0.0))
    gf = float(goal.get("gripper", g0))
    cubic = PROFILES["cubic"]
    cycles = max(1, round(duration / dt))
    theta = np.radians([start[j] for j in ARM_JOINTS])
    lower, upper = (np.array([JOINT_RANGES_RAD[j][k] for j in ARM_JOINTS]) for k in (0, 1))
    samples, here = [], (p0, a0, r0)  # where the line is at the cycle's start
    for k in range(1, cycles + 1):
        s = k / cycles
        f = cubic(s)
        p, a, roll = p0 + f * (pf - p0), _turn(a0, af, f), r0 + f * (rf - r0)
        if method == "ik":
            for _ in range(IK_ITERATIONS):
                error, jac = line_task(theta, p, a, roll)
                if float(np.max(np.abs(error))) < SOLVE_TOL:
                    break
                theta = np.clip(theta + _solve(jac, error, IK_DAMPING), lower, upper)
            else:
                raise UnreachableError(
                    f"The line from {_mm(p0)} to {_mm(pf)} mm leaves the arm's reach at "
                    f"{_mm(p)} mm (residual {np.max(np.abs(error)):.2g}). Fix: move the "
                    "waypoints, or use --approach joint.", "no_convergence",
                    float(np.max(np.abs(error))))
        else:  # the error now, fed back; the line's motion over the cycle, fed forward
            error, jac = line_task(theta, *here)
            wanted = RATE_GAIN * error + np.concatenate(
                [p - here[0], np.cross(here[1], a), [roll - here[2]]]) / dt
            theta = np.clip(theta + _solve(jac, wanted, DAMPING) * dt, lower, upper)
        here = (p, a, roll)
        cfg = dict(zip(ARM_JOINTS, map(math.degrees, theta), strict=True))
        cfg["gripper"] = g0 + f * (gf - g0)
        samples.append(cfg)
    return samples


def _solve(jac: np.ndarray, wanted: np.ndarray, damping: float) -> np.ndarray:
    """Damped least squares: ``J^T (J J^T + lambda^2 I)^-1 wanted``."""
    return jac.T @ np.linalg.solve(jac @ jac.T + damping**2 * np.eye(len(wanted)), wanted)


def _mm(p) -> str:
    return "(" + ", ".join(f"{1e3 * v:.0f}" for v in p) + ")"


def max_path_deviation_mm(positions, p0, pf) -> float:
    """The largest distance [mm] of ``positions`` (n, 3) [m] from the segment ``p0``-``pf``.

    Example:
        >>> max_path_deviation_mm([[0.0, 0.0, 0.001], [0.5, 0.002, 0.0], [1.25, 0.0, 0.0]],
        ...                       (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))  # beyond the end: 0.25 m
        250.0
    """
    p0, pf = np.asarray(p0, dtype=float), np.asarray(pf, dtype=float)
    x = np.asarray(positions, dtype=float).reshape(-1, 3)
    if len(x) == 0:
        return 0.0
    length = float(np.linalg.norm(pf - p0))
    u = (pf - p0) / length if length > 0.0 else np.zeros(3)
    along = np.clip((x - p0) @ u, 0.0, length)
    return float(np.linalg.norm(x - p0 - along[:, None] * u, axis=1).max() * 1e3)


def is_path_sample(name: str) -> bool:
    """Whether step ``name`` is one of a straight path's samples (not its last)."""
    return SAMPLE_MARK in name


def segment_name(name: str) -> str:
    """The step a sample belongs to: ``lift~012`` -> ``lift``."""
    return name.split(SAMPLE_MARK, 1)[0]


def _pairs(plan: Plan) -> list[int]:
    """Indices of the steps that end a vertical move (``SEGMENTS``, a stack's prefix kept)."""
    ends = []
    for i in range(1, len(plan.steps)):
        here, before = plan.steps[i].name, plan.steps[i - 1].name
        for first, last in SEGMENTS:
            if here.endswith(last) and before == here[:len(here) - len(last)] + first:
                ends.append(i)
    return ends


def straighten_plan(plan: Plan, method: str = "ik", dt: float = CONTROL_DT) -> Plan:
    """The plan with its vertical moves (``SEGMENTS``) straight in task space.

    Each such move becomes ``round(duration / dt)`` steps of ``dt`` [s] (no hold), the
    last keeping the step's name and hold (:func:`straight_path` from the step before).

    Args:
        plan: a pick-and-place or stacking plan (its step names as ``pick_and_place_plan``'s).
        method: "ik" or "resolved_rate".
        dt: the control period [s] of the backend that runs it.

    Returns:
        A new plan; the others moves and the plan's settings unchanged.

    Raises:
        PlanError: no vertical move in the plan, or one the arm cannot make straight
            (the message names the step).
    """
    ends = _pairs(plan)
    if not ends:
        raise PlanError("--approach straight: the plan has no vertical move ("
                        + ", ".join(f"{a} -> {b}" for a, b in SEGMENTS) + "). Fix: use "
                        "--approach joint for this plan.")
    out: list[Step] = []
    for i, step in enumerate(plan.steps):
        if i not in ends:
            out.append(Step(step.name, dict(step.configuration), step.duration, step.hold))
            continue
        try:
            path = straight_path(out[-1].configuration, step.configuration, step.duration,
                                 method, dt)
        except UnreachableError as error:
            raise UnreachableError(f"--approach straight, waypoint '{step.name}': {error}",
                                   error.reason, error.distance, error.joint) from None
        out += [Step(f"{step.name}{SAMPLE_MARK}{k:03d}", cfg, dt, 0.0)
                for k, cfg in enumerate(path[:-1], 1)]
        out.append(Step(step.name, path[-1], dt, step.hold))
    return Plan(out, plan.return_to_start, plan.return_duration)


def segments(plan: Plan) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A straightened plan's lines: end step name -> (p0, pf) [m], the commanded ends' FK."""
    lines, first = {}, None
    for i, step in enumerate(plan.steps):
        if is_path_sample(step.name):
            if first is None:
                first = forward_kinematics(plan.steps[i - 1].configuration)[0]
        elif first is not None:
            lines[step.name] = (first, forward_kinematics(step.configuration)[0])
            first = None
    return lines


def path_deviations(plan: Plan, samples: Iterable[tuple[str, Sequence[float]]]
                    ) -> dict[str, float]:
    """Each line's measured largest distance [mm] from its segment.

    Args:
        plan: the straightened plan (:func:`straighten_plan`).
        samples: (step name, measured object frame position [m]) while the step ran, e.g.
            MuJoCo's object frame at each step's end, or the FK of each cycle's present
            positions on the arm.

    Returns:
        End step name -> max distance [mm] (the lines that were reached).
    """
    lines = segments(plan)
    measured: dict[str, list] = {}
    for name, position in samples:
        base = segment_name(name)
        if base in lines:
            measured.setdefault(base, []).append(position)
    return {name: max_path_deviation_mm(points, *lines[name]) for name, points in
            measured.items()}


def describe(deviations: Mapping[str, float], method: str) -> str:
    """One line for the end of a run: each line's and the largest distance from its segment."""
    if not deviations:
        return f"Straight lines ({method}): none was run."
    each = ", ".join(f"{name} {mm:.2f}" for name, mm in deviations.items())
    return (f"Straight lines ({method}): largest distance from the segment "
            f"{max(deviations.values()):.2f} mm ({each} mm).")


def cycle_deviations(plan: Plan, cycles) -> dict[str, float]:
    """:func:`path_deviations` on the arm: the FK of each cycle's present positions.

    Args:
        plan: the straightened plan that ran.
        cycles: the run's ``hw.timing.Cycle`` records (step name, command, measured pose).
    """
    return path_deviations(plan, ((c.step, forward_kinematics(c.measured)[0]) for c in cycles
                                  if c.measured is not None))


def add_approach_arguments(parser) -> None:
    """Add ``--approach joint|straight`` and ``--straight-method ik|resolved_rate``."""
    parser.add_argument("--approach", choices=APPROACHES, default="joint",
                        help="the vertical moves (descent to the pick and the place, the lift, "
                        "the rise after the release): joint-space moves (default), or straight "
                        "lines in task space, top-down, one command per control cycle")
    parser.add_argument("--straight-method", choices=METHODS, default="ik",
                        help="--approach straight: IK at every cycle (default) or resolved-rate "
                        "control with the analytic Jacobian")


def plan_for_approach(args, plan: Plan | None, dt: float = CONTROL_DT, stack=None) -> Plan:
    """``plan`` as ``--approach`` asks (:func:`straighten_plan` for "straight").

    Args:
        args: the parsed ``approach`` and ``straight_method``.
        plan: the pick-and-place plan (None with a stack).
        dt: the backend's control period [s].
        stack: the ``--stack`` plan, if any: its moves stay joint-space moves.

    Raises:
        PlanError: straight lines asked for a stack, or a plan without vertical moves.
    """
    if getattr(args, "approach", "joint") != "straight":
        return plan
    if stack is not None:
        raise PlanError("--approach straight: the lines run in the pick-and-place (its report "
                        "measures them); --stack runs joint-space moves. Fix: leave out "
                        "--approach with --stack.")
    return straighten_plan(plan, args.straight_method, dt)
