"""The pick-and-place on the real arm: check, connect, confirm, run, and end the same way always.

The fault policy (docs/hardware_safety.md) in one place, :func:`execute`:
every way a run can end (done, a fault, a stop signal, an exception) ends
with a controlled stop (goal = present position, torque on), the slow return
to the starting pose when the whole arm answers, and the torque released
there. Torque is never released away from the starting pose by the program:
a position-controlled servo holds its last goal by itself, so holding is
safer than letting go. :func:`ending` says where the arm is and whether it
is torqued; :func:`release_arm` is the explicit release, with the arm in hand.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from so101_kinematics.calibration import CALIBRATE_HINT, MOTOR_IDS, calibrated_limits
from so101_kinematics.errors import (
    CalibrationError,
    FreezeRequested,
    HardwareError,
    NotConfirmed,
    PortLost,
    StopRequested,
    TorqueLost,
)
from so101_kinematics.frames import JOINT_LIMITS, JOINTS
from so101_kinematics.hw.bus import (
    SETUP_ATTEMPTS,
    bus_errors,
    clamp_to_limits,
    connect,
    disconnect,
    format_pose,
    read_block,
    read_pose,
    recover_port,
    release_torque,
    silent_servos,
    with_retries,
)
from so101_kinematics.hw.control import RECOVERY_TIMEOUT_S, ArmSession
from so101_kinematics.hw.cycle_checks import read_torque
from so101_kinematics.hw.feedforward import read_feedforward, torque_on_in_place
from so101_kinematics.hw.grip import held_grip
from so101_kinematics.hw.lead import VelocityLead
from so101_kinematics.hw.preflight import check_run_settings, validate_plan_for_arm
from so101_kinematics.hw.putdown import put_down
from so101_kinematics.hw.servo_settings import (
    configure_as_course,
    describe_unable,
    describe_unread,
    read_back,
)
from so101_kinematics.hw.signals import gc_frozen, stop_on_signals
from so101_kinematics.hw.timing import (
    DEFAULT_RATE_HZ,
    MAX_JOINT_SPEED_DEG_S,
    TRACKING_TOLERANCE_DEG,
    Cycle,
    Segment,
    TimeSource,
    capped_duration,
    speed_caps,
    tracking_tolerances,
)
from so101_kinematics.inputs import Configuration, unit
from so101_kinematics.planning.motion import Plan, Step, run_plan
from so101_kinematics.sensors.cube_reader import read_cubes
from so101_kinematics.sensors.cube_wire import CubeReading
from so101_kinematics.trims import Trims, as_trims

__all__ = [
    "LIMIT_SLACK_DEG", "MotionAborted", "RELEASE_HINT", "RunResult", "after_abort", "ending",
    "execute", "finish", "release_arm", "run_on_arm", "starting_pose",
]

logger = logging.getLogger("pick_place_hw")

LIMIT_SLACK_DEG = 2.0  # a start this far outside the calibration is clamped [deg]
RELEASE_HINT = "python pick_place_hw.py --release --port {port} {arm}"  # arm held by hand


class MotionAborted(HardwareError):
    """The motion was aborted; ``result`` says where the arm is and whether it is torqued."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result


@dataclass
class RunResult:
    """What happened on the arm, and how it was left."""

    start_pose: Configuration
    cycles: list[Cycle] = field(default_factory=list)
    segments: list[Segment] = field(default_factory=list)
    stretched: list[str] = field(default_factory=list)
    outages: list[tuple[float, float]] = field(default_factory=list)  # (start, length) [s]
    final_pose: Configuration | None = None
    final_step: str = ""
    aborted: str | None = None
    returned_to_start: bool = False  # the plan's return or the abort's return completed
    torque_released: bool = False
    unreleased: list[str] = field(default_factory=list)
    silent: list[str] = field(default_factory=list)
    usb_lost: bool = False
    frozen: bool = False
    timing: dict[str, float] = field(default_factory=dict)
    stale_bytes: int = 0  # late-reply bytes dropped before reads (see discard_stale_input)
    cube: CubeReading | None = None  # the virtual lab's cube sensor at the end; None on a real arm
    cubes: list[CubeReading] = field(default_factory=list)  # every cube it reports (stacking)
    torque: dict[str, bool] | None = None  # Torque_Enable read back at the end (None: unread)
    unable: dict[str, str] = field(default_factory=dict)  # joint -> why it cannot hold (read back)
    unread: list[str] = field(default_factory=list)  # hold settings the ending could not read


def _describe(error: BaseException, step: str) -> str:
    where = f" (during '{step}')" if step else ""
    if isinstance(error, (KeyboardInterrupt, StopRequested)):
        name = str(error) or "Ctrl-C"
        return f"stopped by {name}{where}"
    text = str(error).rstrip(".")
    if isinstance(error, HardwareError):
        return f"{text}{where}"
    return f"{type(error).__name__}: {text}{where}"


