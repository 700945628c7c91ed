"""The course's hardware helpers (so101_utils.py) over the hardware backend, with its fault policy.

Assignment 8's example drives the arm with ``load_calibration``,
``setup_motors``, ``move_to_pose(bus, cfg, duration)``,
``hold_position(bus, duration)`` and ends with ``bus.disable_torque()``.
Here they are a thin face: the control loop is :class:`ArmSession`'s
(``hw/control.py``), the endings are ``hw/run.py``'s, so each call keeps the
policy of docs/hardware_safety.md (holding is safer than letting go; torque
is released only at the starting pose, the pose the arm had at
:func:`setup_motors`):

- a fault, Ctrl-C, SIGTERM, SIGHUP or an exception inside ``move_to_pose`` or
  ``hold_position``: controlled stop, slow return to the starting pose, torque
  released there; the last line says where the arm is and whether it is
  torqued, and the script ends there (:class:`ScriptEnded`, exit status 1);
- ``bus.disable_torque()`` at the starting pose releases at once; away from
  it, the arm first returns there slowly (so the course's "move back, then
  disable torque" and a forgotten move back both end released at the start);
- a script that ends without it (done, an exception, Ctrl-C or SIGTERM/SIGHUP
  between the calls) gets the same ending when Python exits;
- input refused before anything moved (calibration, port): one line, exit 2.

The bus handed out is a :class:`~so101_kinematics.hw.guarded.GuardedBus`: the
student's own ``bus.sync_write("Goal_Position", ...)`` is a checked move
ramped at the speed cap (:func:`course_write_goal`), ``Torque_Enable`` 0 is
``bus.disable_torque()``, a write that could drop, spin or weaken the arm is
refused (:func:`course_refuse_write`); raw lerobot is ``bus.raw``.
:func:`setup_motors` puts every register that decides motion back to the
course's values and says which it changed (``hw/servo_settings.py``).
Each move and hold starts from where the arm stands when it is elsewhere than
the last command (a goal written on ``bus.raw``): ``guarded.resync``.
"""

from __future__ import annotations

import atexit
import gc
import logging
import os
import sys
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from so101_kinematics.calibration import load_calibration
from so101_kinematics.errors import CalibrationError, PlanError, SO101Error
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.bus import (
    bus_errors,
    connect,
    disconnect,
    format_pose,
    release_torque,
    with_retries,
)
from so101_kinematics.hw.control import ArmSession
from so101_kinematics.hw.course_calibration import ScriptEnded, refuse
from so101_kinematics.hw.feedforward import read_feedforward, sag_allowance, torque_on_in_place
from so101_kinematics.hw.grip import held_grip
from so101_kinematics.hw.guarded import RAW_TICKS, GuardedBus, ramp_to_goal, resync
from so101_kinematics.hw.lead import VelocityLead
from so101_kinematics.hw.putdown import put_down
from so101_kinematics.hw.run import (
    LIMIT_SLACK_DEG,
    RELEASE_HINT,
    RunResult,
    after_abort,
    ending,
    finish,
    starting_pose,
)
from so101_kinematics.hw.servo_settings import configure_as_course
from so101_kinematics.hw.signals import signals_as_interrupt, stop_on_signals
from so101_kinematics.hw.timing import TimeSource
from so101_kinematics.inputs import (
    MISSING,
    Configuration,
    check_number,
    is_finite_number,
    move_arguments,
    radians_warning,
    start_mismatch,
)
from so101_kinematics.trims import Trims, as_trims

__all__ = [
    "AT_START_TOLERANCE_DEG", "_RUNS", "_end_forgotten_runs", "course_guarded_call",
    "course_hold_position", "course_logged_move", "course_move_to_pose", "course_trims",
    "end_arm", "end_at_start", "setup_motors",
]

logger = logging.getLogger("so101_utils")

# --- Settings ---------------------------------------------------------------
AT_START_TOLERANCE_DEG = 3.0  # an arm joint this close to its starting pose is "at the start"
MAX_MOVE_S = 60.0             # longest move_to_pose duration accepted [s]
MAX_HOLD_S = 3600.0           # longest hold_position duration accepted [s]


@dataclass
class CourseRun:
    """One arm set up by :func:`setup_motors`: its session, starting pose and how to release it."""

    session: ArmSession
    start: Configuration          # the model's angles (trims taken off) [deg], gripper [0, 100]
    release: str                  # the documented command that releases the torque by hand
    restore: ExitStack = field(default_factory=ExitStack)
    ended: str | None = None      # the run's last line, once it ended
    key: int = 0                  # id() of the bus handed out (its key in _RUNS)


