"""Teach mode, the plan table and the run's outcome: what a student reads before and after a run."""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Mapping

from so101_kinematics.errors import PortLost
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.bus import port_lost, read_pose, recover_port
from so101_kinematics.hw.control import READ_RETRIES, RECOVERY_TIMEOUT_S
from so101_kinematics.hw.grip import HELD_MARGIN_PCT
from so101_kinematics.hw.timing import RateLoop, capped_duration
from so101_kinematics.inputs import Configuration
from so101_kinematics.planning import stack_report
from so101_kinematics.planning.motion import Plan
from so101_kinematics.planning.plans import GRIPPER_CLOSED, pick_and_place_steps
from so101_kinematics.planning.straight_line import is_path_sample

__all__ = [
    "MAX_TEACH_RATE_HZ", "TEACH_RATE_HZ", "cube_outcome", "format_configuration",
    "format_plan", "grasp_outcome", "outcome_lines", "teach",
]

TEACH_RATE_HZ = 5.0        # live pose printing [Hz]
MAX_TEACH_RATE_HZ = 50.0   # a terminal cannot show more [Hz]


def format_configuration(cfg: Mapping[str, float], digits: int = 1) -> str:
    """A configuration as a JSON object (valid Python and waypoint-file syntax)."""
    return json.dumps({j: round(float(cfg[j]), digits) for j in JOINTS if j in cfg})


def object_position_cm(cfg: Mapping[str, float]) -> tuple[float, float, float]:
    """FK object-frame position in the base frame [cm]."""
    position, _ = forward_kinematics({j: cfg[j] for j in ARM_JOINTS})
    return tuple(float(v) * 100.0 for v in position)


def format_plan(plan: Plan, *, rate_hz: float, profile: str, max_speed: Mapping[str, float],
                start: Configuration | None = None) -> str:
    """The plan as a table (durations after the speed cap) and the cube positions to place [cm]."""
    waypoints = sum(not is_path_sample(step.name) for step in plan.steps)
    lines = [f"Plan: {waypoints} waypoints, {rate_hz:g} Hz, profile {profile}, speed cap "
             f"{max_speed['shoulder_pan']:g} deg/s (gripper {max_speed['gripper']:g} %/s)"]
    header = f"  {'#':>2} {'waypoint':<16}{'move':>7}{'hold':>6}" + "".join(
        f"{j[:13]:>14}" for j in JOINTS) + "    object x, y, z [cm]"
    lines.append(header)
    previous, line_s, shown = start, 0.0, 0
    for step in plan.steps:
        if is_path_sample(step.name):  # a straight line's sample: shown as its last step
            line_s += step.duration
            previous = step.configuration
            continue
        shown += 1
        i = shown
        if line_s:
            move, line_s = f"{line_s + step.duration:>6.2f}~", 0.0
        elif previous is None:
            move = f"{step.duration:>6.2f}*"
        else:
            capped = capped_duration(previous, step.configuration, step.duration, profile,
                                     max_speed)
            move = f"{capped:>7.2f}"
        x, y, z = object_position_cm(step.configuration)
        lines.append(f"  {i:>2} {step.name[:15]:<16}{move}{step.hold:>6.2f}" + "".join(
            f"{step.configuration[j]:>14.1f}" for j in JOINTS) + f"    {x:6.1f} {y:6.1f} {z:5.1f}")
        previous = step.configuration
    if plan.return_to_start:
        lines.append(f"  {shown + 1:>2} {'return_to_start':<16}"
                     f"{plan.return_duration:>6.2f}*     back to the measured starting pose")
    else:
        lines.append("  (return_to_start: false: the arm holds the last waypoint, torque on)")
    if any(is_path_sample(step.name) for step in plan.steps):
        lines.append("  ~ a straight line in task space, one command per control cycle.")
    if start is None:
        lines.append("  * ramps from (or to) the arm's measured pose; stretched if the speed cap "
                     "needs it.")
    pick, place = pick_and_place_steps(plan)
    lines.append("Place the cubes here (FK of the object frame, base frame, rounded to the grid):")
    for label, step in (("pick ", pick), ("place", place)):
        x, y, z = object_position_cm(step.configuration)
        lines.append(f"  {label} ({step.name}): x = {x:.1f} cm, y = {y:.1f} cm  (cube centre "
                     f"z = {z:.1f} cm)")
    return "\n".join(lines)