def after_abort(session: ArmSession, error: BaseException, start_pose: Configuration,
                return_on_abort: bool, result: RunResult, plan: Plan | None = None) -> None:
    """Controlled stop; a held cube put down (``hw/putdown.py``); the slow return; else hold."""
    held = held_grip(session)  # the run's cycles, before the stop's
    result.aborted = _describe(error, session.step)
    logger.error("Aborting: %s", result.aborted)
    bus = session.bus
    if isinstance(error, PortLost):
        result.usb_lost = True
        return
    try:
        with stop_on_signals(session, freeze_at_once=True):
            if isinstance(error, FreezeRequested):
                raise error  # a freeze, not a stop: below
            pose = session.stop_here()
            if pose is None:
                logger.warning("Holding; waiting up to %g s for every servo to answer ...",
                               RECOVERY_TIMEOUT_S)
                pose = session.wait_for_arm()
            if pose is None:
                result.silent = silent_servos(bus)
                return
            if isinstance(error, TorqueLost):  # hold the limp joint where it sank, then return
                with bus_errors("enabling torque again where the arm is"):
                    with_retries(lambda b: torque_on_in_place(
                        b, session.feedforward, clock=session.loop.clock,
                        sleep=session.loop.sleep), bus)
            if return_on_abort:
                session.stop_reason = None
                session.return_slowly(put_down(session, plan, held, error, start_pose))
                result.returned_to_start = True
    except FreezeRequested:
        recover_port(bus)
        session.stop_here()
        result.frozen = True
    except PortLost:
        result.usb_lost = True
    except Exception as second:  # noqa: BLE001 - the return stopped: hold where it is
        logger.error("The return to the starting pose stopped: %s",
                     _describe(second, "abort_return"))
        recover_port(bus)
        if session.stop_here() is None:
            result.silent = silent_servos(bus)


def execute(session: ArmSession, plan: Plan, start_pose: Configuration,
            return_on_abort: bool = True,
            then: Callable[[ArmSession], None] | None = None) -> RunResult:
    """Run a validated plan on a torqued arm; every ending is a controlled one.

    Args:
        session: the armed session (torque on).
        plan: validated plan.
        start_pose: the measured starting pose (inside the calibrated range).
        return_on_abort: after an abort, move slowly back to ``start_pose``
            when the whole arm answers (else hold where it stopped).
        then: a closed loop run after the plan's steps, before its return, given the
            session: it moves through ``session.move`` and ``session.hold`` (their guards).

    Returns:
        The result. Torque is released only if the arm ended at ``start_pose``.

    Raises:
        MotionAborted: after the controlled ending; ``.result`` has the details.
    """
    result = RunResult(dict(start_pose))
    session.rest_pose = dict(start_pose)  # every move may come as low as where the arm stood

    def on_step(step: Step) -> None:
        session.step = step.name
        logger.info("-> %s (%.2f s, hold %.2f s)", step.name, step.duration, step.hold)

    try:
        with gc_frozen(), stop_on_signals(session):
            run_plan(plan, session.move, session.hold, initial=start_pose, on_step=on_step,
                     then=None if then is None else lambda: then(session))
        result.returned_to_start = plan.return_to_start
    except (Exception, KeyboardInterrupt) as error:
        after_abort(session, error, start_pose, return_on_abort, result, plan)
    finally:
        finish(session, result)
    if result.aborted is not None:
        raise MotionAborted(f"Pick-and-place aborted: {result.aborted}.", result)
    return result


def finish(session: ArmSession, result: RunResult) -> None:
    """Record the run in ``result``; release the torque only if the arm returned to the start."""
    result.cycles, result.segments = session.cycles, session.segments
    result.stretched, result.outages = session.stretched, session.outages
    result.stale_bytes, result.final_step = session.stale_bytes, session.step
    if len(session.cycles) >= 3:
        result.timing = session.timing()
    if not result.usb_lost:
        try:
            result.final_pose = session.read_pose()  # where it holds, or is released
        except (Exception, KeyboardInterrupt):
            result.final_pose = None
        result.cubes = read_cubes(lambda *block: read_block(session.bus, *block))
        result.cube = result.cubes[0] if result.cubes else None
        if result.returned_to_start:
            result.unreleased = release_torque(session.bus)
            result.torque_released = not result.unreleased
        result.torque = read_torque(session.bus)  # the last line says what the servos say
        if not result.torque_released:  # and whether each can hold where it is
            result.torque, result.unable, result.unread = read_back(
                session.bus, result.final_pose, result.torque)