_RUNS: dict[int, CourseRun] = {}  # id(bus handed out) -> its run, while set up and not ended
_PROCESS = ExitStack()  # signal handlers and the frozen heap, undone when the last run ends


def setup_motors(calibration: Mapping[str, Any], port: str,
                 offset_config: Mapping[str, float] | str | Path | Callable | None = None,
                 gravity_ff: bool = True, *, time_source: TimeSource | None = None):
    """Connect, configure and torque the arm where it stands; returns the lerobot bus.

    The port is taken for this program alone; the servos must hold this
    calibration; torque comes on with each goal set to the present position,
    so nothing moves. That pose is the starting pose every ending returns to.

    Args:
        calibration: from :func:`course_load_calibration` (or any lerobot calibration mapping).
        port: the arm's serial port (``lerobot-find-port``).
        offset_config: trims added to every goal ([deg] per joint; a dict, a trim
            file, or the course's ``offset_config(config)`` function); see
            ``so101_kinematics.trims``. Positions read back through the bus
            (``bus.sync_read``) are the servos' own, without the trims.
        gravity_ff: offset every goal by the sag the servos will have there (read from
            their P_Coefficient and Present_Voltage; ``so101_kinematics/hw/feedforward.py``),
            so the arm rests where it is sent; ``False``: the raw sag, as lerobot alone.
        time_source: the arm's time (the torque's ramp, every move and hold): None for the
            wall clock, or the virtual arm's simulated one (``arm.clock``, as ``run_on_arm``'s).

    Returns:
        A :class:`~so101_kinematics.hw.guarded.GuardedBus`: lerobot's bus whose
        ``Goal_Position`` writes are checked and ramped at the speed cap; lerobot's
        own bus, unguarded, is its ``raw`` attribute.

    Raises:
        ScriptEnded: refused before anything moved (one line, exit status 2).
    """
    try:
        trims = as_trims(offset_config)
        if not isinstance(calibration, Mapping):
            raise CalibrationError(f"setup_motors needs the calibration from load_calibration, "
                                   f"got {calibration!r}. Fix: calibration = "
                                   "load_calibration(ROBOT_NAME), then setup_motors(calibration, "
                                   "PORT_ID).")
        robot_id = getattr(calibration, "robot_id", None)
        checked = load_calibration(calibration, robot_id)
        bus = connect(port, checked, robot_id=robot_id)
    except SO101Error as error:
        raise refuse(error) from None
    ramp_time = {} if time_source is None else {"clock": time_source.clock,
                                                "sleep": time_source.sleep}
    armed = False
    try:
        start = trims.from_wire(starting_pose(bus, checked, port, robot_id))
        armed = True
        with bus_errors("configuring the servos and enabling torque"):
            configure_as_course(bus, "setup_motors")
            feedforward = read_feedforward(bus, gravity_ff)
            with_retries(lambda b: torque_on_in_place(b, feedforward, trims.to_wire(start),
                                                      **ramp_time), bus)
    except BaseException as error:
        if armed:  # torque may be on at the starting pose, nothing moved: release there
            release_torque(bus)
        disconnect(bus)
        if isinstance(error, SO101Error):
            raise refuse(error) from None
        raise
    source = getattr(calibration, "source", None)
    arm = f"--id {robot_id}" if robot_id else f"--calibration {source or 'YOUR_CALIBRATION.json'}"
    lead = VelocityLead.for_feedforward(feedforward, enabled=False)  # on per move, when asked
    loop_time = {} if time_source is None else {**ramp_time, "spin": time_source.spin}
    run = CourseRun(ArmSession(bus, trims=trims, feedforward=feedforward, velocity_lead=lead,
                               **loop_time), start, RELEASE_HINT.format(port=port, arm=arm))
    run.session.command = dict(start)
    run.session.rest_pose = dict(start)  # moves may come as low as where the arm stood
    run.restore.callback(_unlock_port, bus)  # a run that ended leaves the port to other programs
    original = bus.disable_torque

    def disable_torque(motors=None, num_retry: int = 0) -> None:
        """The course's last call: release at the starting pose (returning there first)."""
        if run.ended is None:
            end_at_start(run, "bus.disable_torque()")
        elif run.ended.endswith("torque off."):  # already released: lerobot's own call is harmless
            original(motors, num_retry=num_retry)
        else:  # the run ended holding away from the start (a fault): holding is safer
            logger.warning("Not releasing the torque away from the starting pose: %s", run.ended)

    bus.disable_torque = disable_torque  # lerobot's own disconnect() calls it too
    guarded = GuardedBus(bus, lambda values, what, normalize: course_write_goal(
        guarded, values, what, normalize), disable_torque,
        lambda line: course_refuse_write(guarded, line))
    run.key = id(guarded)
    if not _RUNS:  # the process's settings, while any arm is set up (two arms: until both end)
        _PROCESS.enter_context(signals_as_interrupt())  # SIGTERM/SIGHUP between calls: Ctrl-C
        gc.collect()
        gc.freeze()  # no 0.2 s full garbage collection in the middle of a move (hw/signals.py)
        _PROCESS.callback(gc.unfreeze)
    _RUNS[run.key] = run
    logger.info("Torque on, holding where the arm stands (%s); trims: %s.", format_pose(start),
                trims.describe())
    return guarded


