"""Pick-and-place on a real SO-101 follower through lerobot's FeetechMotorsBus, safe by default."""

from __future__ import annotations

import argparse
import csv
import json
import logging
import math
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from so101_bus import (
    FIND_PORT_HINT,
    LerobotMissing,
    bus_errors,
    configure,
    connect,
    disconnect,
    enable_torque_in_place,
    recover_port,
    release_torque,
    silent_servos,
)
from so101_calibration import (
    CALIBRATE_HINT,
    MOTOR_IDS,
    CalibrationError,
    HardwareError,
    calibrated_limits,
    find_calibration,
    load_calibration,
)
from so101_cartesian_plan import add_cartesian_arguments, plan_from_arguments
from so101_control import (
    DEFAULT_RATE_HZ,
    MAX_JOINT_SPEED_DEG_S,
    TRACKING_TIMEOUT_S,
    TRACKING_TOLERANCE_DEG,
    ArmSession,
    BusError,
    Cycle,
    RateLoop,
    Segment,
    StopRequested,
    capped_duration,
    gc_frozen,
    speed_caps,
    stop_on_sigint,
    tracking_tolerances,
)
from so101_forward_kinematics import ARM_JOINTS, JOINTS, get_forward_kinematics
from so101_motion import (
    PROFILES,
    Configuration,
    JointLimitError,
    Limits,
    Plan,
    PlanError,
    Step,
    default_plan,
    load_plan,
    pick_and_place_steps,
    run_plan,
    unit,
    validate_plan,
)

logger = logging.getLogger("pick_place_hw")

# --- Settings ---------------------------------------------------------------
TEACH_RATE_HZ = 5.0                # live pose printing in --teach [Hz]
LIMIT_SLACK_DEG = 2.0              # a start this far outside the calibration is clamped [deg]


# --- Errors -----------------------------------------------------------------
class NotConfirmed(HardwareError):
    """The user did not confirm (or could not be asked)."""