def ending(result: RunResult, release: str) -> str:
    """The run's last line: where the arm is and whether it is torqued, and what to do."""
    hold = f"Support the arm with a hand, then release it with: {release}"
    if result.usb_lost:
        return ("The arm's USB connection was lost: the servos hold their last goal, torque ON. "
                f"Support the arm, plug the cable back in, then release it with: {release}")
    if result.returned_to_start and result.torque_released:
        done = "Done: b" if result.aborted is None else "B"
        return f"{done}ack at the starting pose, torque off."
    if result.returned_to_start:
        return (f"The arm is back at its starting pose, but torque could NOT be released on "
                f"{', '.join(result.unreleased)} (not answering): it holds there. Check the cable "
                f"to that servo and run: {release}")
    if result.silent:
        names = ", ".join(f"{j} (id {MOTOR_IDS[j]})" for j in result.silent)
        return (f"Not answering: {names}. The other servos hold where they are, torque ON (a "
                f"powered silent servo holds its last goal). Check the cable and power of the "
                f"silent servo(s). {hold}")
    pose = "" if result.final_pose is None else f" ({format_pose(result.final_pose)})"
    torque = torque_words(result.torque, result.unable, result.unread)
    holding = "NOT holding" if result.unable else "holding"
    if result.frozen:
        return f"Frozen where it was by a second stop signal{pose}, {torque}. {hold}"
    if result.aborted is None:
        return (f"Done: {holding} the final pose "
                f"'{result.final_step}'{pose}, {torque} (the plan has return_to_start: "
                f"false). {hold}")
    return f"The arm is {holding} where it stopped{pose}, {torque}. {hold}"


def torque_words(torque: dict[str, bool] | None, unable: Mapping[str, str] | None = None,
                 unread: list[str] | None = None) -> str:
    """The torque as read back from the servos, for a last line (never what was commanded).

    ``unable``: the servos that cannot hold where they are (``servo_settings.unable_to_hold``);
    ``unread``: the hold settings the ending could not read (said, never guessed).
    """
    cannot = f", but {describe_unable(unable)}" if unable else ""
    if unread:
        cannot += f"{'; ' if unable else ', but '}{describe_unread(unread)}"
    if torque is None:
        return f"torque not read back (commanded ON){cannot}"
    limp = [joint for joint, on in torque.items() if not on]
    if not limp:
        return f"torque ON{cannot}"
    if len(limp) == len(torque):
        return "torque OFF on every servo (read back): the arm is limp"
    return (f"torque ON, but OFF on {', '.join(limp)} (read back: limp)"
            f"{cannot.replace(', but', ';', 1)}")


def starting_pose(bus, calibration, port: str, robot_id: str | None) -> Configuration:
    """The measured pose, clamped into the calibration; refused if far outside it."""
    limits = calibrated_limits(calibration)
    with bus_errors("reading the starting pose"):
        measured = read_pose(bus, SETUP_ATTEMPTS - 1)
    start = clamp_to_limits(measured, limits)
    for joint in JOINTS:
        if abs(start[joint] - measured[joint]) > LIMIT_SLACK_DEG:
            raise CalibrationError(
                f"The arm's {joint} reads {measured[joint]:.1f} {unit(joint)}, outside its "
                f"calibrated range [{limits[joint][0]:.1f}, {limits[joint][1]:.1f}]: the "
                "calibration does not fit this arm. Fix: `"
                + CALIBRATE_HINT.format(port=port, robot_id=robot_id or "ID") + "`.")
    bounds = JOINT_LIMITS
    outside = [j for j in JOINTS if not bounds[j][0] <= start[j] <= bounds[j][1]]
    if outside:
        logger.warning("The starting pose is outside the model's limits on %s; the arm will "
                       "return there at the end anyway (it is where it stood).", ", ".join(outside))
    return start