def _unlock_port(bus) -> None:
    lock = getattr(bus, "so101_port_lock", None)
    if lock is not None:
        bus.so101_port_lock = None
        os.close(lock)


def _run_of(bus, what: str) -> CourseRun:
    run = _RUNS.get(id(bus))
    if run is None:
        raise refuse(PlanError(
            f"{what} needs the bus returned by setup_motors (set up and not ended). Fix: "
            "bus = setup_motors(calibration, PORT_ID) before moving the arm."))
    return run


def _guarded(bus, what: str, action: Callable[[ArmSession], None]) -> None:
    """Run ``action(session)``; on any fault, signal or exception end as the policy says."""
    run = _run_of(bus, what)
    session = run.session
    session.step = what
    try:
        with stop_on_signals(session):
            action(session)
    except (Exception, KeyboardInterrupt) as error:
        result = RunResult(dict(run.start))
        after_abort(session, error, run.start, True, result)
        finish(session, result)
        print(f"ABORTED: {what}: {result.aborted}.", file=sys.stderr)
        line = _end(run, result)
        raise ScriptEnded(1, line, result) from None


MOVE_SHAPES = ("move_to_pose(bus, desired_position, duration) or, with assignment 8's starting "
               "configuration, move_to_pose(bus, starting_position, desired_position, duration)")


def course_move_to_pose(bus, *args, desired_position=MISSING, duration=MISSING,
                        profile: str | None = None, what: str = "move_to_pose",
                        velocity_ff: bool = False) -> None:
    """Move to the target ([deg], gripper [0, 100]) in ``duration`` [s]; joints left out stay put.

    ``(bus, desired_position, duration)`` or assignment 8's ``(bus,
    starting_position, desired_position, duration)``: the move starts from the
    last goal either way (a starting position farther than
    ``checks.START_MISMATCH`` from it is named in a warning, never jumped to).
    A target within ``LIMIT_SLACK_DEG`` outside the calibrated range (a pose
    read back with ``bus.sync_read``) is clamped into it. ``profile`` is the
    move's time scaling (default the session's; ``move_to_pose_cubic`` passes
    "cubic"), ``what`` the name the messages use; ``velocity_ff`` leads each goal by
    the servo's lag times the planned velocity (``hw/lead.py``).
    """
    def move(session: ArmSession) -> None:
        start, cfg, seconds = move_arguments(
            args, {"desired_position": desired_position, "duration": duration},
            MOVE_SHAPES.replace("move_to_pose", what), "bus")
        seconds = check_number(seconds, f"{what} duration", 0.0, MAX_MOVE_S, "s")
        if not isinstance(cfg, Mapping):
            raise PlanError(f"{what} needs a configuration dict joint -> [deg], got "
                            f"{type(cfg).__name__}. Fix: e.g. {{'shoulder_pan': 0.0, ...}}.")
        resync(session)
        target = dict(session.command, **cfg)
        for joint in JOINTS:
            low, high = session.limits[joint]
            value = target.get(joint)
            if is_finite_number(value) and low - LIMIT_SLACK_DEG <= value <= high + LIMIT_SLACK_DEG:
                target[joint] = min(high, max(low, float(value)))
        warning = start_mismatch(start, session.command,
                                 sag_allowance(session.feedforward, session.command))
        if warning:
            logger.warning(warning)
        warning = radians_warning(cfg, session.command)
        if warning:
            logger.warning(warning)
        session.move(target, seconds, profile=profile, velocity_ff=velocity_ff)

    _guarded(bus, what, move)


