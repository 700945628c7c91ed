"""Moving the simulated arm: the course's ``move_to_pose`` and ``hold_position``.

``move_to_pose`` takes the course's ``(m, d, viewer, cfg, duration)`` and
assignment 8's suggested ``(m, d, viewer, starting_cfg, cfg, duration)``;
``hold_position`` takes both of the course's shapes: ``(m, d, viewer,
duration)`` (assignment 6) and ``(m, d, viewer, cfg, duration)`` (assignment 7,
the configuration before the duration); any other shape is a one-line
``CallShapeError`` naming the accepted ones.

Motion is timed on simulation time (``d.time``): a headless run
(``viewer=None``) is deterministic and runs as fast as the CPU allows; with a
viewer it is paced to real time, and when the window is closed the motion
stops and returns (every later call returns at once), so the course's
``while viewer.is_running():`` loop ends and the script exits normally; the
project's runners pass ``raise_if_closed=True`` to stop with ``ViewerClosed``.
The first time :func:`move_to_pose` or :func:`hold_position` sees MuJoCo's
passive viewer, they arrange for the interpreter to close it and wait for its
render thread at exit (``display.guard_viewer_exit``), so a script that leaves
its ``with mujoco.viewer.launch_passive(...)`` block right after a move exits
cleanly instead of crashing in MuJoCo's GLFW teardown.
A move or hold lasts at most ``motion.MAX_DURATION`` (600 s); its memory does
not grow with its duration (commands are computed ``COMMAND_BLOCK_STEPS``
physics steps at a time).
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Mapping

import mujoco
import numpy as np

from so101_kinematics import display
from so101_kinematics.errors import CallShapeError, ViewerClosed
from so101_kinematics.inputs import (
    MISSING,
    check_duration,
    describe_value,
    is_finite_number,
    move_arguments,
    radians_warning,
    start_mismatch,
)
from so101_kinematics.planning.motion import Trajectory
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import get_command, held_at_limits, joint_table, to_radians

__all__ = [
    "COMMAND_BLOCK_STEPS", "HOLD_SHAPES", "VIEWER_SYNC_PERIOD", "_guard_passive_viewer",
    "hold_position", "move_to_pose",
]

logger = logging.getLogger(__name__)

VIEWER_SYNC_PERIOD = 1.0 / 60.0  # [s] of simulation time between viewer updates
# Physics steps whose commands are computed at once (one numpy evaluation of
# the profile): a move's memory is this many rows, whatever its duration.
COMMAND_BLOCK_STEPS = 4096


def _guard_passive_viewer(viewer) -> None:
    """On first sight of MuJoCo's passive viewer, make the interpreter's exit wait for it."""
    passive = sys.modules.get("mujoco.viewer")
    if passive is not None and isinstance(viewer, passive.Handle):
        display.guard_viewer_exit(viewer)


def _advance(m, d, viewer, until: float, path: Trajectory | None, t0: float,
             velocity_actuators: np.ndarray | None = None) -> None:
    """Step the simulation to time ``until`` [s], following ``path`` if given.

    With ``velocity_actuators`` (a velocity model's ``<joint>_vel``, in ``path.goal``'s
    order) the path's velocity [rad/s] is fed forward to them, and set to 0 at the end.

    A move's commands are computed ``COMMAND_BLOCK_STEPS`` steps at a time
    (one numpy evaluation of the profile per block, so memory does not grow
    with the duration) and set before each physics step; a hold keeps the
    command, so the steps between two viewer updates run in one
    ``mj_step(m, d, n)`` call. Same physics as a per-step Python loop, with
    about 1 us of Python per step instead of about 10.
    """
    if viewer is not None:
        _guard_passive_viewer(viewer)
    realtime = viewer is not None and not getattr(viewer, "offscreen", False)
    every_step = viewer is not None and getattr(viewer, "sync_every_step", False)
    dt = m.opt.timestep
    n_steps = round((until - d.time) / dt)
    if n_steps <= 0:
        return
    block_start = block_stop = 0  # steps [block_start, block_stop) have their commands in rows
    if path is not None:
        # The unit conversion is affine per joint, so interpolating in radians
        # is the same path as interpolating in user units.
        actuators = positions = np.array([act for name, _, act, *_ in joint_table(m)
                                          if name in path.goal])
        start = np.array(list(to_radians(m, {j: path.start[j] for j in path.goal}).values()))
        delta = np.array(list(to_radians(m, path.goal).values())) - start
        if velocity_actuators is not None:
            actuators = np.concatenate([positions, velocity_actuators])
        elapsed0 = d.time - t0  # [s] at the start of the first step
        ctrl, step = d.ctrl, actuation.step
        if np.array_equal(actuators, np.arange(m.nu)):
            actuators = slice(None)  # all of them, in order: plain row copies
    wall0, sim0 = time.perf_counter(), d.time
    next_sync = d.time
    done = 0
    while done < n_steps:
        if viewer is None:
            chunk = min(n_steps - done, COMMAND_BLOCK_STEPS)
        elif every_step:
            chunk = 1
        else:
            chunk = max(1, min(n_steps - done, math.ceil((next_sync - d.time) / dt - 1e-6)))
        if path is None:
            actuation.step(m, d, chunk)
        else:
            if done >= block_stop:
                block_start, block_stop = done, min(done + COMMAND_BLOCK_STEPS, n_steps)
                elapsed = elapsed0 + dt * np.arange(block_start, block_stop)  # [s] per step
                rows = start + path.fractions(elapsed)[:, None] * delta  # [rad], one per step
                if velocity_actuators is not None:  # [rad/s] beside the goals
                    rows = np.hstack([rows, path.rates(elapsed)[:, None] * delta])
            chunk = min(chunk, block_stop - done)
            step(m, d, chunk, rows[done - block_start:done - block_start + chunk], actuators)
        done += chunk
        if viewer is None:
            continue
        if every_step or d.time >= next_sync - 1e-9:
            if not viewer.is_running():
                raise ViewerClosed("The viewer was closed.")
            viewer.sync()
            next_sync = d.time + VIEWER_SYNC_PERIOD
            if realtime:
                lag = (d.time - sim0) - (time.perf_counter() - wall0)
                if lag > 0:
                    time.sleep(lag)
    if path is not None:
        # The last step's command is the profile one step before the end; a move
        # ends commanding its goal exactly (a linear move would stay short of it).
        ctrl[positions] = start + delta
        if velocity_actuators is not None:
            ctrl[velocity_actuators] = 0.0


MOVE_SHAPES = ("move_to_pose(m, d, viewer, cfg, duration) or, with assignment 8's starting "
               "configuration, move_to_pose(m, d, viewer, starting_cfg, cfg, duration)")
"""The call shapes :func:`move_to_pose` accepts, as its error messages name them."""


def _viewer_closed(viewer) -> bool:
    """Whether a viewer was given and its window is closed (then a move or hold returns at once)."""
    return viewer is not None and not viewer.is_running()


def _run_until_closed(step, raise_if_closed: bool) -> None:
    """Run ``step()``; a closed viewer ends it quietly, or with ViewerClosed if asked."""
    try:
        step()
    except ViewerClosed:
        if raise_if_closed:
            raise
        logger.info("Viewer closed: the motion stopped.")


def move_to_pose(m: mujoco.MjModel, d: mujoco.MjData, viewer, *args,
                 cfg: Mapping[str, float] = MISSING, duration: float = MISSING,
                 profile: str = "minimum_jerk", raise_if_closed: bool = False,
                 velocity: bool | None = None) -> None:
    """Move from the current command to ``cfg`` in ``duration`` [s] of simulation time.

    ``move_to_pose(m, d, viewer, cfg, duration)``, or assignment 8's suggested
    improvement ``move_to_pose(m, d, viewer, starting_cfg, cfg, duration)``.
    The target is checked before the first step; a joint beyond the model's
    range is held at its limit with one warning line, as the course's utils
    and MuJoCo do (``scene.held_at_limits``; the real arm refuses it). When the
    viewer is closed the move stops and returns (at once if it was already
    closed), so the course's ``while viewer.is_running():`` loop ends. The path starts at the
    last command (not the measured pose), so a gripper squeezing an object
    keeps squeezing while the arm moves; that is what the course's starting
    configuration is for, so a ``starting_cfg`` within ``checks.START_MISMATCH``
    of the last command changes nothing, and one farther away is named in a
    warning (the move still starts from the last command: no jump).

    Args:
        m: the model.
        d: the simulation data.
        viewer: ``None`` (headless, as fast as possible), a passive viewer
            (paced to real time) or any object with ``sync()`` and
            ``is_running()`` (e.g. an offscreen recorder).
        *args: ``cfg, duration`` or ``starting_cfg, cfg, duration``.
        cfg: target configuration ([deg], gripper [0, 100]).
        duration: time for the move [s], in [0, ``MAX_DURATION``].
        profile: a name in ``profiles.PROFILES``: "minimum_jerk" (smooth, default),
            "linear" (the course's), "cubic" (assignment 9's), "quintic", "direct" (a step).
        velocity: feed the path's velocity to the model's ``<joint>_vel`` actuators
            (``model/scene_with_velocity.xml``); default: when the model has them.
        raise_if_closed: raise ViewerClosed when the viewer is closed (a
            plan runner stops that way) instead of returning.

    Raises:
        CallShapeError: any other shape of arguments.
        PlanError: a duration that is not a number in [0, MAX_DURATION] s, a
            joint missing or unknown, a value that is not a number; ``velocity=True``
            on a model without velocity actuators.
        ViewerClosed: the viewer window was closed, with ``raise_if_closed``.
    """
    start, cfg, duration = move_arguments(args, {"cfg": cfg, "duration": duration},
                                          MOVE_SHAPES, "m, d, viewer")
    goal = held_at_limits(m, cfg, "move_to_pose target")
    duration = check_duration(duration, "move_to_pose duration")
    command = get_command(m, d)
    for warning in (start_mismatch(start, command, actuation.expected_sag(m, command)),
                    radians_warning(cfg, command)):
        if warning:
            logger.warning(warning)
    path = Trajectory(command, goal, duration, profile)
    feed = actuation.velocity_actuators(m, velocity, list(goal))
    if _viewer_closed(viewer):
        if raise_if_closed:
            raise ViewerClosed("The viewer was closed.")
        return
    t0 = d.time
    _run_until_closed(lambda: _advance(m, d, viewer, t0 + path.duration, path, t0, feed),
                      raise_if_closed)


HOLD_SHAPES = ("hold_position(m, d, viewer, duration) (assignment 6) or "
               "hold_position(m, d, viewer, cfg, duration) (assignment 7)")
"""The call shapes :func:`hold_position` accepts, as its error messages name them."""



def _hold_arguments(args: tuple, cfg, duration) -> tuple[Mapping[str, float] | None, object]:
    """(cfg or None, duration) from either course shape; :class:`CallShapeError` for the rest."""
    fix = f"Fix: call {HOLD_SHAPES}."
    if len(args) > 2:
        raise CallShapeError(f"hold_position takes at most 5 arguments, got {3 + len(args)} "
                             f"(m, d, viewer and {describe_value(list(args))}). {fix}")
    names = ("cfg", "duration") if len(args) == 2 else (
        ("cfg",) if args and isinstance(args[0], Mapping) else ("duration",) if args else ())
    keywords = {"cfg": cfg, "duration": duration}
    for name, value in zip(names, args, strict=True):
        if keywords[name] is not MISSING:
            raise CallShapeError(f"hold_position got {name} both by position and by keyword. "
                                 f"{fix}")
        keywords[name] = value
    cfg, duration = keywords["cfg"], keywords["duration"]
    if isinstance(duration, Mapping):
        if cfg is not MISSING and not isinstance(cfg, Mapping):
            raise CallShapeError(f"hold_position got the duration ({describe_value(cfg)}) "
                                 "before the configuration; the configuration comes first. "
                                 "Fix: call hold_position(m, d, viewer, cfg, duration).")
        raise CallShapeError(f"hold_position got a configuration ({describe_value(duration)}) "
                             f"where the duration [s] belongs. {fix}")
    if duration is MISSING:
        what = "after the configuration " if cfg is not MISSING else ""
        raise CallShapeError(f"hold_position needs a duration [s] {what}(how long to hold). "
                             f"{fix}")
    if cfg is not MISSING and not isinstance(cfg, Mapping):
        raise CallShapeError(f"hold_position's configuration must be a dict joint name -> value "
                             f"([deg], gripper [0, 100]), got {describe_value(cfg)}. {fix}")
    return (None if cfg is MISSING else cfg), duration


def hold_position(m: mujoco.MjModel, d: mujoco.MjData, viewer, *args,
                  cfg: Mapping[str, float] = MISSING, duration: float = MISSING,
                  raise_if_closed: bool = False) -> None:
    """Hold for ``duration`` [s] of simulation time, commanding ``cfg`` first if it is given.

    Both of the course's shapes: ``hold_position(m, d, viewer, duration)``
    (assignment 6: keep the current command) and ``hold_position(m, d,
    viewer, cfg, duration)`` (assignment 7: command ``cfg``, then step for
    ``duration``); ``cfg`` and ``duration`` may also be given by keyword.
    Commanding ``cfg`` is a step command, as the course's is: after
    ``move_to_pose(..., cfg, ...)`` it is the command already there; joints
    missing from ``cfg`` keep their command.

    Args:
        m: the model.
        d: the simulation data.
        viewer: as for :func:`move_to_pose`.
        *args: ``duration`` or ``cfg, duration``.
        cfg: configuration to command ([deg], gripper [0, 100]), checked before
            any step; a joint beyond its range is held at its limit, with a warning.
        duration: [s], in [0, ``MAX_DURATION``].
        raise_if_closed: as for :func:`move_to_pose` (by default a closed
            viewer ends the hold: it returns).

    Raises:
        CallShapeError: any other shape (too many arguments, a dict where the
            duration belongs, no duration); the message names both shapes.
        PlanError: a duration that is not a number in [0, MAX_DURATION] s, an
            unknown joint or a value that is not a number in ``cfg``.
        ViewerClosed: the viewer window was closed, with ``raise_if_closed``.
    """
    if isinstance(viewer, Mapping) or is_finite_number(viewer):
        raise CallShapeError(f"hold_position's third argument is the viewer (None when "
                             f"headless), got {describe_value(viewer)}. Fix: call "
                             f"{HOLD_SHAPES}.")
    cfg, duration = _hold_arguments(args, cfg, duration)
    duration = check_duration(duration, "hold_position duration")
    if cfg is not None:
        angles = to_radians(m, held_at_limits(m, cfg, "hold_position configuration", True))
        for name, _, act, *_ in joint_table(m):
            if name in angles:
                d.ctrl[act] = angles[name]
    if _viewer_closed(viewer):
        if raise_if_closed:
            raise ViewerClosed("The viewer was closed.")
        return
    t0 = d.time
    _run_until_closed(lambda: _advance(m, d, viewer, t0 + duration, None, t0), raise_if_closed)