class MotionAborted(HardwareError):
    """The motion was aborted; ``result`` tells whether the arm returned and torque is off."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result


# --- Limits of this arm ------------------------------------------------------
@lru_cache(maxsize=1)
def model_limits() -> dict[str, tuple[float, float]]:
    """The MuJoCo model's joint limits in user units (the simulator's, so sim and hw agree)."""
    import so101_mujoco_utils

    return so101_mujoco_utils.joint_limits(so101_mujoco_utils.load_model())


def validate_plan_for_arm(plan: Plan, calibration: Mapping[str, Any] | None,
                          source: str = "the calibration") -> Plan:
    """Check every waypoint against the model's limits and the arm's calibrated limits.

    Args:
        plan: the plan.
        calibration: joint -> calibration, or None to check the model's limits only.
        source: where the calibration came from (for messages).

    Returns:
        The plan, configurations normalised to floats.

    Raises:
        PlanError: bad structure; JointLimitError naming joint, value, limit,
            which limits (model or calibration) and the fix.
    """
    try:
        validate_plan(plan, model_limits())
    except JointLimitError as error:
        raise JointLimitError(f"{error} (joint limits of the SO-101 model, as in the simulator)") \
            from None
    if calibration is not None:
        try:
            validate_plan(plan, calibrated_limits(calibration))
        except JointLimitError as error:
            raise JointLimitError(f"{error} (calibrated range of this arm, from {source}; if the "
                                  "range looks too small, recalibrate)") from None
    for label, value in (("return_duration", plan.return_duration),):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value < 0:
            raise PlanError(f"The plan's {label} must be a number of seconds >= 0, got {value!r}.")
    return plan


# --- The pick-and-place ----------------------------------------------------------
@dataclass
class RunResult:
    """What happened on the arm."""

    start_pose: Configuration
    cycles: list[Cycle] = field(default_factory=list)
    segments: list[Segment] = field(default_factory=list)
    stretched: list[str] = field(default_factory=list)
    final_pose: Configuration | None = None
    aborted: str | None = None
    returned_to_start: bool = False
    unreleased: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)
    stale_bytes: int = 0  # late-reply bytes dropped before reads (see discard_stale_input)


def _describe(error: BaseException, step: str) -> str:
    where = f" (during '{step}')" if step else ""
    if isinstance(error, (KeyboardInterrupt, StopRequested)):
        return f"stopped by Ctrl-C{where}"
    text = str(error).rstrip(".")
    if isinstance(error, HardwareError):
        return f"{text}{where}"
    return f"{type(error).__name__}: {text}{where}"


def clamp_to_limits(cfg: Mapping[str, float], limits: Limits) -> Configuration:
    """``cfg`` with each joint clamped into its limits."""
    return {j: min(limits[j][1], max(limits[j][0], cfg[j])) for j in JOINTS}


def execute(session: ArmSession, plan: Plan, start_pose: Configuration,
            return_on_abort: bool = True) -> RunResult:
    """Run a validated plan on a torqued arm; on any failure stop, return slowly if safe, release.

    Args:
        session: the armed session (torque on).
        plan: validated plan.
        start_pose: the measured starting pose (inside the calibrated range);
            the plan ends there.
        return_on_abort: move slowly back to ``start_pose`` after an abort
            when the bus still answers.

    Returns:
        The result (torque released on success too).

    Raises:
        MotionAborted: after stopping and releasing; ``.result`` has the details.
    """
    result = RunResult(dict(start_pose))
    bus = session.bus

    def on_step(step: Step) -> None:
        session.step = step.name
        logger.info("-> %s (%.2f s, hold %.2f s)", step.name, step.duration, step.hold)

    try:
        with gc_frozen(), stop_on_sigint(session):
            run_plan(plan, session.move, session.hold, initial=start_pose, on_step=on_step)
    except (Exception, KeyboardInterrupt) as error:
        step = session.step
        result.aborted = _describe(error, step)
        logger.error("Aborting: %s", result.aborted)
        if isinstance(error, KeyboardInterrupt):
            recover_port(bus)  # Ctrl-C may have cut a transaction in half
        bus_failed = isinstance(error, BusError)
        if bus_failed:
            silent = silent_servos(bus)
            if silent:
                names = ", ".join(f"{j} (id {MOTOR_IDS[j]})" for j in silent)
                result.aborted += f". Not answering: {names}"
        if return_on_abort and not bus_failed:
            session.stop_reason = None
            try:
                with stop_on_sigint(session):
                    session.return_slowly(start_pose)
                result.returned_to_start = True
            except (Exception, KeyboardInterrupt) as second:
                logger.error("The return to the starting pose stopped: %s",
                             _describe(second, "abort_return"))
                if isinstance(second, KeyboardInterrupt):
                    recover_port(bus)
    finally:
        try:
            result.final_pose = session.read_pose()
        except (Exception, KeyboardInterrupt):
            result.final_pose = None
        result.unreleased = release_torque(bus)
        result.cycles, result.segments = session.cycles, session.segments
        result.stretched = session.stretched
        result.stale_bytes = session.stale_bytes
        if len(session.cycles) >= 3:
            result.timing = session.timing()
    if result.aborted is not None:
        if result.returned_to_start:
            after = "The arm moved slowly back to its starting pose"
        elif result.aborted.startswith("stopped") or not return_on_abort:
            after = "The arm stopped where it was"
        else:
            after = "The arm was NOT moved back (the bus failed or the return stopped)"
        if result.unreleased:
            after += ("; torque could NOT be released on " + ", ".join(result.unreleased)
                      + ": support the arm and switch off its power supply.")
        else:
            after += "; torque is off on every servo."
        raise MotionAborted(f"Pick-and-place aborted: {result.aborted}. {after}", result)
    return result


def run_on_arm(port: str, calibration_path: str | Path, plan: Plan, *, robot_id: str | None = None,
               rate_hz: float = DEFAULT_RATE_HZ, profile: str = "minimum_jerk",
               max_joint_speed: float = MAX_JOINT_SPEED_DEG_S,
               tracking_tolerance: float = TRACKING_TOLERANCE_DEG,
               confirm: Callable[[str], bool] | None = None, write_calibration: bool = False,
               return_on_abort: bool = True,
               on_cycle: Callable[[ArmSession, Cycle], None] | None = None) -> RunResult:
    """The whole hardware run: check, connect, confirm, torque on, run, return, torque off.

    Nothing is sent to the servos' goal registers and torque stays off until
    the plan has passed both limit checks, the servos answered, their
    calibration matched the file and ``confirm`` (if given) said yes.

    Args:
        port: serial port of the arm.
        calibration_path: lerobot calibration JSON of this arm.
        plan: the plan (validated here against model and calibrated limits).
        robot_id: for messages.
        rate_hz: control loop rate [Hz].
        profile: "minimum_jerk" or "linear".
        max_joint_speed: speed cap of the arm joints [deg/s].
        tracking_tolerance: stall/collision tolerance of the arm joints [deg].
        confirm: asked with a summary before torque on; False refuses.
        write_calibration: write the file into the servos if they differ.
        return_on_abort: move back slowly after an abort when the bus answers.
        on_cycle: hook called after each control cycle.

    Returns:
        The run's result.

    Raises:
        CalibrationError, PlanError, ConnectionFailed, LerobotMissing, NotConfirmed:
            refused before anything moved.
        MotionAborted: aborted during motion (stopped, returned if safe, released).
    """
    calibration = load_calibration(calibration_path, robot_id)
    validate_plan_for_arm(plan, calibration, str(calibration_path))
    RateLoop(rate_hz)  # validates the rate before connecting
    if not (isinstance(max_joint_speed, (int, float)) and max_joint_speed > 0):
        raise PlanError(f"The speed cap must be > 0 deg/s, got {max_joint_speed!r}.")
    if not (isinstance(tracking_tolerance, (int, float)) and tracking_tolerance > 0):
        raise PlanError(f"The tracking tolerance must be > 0 deg, got {tracking_tolerance!r}.")
    bus = connect(port, calibration, robot_id=robot_id, write_calibration=write_calibration)
    armed = False
    try:
        limits = calibrated_limits(calibration)
        with bus_errors("reading the starting pose"):
            measured = {j: float(v) for j, v in bus.sync_read("Present_Position").items()}
        start = clamp_to_limits(measured, limits)
        for joint in JOINTS:
            if abs(start[joint] - measured[joint]) > LIMIT_SLACK_DEG:
                raise CalibrationError(
                    f"The arm's {joint} reads {measured[joint]:.1f} {unit(joint)}, outside its "
                    f"calibrated range [{limits[joint][0]:.1f}, {limits[joint][1]:.1f}]: the "
                    "calibration does not fit this arm. Fix: `"
                    + CALIBRATE_HINT.format(port=port, robot_id=robot_id or "ID") + "`.")
        bounds = model_limits()
        outside_model = [j for j in JOINTS if not bounds[j][0] <= start[j] <= bounds[j][1]]
        if outside_model:
            logger.warning("The starting pose is outside the model's limits on %s; the arm will "
                           "return there at the end anyway (it is where it stood).",
                           ", ".join(outside_model))
        session = ArmSession(
            bus, rate_hz=rate_hz, profile=profile, max_speed=speed_caps(max_joint_speed),
            tracking_tolerance=tracking_tolerances(tracking_tolerance),
            on_cycle=on_cycle)
        session.command = dict(start)
        first = plan.steps[0]
        first_duration = capped_duration(start, first.configuration, first.duration, profile,
                                         session.max_speed)
        print("Starting pose (returned to at the end): " + format_configuration(start))
        print(f"First move: to '{first.name}' in {first_duration:.2f} s, ramping from this pose.")
        if confirm is not None and not confirm("Enable torque and run the pick-and-place?"):
            raise NotConfirmed("Not confirmed: nothing moved.")
        armed = True
        with bus_errors("configuring the servos and enabling torque"):
            configure(bus)
            enable_torque_in_place(bus)
        return execute(session, plan, start, return_on_abort=return_on_abort)
    except MotionAborted:
        raise  # execute() stopped, returned if safe and released already
    except BaseException:
        if armed:
            unreleased = release_torque(bus)
            if unreleased:
                logger.error("Torque could NOT be released on %s: support the arm and switch off "
                             "its power supply.", ", ".join(unreleased))
        raise
    finally:
        disconnect(bus)


# --- Output: plan, FK, log, plot ------------------------------------------------
def format_configuration(cfg: Mapping[str, float], digits: int = 1) -> str:
    """A configuration as a JSON object (valid Python and waypoint-file syntax)."""
    return json.dumps({j: round(float(cfg[j]), digits) for j in JOINTS if j in cfg})


def object_position_cm(cfg: Mapping[str, float]) -> tuple[float, float, float]:
    """FK object-frame position in the base frame [cm]."""
    position, _ = get_forward_kinematics({j: cfg[j] for j in ARM_JOINTS})
    return tuple(float(v) * 100.0 for v in position)


def format_plan(plan: Plan, *, rate_hz: float, profile: str, max_speed: Mapping[str, float],
                start: Configuration | None = None) -> str:
    """The plan as a table (durations after the speed cap) and the cube positions to place [cm]."""
    lines = [f"Plan: {len(plan.steps)} waypoints, {rate_hz:g} Hz, profile {profile}, speed cap "
             f"{max_speed['shoulder_pan']:g} deg/s (gripper {max_speed['gripper']:g} %/s)"]
    header = f"  {'#':>2} {'waypoint':<16}{'move':>7}{'hold':>6}" + "".join(
        f"{j[:13]:>14}" for j in JOINTS) + "    object x, y, z [cm]"
    lines.append(header)
    previous = start
    for i, step in enumerate(plan.steps, 1):
        if previous is None:
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
        lines.append(f"  {len(plan.steps) + 1:>2} {'return_to_start':<16}"
                     f"{plan.return_duration:>6.2f}*     back to the measured starting pose")
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


def write_log_csv(cycles: list[Cycle], path: str | Path) -> Path:
    """CSV: t_s (scheduled), wall_s (actual cycle start), step, cmd_<joint>, meas_<joint>."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["t_s", "wall_s", "step"] + [f"cmd_{j}" for j in JOINTS]
                        + [f"meas_{j}" for j in JOINTS])
        for c in cycles:
            measured = [f"{c.measured[j]:.4f}" if c.measured else "" for j in JOINTS]
            writer.writerow([f"{c.t_s:.6f}", f"{c.wall_s:.6f}", c.step]
                            + [f"{c.command[j]:.4f}" for j in JOINTS] + measured)
    return path