def teach(bus, *, rate_hz: float = TEACH_RATE_HZ, duration: float | None = None,
          out=None) -> Configuration | None:
    """Torque off; print the pose live (configuration dict + FK object position) until Ctrl-C.

    A failed read is skipped (the arm is in the user's hands, nothing is
    commanded); if the arm stays silent for ``RECOVERY_TIMEOUT_S`` the mode ends.

    Args:
        bus: connected bus.
        rate_hz: print rate [Hz], in (0, ``MAX_TEACH_RATE_HZ``].
        duration: stop after this long [s] (None: until Ctrl-C).
        out: text stream (default stdout); a terminal gets one updating line.

    Returns:
        The last pose read.

    Raises:
        PortLost: the port vanished.
    """
    out = out or sys.stdout
    bus.disable_torque()
    live = hasattr(out, "isatty") and out.isatty()
    print("Torque is off: move the arm by hand. Ctrl-C to stop.", file=out)
    loop = RateLoop(rate_hz)
    started = loop.start()
    pose, silent_since = None, None
    try:
        while duration is None or loop.deadline - started < duration - 1e-9:
            try:
                pose = read_pose(bus, READ_RETRIES)
            except Exception:  # noqa: BLE001 - a glitch: skip this line
                if port_lost(bus):
                    raise PortLost.during("teach mode") from None
                recover_port(bus, settle=False)
                silent_since = silent_since or time.monotonic()
                if time.monotonic() - silent_since > RECOVERY_TIMEOUT_S:
                    print(f"\nThe arm has not answered for {RECOVERY_TIMEOUT_S:g} s: check its "
                          "power supply and cables.", file=out)
                    break
                loop.wait()
                continue
            silent_since = None
            x, y, z = object_position_cm(pose)
            line = f"{format_configuration(pose)}  object x={x:.1f} y={y:.1f} z={z:.1f} cm"
            print(("\r" + line) if live else line, end="" if live else "\n", file=out, flush=True)
            loop.wait()
    except KeyboardInterrupt:
        pass
    if live:
        print(file=out)
    if pose is not None:
        print("Last pose (paste into a waypoint file): " + format_configuration(pose), file=out)
    return pose


def grasp_outcome(plan: Plan, cycles) -> str | None:
    """Whether the jaws closed on something, from the log: works on a real arm too.

    The gripper is not tracked (it squeezes the cube by design), so a cube
    between the jaws shows as a gripper that stops short of its command.

    Returns:
        A line for the student, or None if the plan does not close the gripper.
    """
    closing = [s for s in plan.steps if s.configuration["gripper"] <= GRIPPER_CLOSED + 1e-9]
    if not closing:
        return None
    step = closing[0].name
    measured = [c.measured["gripper"] for c in cycles if c.step == step and c.measured]
    if not measured:
        return None
    final = measured[-1]
    if final <= GRIPPER_CLOSED + HELD_MARGIN_PCT:  # hw/grip.py's rule: nothing held
        return (f"The jaws closed on nothing at '{step}' (gripper {final:.1f} %, commanded "
                f"{GRIPPER_CLOSED:g} %): the cube was not picked. Check where it stands against "
                "the FK pick position.")
    return f"The jaws closed on the cube at '{step}' (gripper stopped at {final:.1f} %)."


def cube_outcome(plan: Plan, cube) -> str | None:
    """Where the virtual lab's cube sensor says the cube ended, against the FK place position."""
    if cube is None:
        return None
    _, place = pick_and_place_steps(plan)
    target, _ = forward_kinematics({j: place.configuration[j] for j in ARM_JOINTS})
    x, y, z = cube.position_m
    miss = 1e3 * math.hypot(x - target[0], y - target[1])
    where = "in the jaws" if cube.held else f"tilted {cube.tilt_deg:.1f} deg"
    return (f"Cube (the virtual arm's sensor): at x = {100 * x:.1f} cm, y = {100 * y:.1f} cm, "
            f"z = {100 * z:.1f} cm, {where}; {miss:.1f} mm from the FK place position "
            f"({100 * target[0]:.1f}, {100 * target[1]:.1f}) cm.")


def outcome_lines(plan: Plan, result, stack=None) -> list[str]:
    """What a run tells the student after it, before its last line (outages, grasp, cubes, loop).

    Args:
        plan: the plan that ran.
        result: its ``so101_kinematics.hw.run.RunResult``.
        stack: the ``StackPlan`` when the plan stacks blocks, else None.
    """
    lines = [f"The arm did not answer for {length:.2f} s at t = {start:.2f} s; the plan paused "
             "and resumed." for start, length in result.outages]
    lines += [grasp_outcome(plan, result.cycles),
              stack_report.stack_outcome(stack, result.cubes) if stack
              else cube_outcome(plan, result.cube)]
    if result.aborted is None and result.timing:
        timing = result.timing
        lines.append(f"Loop {timing.get('achieved_hz', 0):.1f} Hz, period p50 "
                     f"{timing.get('period_p50_ms', 0):.2f} ms, p99 error "
                     f"{timing.get('period_p99_error_ms', 0):.2f} ms, "
                     f"{timing.get('overruns', 0)} overruns.")
    return [line for line in lines if line]