def run_on_arm(port: str, calibration: Mapping[str, Any], plan: Plan, *,
               robot_id: str | None = None, source: str = "the calibration",
               rate_hz: float = DEFAULT_RATE_HZ, profile: str = "minimum_jerk",
               max_joint_speed: float = MAX_JOINT_SPEED_DEG_S,
               tracking_tolerance: float = TRACKING_TOLERANCE_DEG,
               confirm: Callable[[str], bool] | None = None, write_calibration: bool = False,
               return_on_abort: bool = True, trims: Trims | str | None = None,
               on_cycle: Callable[[ArmSession, Cycle], None] | None = None,
               on_start: Callable[[Configuration, float], None] | None = None,
               gravity_ff: bool = True, base_height: float = 0.0,
               velocity_ff: bool = False, time_source: TimeSource | None = None,
               then: Callable[[ArmSession], None] | None = None) -> RunResult:
    """The whole hardware run: check, connect, confirm, torque on, run, return, torque off.

    Nothing is sent to the servos' goal registers and torque stays off until
    the plan has passed both limit checks, the servos answered, their
    calibration matched and ``confirm`` (if given) said yes.

    Args:
        port: serial port of the arm.
        calibration: the loaded lerobot calibration of this arm (``load_calibration``).
        plan: the plan (validated here against model and calibrated limits).
        robot_id: for messages.
        source: where the calibration came from (for messages).
        rate_hz: control loop rate [Hz].
        profile: "minimum_jerk" or "linear".
        max_joint_speed: speed cap of the arm joints [deg/s].
        tracking_tolerance: stall/collision tolerance of the arm joints [deg].
        confirm: asked before torque on; False refuses.
        write_calibration: write the calibration into the servos if they differ.
        return_on_abort: after an abort, move back slowly when the arm answers.
        trims: per-joint offsets added to every goal (a Trims, a mapping or a trim file).
        on_cycle: hook called after each control cycle (the log).
        on_start: called with the measured starting pose and the first move's
            duration [s] before ``confirm``.
        gravity_ff: offset each goal by the sag the servos will have (``hw/feedforward.py``).
        base_height: the table is this far below the base frame [m]: no move goes into it.
        velocity_ff: lead each goal by the servos' lag x the planned velocity (``hw/lead.py``).
        then: a closed loop after the plan's steps, before the return (see :func:`execute`).
        time_source: the run's time (the control loop, the torque's ramp): None for the wall
            clock, or a simulated one (the virtual arm's ``clock``, ``virtual/sim_clock.py``).
            The bus's own waits (a port settling, lerobot's timeouts) stay on the wall clock.

    Raises:
        CalibrationError, PlanError, ConnectionFailed, LerobotMissing, NotConfirmed:
            refused before anything moved.
        MotionAborted: aborted during motion (controlled ending done).
    """
    trims = as_trims(trims)
    validate_plan_for_arm(plan, calibration, source, trims, base_height)
    check_run_settings(rate_hz, max_joint_speed, tracking_tolerance)
    ramp_time = {} if time_source is None else {"clock": time_source.clock,
                                                "sleep": time_source.sleep}
    loop_time = {} if time_source is None else {**ramp_time, "spin": time_source.spin}
    bus = connect(port, calibration, robot_id=robot_id, write_calibration=write_calibration)
    armed = False
    try:
        start = trims.from_wire(starting_pose(bus, calibration, port, robot_id))
        session = ArmSession(
            bus, rate_hz=rate_hz, profile=profile, max_speed=speed_caps(max_joint_speed),
            tracking_tolerance=tracking_tolerances(tracking_tolerance), on_cycle=on_cycle,
            trims=trims, base_height=base_height, **loop_time)
        session.command = dict(start)
        first = plan.steps[0]
        if on_start is not None:
            on_start(start, capped_duration(start, first.configuration, first.duration, profile,
                                            session.max_speed))
        if confirm is not None and not confirm("Enable torque and run the pick-and-place?"):
            raise NotConfirmed("Not confirmed: nothing moved.")
        armed = True
        with bus_errors("configuring the servos and enabling torque"):
            configure_as_course(bus, "pick_place_hw")
            session.feedforward = feedforward = read_feedforward(bus, gravity_ff)
            session.velocity_lead = VelocityLead.for_feedforward(feedforward, velocity_ff)
            with_retries(lambda b: torque_on_in_place(b, feedforward, trims.to_wire(start),
                                                      **ramp_time), bus)
        return execute(session, plan, start, return_on_abort=return_on_abort, then=then)
    except MotionAborted:
        raise
    except BaseException:
        if armed:  # torque came on at the start pose and nothing moved: release there
            unreleased = release_torque(bus)
            if unreleased:
                logger.error("Torque could NOT be released on %s (at the starting pose).",
                             ", ".join(unreleased))
        raise
    finally:
        disconnect(bus)


def release_arm(port: str, calibration: Mapping[str, Any], *, robot_id: str | None = None,
                confirm: Callable[[str], bool] | None = None) -> list[str]:
    """Release the torque of every servo, asked for explicitly with the arm held by hand.

    Returns:
        The joints whose servo did not answer (still torqued if powered).

    Raises:
        NotConfirmed: the user said no.
    """
    bus = connect(port, calibration, robot_id=robot_id, check_calibration=False)
    try:
        question = ("Hold the arm with a hand: without torque it falls under gravity. "
                    "Release the torque now?")
        if confirm is not None and not confirm(question):
            raise NotConfirmed("Not confirmed: torque unchanged.")
        return release_torque(bus)
    finally:
        disconnect(bus)