def plot_log(cycles: list[Cycle], path: str | Path,
             title: str = "SO-101: commanded vs measured") -> Path:
    """PNG with one panel per joint: commanded and measured against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    t = [c.t_s for c in cycles]
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    measured = [c for c in cycles if c.measured]
    for ax, joint in zip(axes.flat, JOINTS, strict=True):
        ax.plot(t, [c.command[joint] for c in cycles], label="commanded", lw=1.5)
        ax.plot([c.t_s for c in measured], [c.measured[joint] for c in measured],
                label="measured", lw=1.0, ls="--")
        worst = max((abs(c.command[joint] - c.measured[joint]) for c in measured), default=0.0)
        ax.set_title(f"{joint}  (max |commanded - measured| = {worst:.2f} {unit(joint)})",
                     fontsize=10)
        ax.set_ylabel("[%]" if joint == "gripper" else "[deg]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes.flat[0].legend(loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# --- Teach mode ------------------------------------------------------------------
def teach(bus, *, rate_hz: float = TEACH_RATE_HZ, duration: float | None = None,
          out=None) -> Configuration | None:
    """Torque off; print the pose live (configuration dict + FK object position) until Ctrl-C.

    Args:
        bus: connected bus.
        rate_hz: print rate [Hz].
        duration: stop after this long [s] (None: until Ctrl-C).
        out: text stream (default stdout); a terminal gets one updating line.

    Returns:
        The last pose read.
    """
    out = out or sys.stdout
    bus.disable_torque()
    live = hasattr(out, "isatty") and out.isatty()
    print("Torque is off: move the arm by hand. Ctrl-C to stop.", file=out)
    loop = RateLoop(rate_hz)
    started = loop.start()
    pose = None
    try:
        while duration is None or loop.deadline - started < duration - 1e-9:
            raw = bus.sync_read("Present_Position")
            pose = {j: float(raw[j]) for j in JOINTS}
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


# --- Command line ------------------------------------------------------------------
def ask(question: str, assume_yes: bool, stdin=None) -> bool:
    """Ask yes/no on a terminal; ``assume_yes`` answers yes; never blocks on a non-terminal.

    Raises:
        NotConfirmed: stdin is not a terminal and ``assume_yes`` is False.
    """
    if assume_yes:
        return True
    stdin = stdin or sys.stdin
    if not (hasattr(stdin, "isatty") and stdin.isatty()):
        raise NotConfirmed(f"{question} - cannot ask: stdin is not a terminal. Pass --yes to run "
                           "without confirmation.")
    print(f"{question} [y/N] ", end="", flush=True)
    answer = stdin.readline()
    return answer.strip().lower() in ("y", "yes")


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        description="The course's pick-and-place on a real SO-101 follower (lerobot Feetech bus). "
                    "Validates the whole plan against the model's and the arm's calibrated limits "
                    "before torque on; ramps from the measured pose; caps joint speed; runs a "
                    "deadline-scheduled loop reading the arm every cycle; aborts on a stall, a bus "
                    "error or Ctrl-C by moving slowly back to the start and releasing torque.",
        epilog="Examples:\n  python pick_place_hw.py --calibration my_arm.json --dry-run\n"
               "  python pick_place_hw.py --port /dev/ttyACM0 --id my_arm --log run.csv "
               "--plot run.png\n"
               "  python pick_place_hw.py --port /dev/ttyACM0 --id my_arm --teach",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--port", help=f"serial port of the arm (find it with `{FIND_PORT_HINT}`)")
    who = parser.add_mutually_exclusive_group()
    who.add_argument("--id", dest="robot_id",
                     help="robot id given to lerobot-calibrate; the calibration is read from "
                          "$HF_LEROBOT_CALIBRATION/robots/so_follower/ID.json (or so101_follower/)")
    who.add_argument("--calibration", type=Path, help="lerobot calibration JSON file of this arm")
    parser.add_argument("--plan", type=Path, help="waypoint file (JSON or TOML) instead of the "
                        "course's plan")
    parser.add_argument("--move-duration", type=float, default=2.0,
                        help="duration of each move of the built-in plan [s] (default 2)")
    parser.add_argument("--hold", type=float, default=0.5,
                        help="pause after each move of the built-in plan [s] (default 0.5)")
    parser.add_argument("--profile", choices=sorted(PROFILES), default="minimum_jerk",
                        help="time scaling of each move (default minimum_jerk, as the simulator)")
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ,
                        help=f"control loop rate [Hz] (default {DEFAULT_RATE_HZ:g})")
    parser.add_argument("--max-speed", type=float, default=MAX_JOINT_SPEED_DEG_S,
                        help="speed cap of each arm joint [deg/s] (default "
                             f"{MAX_JOINT_SPEED_DEG_S:g}); too-short moves are stretched")
    parser.add_argument("--tracking-tolerance", type=float, default=TRACKING_TOLERANCE_DEG,
                        help=f"abort when a joint is this far from its command [deg] for "
                             f"{TRACKING_TIMEOUT_S:g} s (default {TRACKING_TOLERANCE_DEG:g})")
    parser.add_argument("--dry-run", action="store_true",
                        help="validate and print the plan and cube positions; send nothing")
    parser.add_argument("--teach", action="store_true",
                        help="torque off; print the pose live as a configuration and its FK "
                             "object position")
    parser.add_argument("--yes", "-y", action="store_true",
                        help="do not ask before enabling torque")
    parser.add_argument("--write-calibration", action="store_true",
                        help="if the servos hold another calibration, write the file into them")
    parser.add_argument("--no-return-on-abort", action="store_true",
                        help="after an abort, release torque where the arm is instead of returning")
    parser.add_argument("--log", type=Path,
                        help="CSV of time, commanded and measured joints per cycle")
    parser.add_argument("--plot", type=Path, help="PNG of commanded vs measured per joint")
    parser.add_argument("--verbose", "-v", action="store_true", help="debug logging")
    add_cartesian_arguments(parser)
    return parser


def _dry_run(args, plan: Plan, calibration) -> int:
    caps = speed_caps(args.max_speed)
    start = None
    if args.port:
        try:
            bus = connect(args.port, calibration, robot_id=args.robot_id)
        except LerobotMissing as error:
            logger.warning("%s Showing the plan without reading the arm.", error)
        else:
            try:
                measured = {j: float(v) for j, v in bus.sync_read("Present_Position").items()}
                start = clamp_to_limits(measured, calibrated_limits(calibration))
                print("Measured starting pose: " + format_configuration(measured))
            finally:
                disconnect(bus)
    print(format_plan(plan, rate_hz=args.rate, profile=args.profile, max_speed=caps, start=start))
    print("Dry run: the plan is valid; nothing was sent to the arm.")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 1 aborted, 2 refused)."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s: %(message)s")
    try:
        plan = plan_from_arguments(args) or (
            load_plan(args.plan) if args.plan else default_plan(args.move_duration, args.hold))
        calibration, source = None, None
        if args.calibration:
            source = args.calibration
        elif args.robot_id:
            source = find_calibration(args.robot_id, args.port)
        if source is not None:
            calibration = load_calibration(source, args.robot_id)
            logger.info("Calibration: %s", source)
        elif not args.dry_run:
            raise CalibrationError("Tell me which arm: --id ROBOT_ID (the id you gave "
                                   "lerobot-calibrate) or --calibration PATH.")
        validate_plan_for_arm(plan, calibration, str(source))
        RateLoop(args.rate)
        if calibration is None:
            logger.warning("No calibration given: checked against the model's limits only.")
        if args.dry_run:
            return _dry_run(args, plan, calibration)
        if args.teach:
            bus = connect(args.port, calibration, robot_id=args.robot_id)
            try:
                teach(bus)
            finally:
                disconnect(bus)
            return 0
        print(format_plan(plan, rate_hz=args.rate, profile=args.profile,
                          max_speed=speed_caps(args.max_speed)))
        result = run_on_arm(
            args.port, source, plan, robot_id=args.robot_id, rate_hz=args.rate,
            profile=args.profile,
            max_joint_speed=args.max_speed, tracking_tolerance=args.tracking_tolerance,
            confirm=lambda q: ask(q, args.yes), write_calibration=args.write_calibration,
            return_on_abort=not args.no_return_on_abort)
    except MotionAborted as error:
        print(f"ABORTED: {error}", file=sys.stderr)
        _write_outputs(args, error.result)
        return 1
    except (HardwareError, PlanError, ValueError) as error:
        print(f"Refused, nothing moved: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("Interrupted.", file=sys.stderr)
        return 130
    _write_outputs(args, result)
    timing = result.timing
    print("Done: back at the starting pose, torque off. Loop "
          f"{timing.get('achieved_hz', 0):.1f} Hz, "
          f"period p50 {timing.get('period_p50_ms', 0):.2f} ms, p99 error "
          f"{timing.get('period_p99_error_ms', 0):.2f} ms, {timing.get('overruns', 0)} overruns.")
    return 0


def _write_outputs(args, result: RunResult) -> None:
    if args.log and result.cycles:
        print(f"Log: {write_log_csv(result.cycles, args.log)}")
    if args.plot and result.cycles:
        print(f"Plot: {plot_log(result.cycles, args.plot)}")


if __name__ == "__main__":
    sys.exit(main())