def course_logged_move(bus, *args, desired_position=MISSING, duration=MISSING,
                       profile: str | None = None, velocity_ff: bool = False) -> list:
    """:func:`course_move_to_pose`, returning the move's control cycles (``timing.Cycle``)."""
    session = _run_of(bus, "move_to_pose_with_logging").session
    cycles, previous = [], session.on_cycle

    def record(arm: ArmSession, cycle) -> None:
        cycles.append(cycle)
        if previous is not None:
            previous(arm, cycle)

    session.on_cycle = record
    try:
        course_move_to_pose(bus, *args, desired_position=desired_position, duration=duration,
                            profile=profile, what="move_to_pose_with_logging",
                            velocity_ff=velocity_ff)
    finally:
        session.on_cycle = previous
    return cycles


def course_hold_position(bus, duration: float) -> None:
    """Hold the last commanded pose for ``duration`` [s], reading and checking the arm."""
    def hold(session: ArmSession) -> None:
        seconds = check_number(duration, "hold_position duration", 0.0, MAX_HOLD_S, "s")
        resync(session)
        session.hold(seconds)

    _guarded(bus, "hold_position", hold)


def course_write_goal(bus, values: Mapping[str, Any], what: str, normalize: bool = True) -> None:
    """A student's own ``Goal_Position`` write: checked, ramped there (``hw/guarded.py``)."""
    if not normalize:
        raise refuse(PlanError(f"{what} {RAW_TICKS}"), "Refused (this write; it moved nothing)")
    _guarded(bus, what, lambda session: ramp_to_goal(session, values, what))


def course_refuse_write(bus, line: str) -> None:
    """A register write refused (``hw/guarded.py``): the line, the ending at the start, exit 2.

    Nothing was written; the arm returns to its starting pose and is released there, as
    when a script ends, and the script ends with the refusal (exit status 2).
    """
    print(line, file=sys.stderr, flush=True)
    run = _RUNS.get(id(bus))
    if run is not None:
        end_at_start(run, "A refused write:")
    raise ScriptEnded(2, line)


def end_at_start(run: CourseRun, why: str) -> str:
    """The run's normal ending: back to the starting pose (slowly, if away), torque off there."""
    session = run.session
    session.step = "return_to_start"
    result = RunResult(dict(run.start))
    try:
        with stop_on_signals(session, freeze_at_once=True):
            pose = session.read_pose()
            away = [j for j in ARM_JOINTS if abs(pose[j] - run.start[j]) > AT_START_TOLERANCE_DEG]
            if away:
                logger.warning("%s away from the starting pose (%s): returning there slowly "
                               "before releasing the torque.", why, ", ".join(away))
                session.return_slowly(put_down(session, None, held_grip(session), None, run.start))
        result.returned_to_start = True
    except (Exception, KeyboardInterrupt) as error:
        after_abort(session, error, run.start, True, result)
    finish(session, result)
    return _end(run, result)


def end_arm(bus, why: str) -> str | None:
    """End the run of ``bus`` (:func:`setup_motors`'s) as :func:`end_at_start` does; its last line.

    One program driving two arms ends each this way (a fault on one ends the other too).
    None: that run has ended already (a fault's ending: its ``ScriptEnded.line``).
    """
    run = _RUNS.get(id(bus))
    return None if run is None else end_at_start(run, why)


def _end(run: CourseRun, result: RunResult) -> str:
    """Close the run and print its last line (where the arm is, whether it is torqued)."""
    _RUNS.pop(run.key, None)
    run.restore.close()
    if not _RUNS:
        _PROCESS.close()
    run.ended = ending(result, run.release)
    released = result.returned_to_start and result.torque_released
    print(run.ended, file=sys.stdout if released and result.aborted is None else sys.stderr,
          flush=True)
    return run.ended


@atexit.register
def _end_forgotten_runs() -> None:
    """A script that ends without ``bus.disable_torque()`` gets the same ending as with it."""
    for run in list(_RUNS.values()):
        end_at_start(run, "The script ended without bus.disable_torque():")


def course_trims() -> Trims:
    """The trims of the arm :func:`setup_motors` set up (its ``offset_config``); none before."""
    runs = [run for run in _RUNS.values() if run.ended is None]
    return runs[-1].session.trims if runs else Trims()


def course_guarded_call(bus, what: str, compute: Callable[[], Any]) -> Any:
    """``compute()`` under the fault policy: an error in it ends the script as one in a move."""
    out = []
    _guarded(bus, what, lambda session: out.append(compute()))
    return out[0]
