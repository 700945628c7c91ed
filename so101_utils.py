"""Hardware helpers for the SO-101 follower, with the course's names: load, set up, move, hold.

Assignment 8 runs its inverse kinematics on the real arm with four helpers::

    from so101_utils import load_calibration, move_to_pose, hold_position, setup_motors

    calibration = load_calibration("follower-1")          # the id given to lerobot-calibrate
    bus = setup_motors(calibration, "/dev/ttyACM0")       # torque on, holding where it stands
    starting_pose = bus.sync_read("Present_Position")
    move_to_pose(bus, desired_configuration, 2.0)         # [deg], gripper 0-100; [s]
    hold_position(bus, 10.0)                              # [s]
    move_to_pose(bus, starting_pose, 2.0)
    bus.disable_torque()                                  # released at the starting pose

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.

The same control loop, speed caps, checks and endings as ``pick_place_hw.py`` run under these
helpers, so docs/hardware_safety.md's fault policy holds in a student's script: a fault, a
signal or an exception returns the arm slowly to the pose it had at ``setup_motors`` and
releases it there (``bus.disable_torque()`` too); the last line says where the arm is and
whether it is torqued; bad input before anything moved is one line, exit status 2.

Also here: ``offset_config`` (the course's trims, at most 5 deg per joint), assignment 8's
``pick_up_block`` / ``place_block``, assignment 9's ``move_to_pose_cubic`` (the course's
cubic; ``velocity_ff=True`` feeds its velocity through the goal) and week 8's
``move_to_pose_with_logging`` (the course's DataFrame) with ``plot_data(df)``.
"""

from __future__ import annotations

import math

from so101_kinematics.hw.course_calibration import course_load_calibration
from so101_kinematics.hw.course_helpers import (
    course_guarded_call,
    course_hold_position,
    course_logged_move,
    course_move_to_pose,
    course_trims,
)
from so101_kinematics.hw.course_helpers import setup_motors as _setup_motors
from so101_kinematics.ik.blocks import pick_up_moves, place_moves
from so101_kinematics.inputs import MISSING, check_configuration
from so101_kinematics.planning.trajectory_log import (
    logging_frame,
    plot_data,  # noqa: F401 - week 8's plot
    require_pandas,
)


def load_calibration(robot_name_or_path):
    """The arm's lerobot calibration, by robot id or from a calibration JSON file.

    Args:
        robot_name_or_path: the ``--robot.id`` given to ``lerobot-calibrate``
            (looked up where lerobot keeps calibrations:
            ``$HF_LEROBOT_CALIBRATION/robots/so_follower/ID.json``), or the path of a
            calibration JSON file.

    Returns:
        joint name -> calibration (servo id, drive mode, homing offset, range [ticks]).
    """
    return course_load_calibration(robot_name_or_path)


def setup_motors(calibration, port, offset_config=None, gravity_ff=True):
    """Connect to the arm and turn torque on where it stands; returns the lerobot bus.

    Nothing moves: each servo's goal is set to its present position before
    torque comes on. That pose is where every ending returns the arm.

    Args:
        calibration: from :func:`load_calibration`.
        port: the arm's serial port (``lerobot-find-port`` tells which).
        offset_config: optional trims, joint -> [deg] added to every goal (a
            dict, a JSON/TOML trim file, or an ``offset_config(config)`` function).
        gravity_ff: offset each goal by the sag gravity causes at P = 16 (default
            on; ``False`` shows the raw sag). See docs/servo.md.

    Returns:
        lerobot's ``FeetechMotorsBus``, connected, arm joints in [deg], gripper 0-100,
        guarded: a ``bus.sync_write("Goal_Position", ...)`` is checked and ramped at the
        speed cap, ``Torque_Enable`` 0 is ``bus.disable_torque()``, and a write that could
        drop, spin or weaken the arm (Torque_Limit, P, Operating_Mode, Goal_Velocity, ...)
        is refused in one line (``so101_kinematics/hw/guarded.py``); the bare bus is
        ``bus.raw``. Registers an earlier program left are put back to the course's values
        (``so101_kinematics/hw/servo_settings.py``), each change named in a warning.
    """
    return _setup_motors(calibration, port, offset_config, gravity_ff)


def move_to_pose(bus, *args, desired_position=MISSING, duration=MISSING, velocity_ff=False):
    """Move the arm smoothly to ``desired_position`` in ``duration`` seconds.

    ``move_to_pose(bus, desired_position, duration)``, or assignment 8's
    suggested improvement ``move_to_pose(bus, starting_position,
    desired_position, duration)``. Each move starts from the previous move's
    target (the goal the servos hold), which is what that improvement is for;
    a ``starting_position`` more than 3 deg (``START_MISMATCH``) from it is
    named in a warning and never jumped to.

    Args:
        bus: from :func:`setup_motors`.
        *args: ``desired_position, duration`` or ``starting_position,
            desired_position, duration`` (``starting_position``: where the move
            is meant to start, joint name -> [deg]).
        desired_position: joint name -> [deg] (gripper 0-100); joints left out
            keep their goal.
        duration: [s]; stretched (with a warning) if a joint would exceed its
            speed cap.
        velocity_ff: the week-9 workaround for a velocity on the real arm: each goal
            sent leads the plan by the servo's lag (0.1 s at P = 16 on 5 V) times the
            planned velocity, at most 10 deg, never past the move's goal
            (``so101_kinematics/hw/lead.py``; docs/trajectories.md, "Velocity on the real arm").
    """
    course_move_to_pose(bus, *args, desired_position=desired_position, duration=duration,
                        velocity_ff=velocity_ff)


def move_to_pose_cubic(bus, *args, desired_position=MISSING, duration=MISSING,
                       velocity_ff=False):
    """Move as :func:`move_to_pose` does, along the course's cubic (assignment 9).

    Per joint ``q(t) = a0 + a1 t + a2 t^2 + a3 t^3`` with ``a0`` the start,
    ``a1 = 0``, ``a2 = 3 (qf - q0) / T^2``, ``a3 = -2 (qf - q0) / T^3`` (zero
    velocity at both ends), ``t`` clipped to ``[0, duration]``
    (``so101_kinematics/planning/profiles.py``). Same shapes, checks, speed cap (its
    peak is 1.5 times the mean speed) and fault policy as :func:`move_to_pose`:
    ``move_to_pose_cubic(bus, desired_position, duration)`` or
    ``move_to_pose_cubic(bus, starting_position, desired_position, duration)``.
    ``velocity_ff=True`` feeds the cubic's velocity ``a1 + 2 a2 t + 3 a3 t^2`` forward
    through the goal, as :func:`move_to_pose`'s does.
    """
    course_move_to_pose(bus, *args, desired_position=desired_position, duration=duration,
                        profile="cubic", what="move_to_pose_cubic", velocity_ff=velocity_ff)


def move_to_pose_with_logging(bus, *args, desired_position=MISSING, duration=MISSING,
                              profile="linear", velocity_ff=False):
    """Week 8's logged move: as :func:`move_to_pose`, returning the course's DataFrame.

    ``move_to_pose_with_logging(bus, desired_position, duration)`` or with the
    starting position first; one row per control cycle (100 Hz): ``time`` [s] from
    the move's start, ``target_<joint>`` (the goal commanded) and ``actual_<joint>``
    (``Present_Position``), [deg], gripper 0-100. ``profile``: "linear" (the
    course's), "cubic", "quintic" or "minimum_jerk"; ``velocity_ff`` as for
    :func:`move_to_pose` (``target_`` stays the plan). Needs pandas (the hw extra has it).
    """
    require_pandas()
    cycles = course_logged_move(bus, *args, desired_position=desired_position,
                                duration=duration, profile=profile, velocity_ff=velocity_ff)
    t0 = cycles[0].t_s if cycles else 0.0
    return logging_frame([c.t_s - t0 for c in cycles], [c.command for c in cycles],
                         [c.measured for c in cycles])


def hold_position(bus, duration):
    """Hold the last commanded pose for ``duration`` seconds, watching the arm.

    Args:
        bus: from :func:`setup_motors`.
        duration: [s].
    """
    course_hold_position(bus, duration)


def offset_config(config):
    """The course's trims helper: ``config`` with each joint's trim added ([deg], gripper [%]).

    The trims are those given to :func:`setup_motors` as ``offset_config``
    (none before it, or without them). ``move_to_pose`` adds them itself: call
    this only for a goal written to the bus by hand.

    Args:
        config: joint name -> value ([deg], gripper 0-100); any subset of the joints.

    Returns:
        A new dict, the same joints, each plus its trim.
    """
    values = check_configuration(config, dict.fromkeys(config, (-math.inf, math.inf)),
                                 "offset_config")
    return course_trims().to_wire(values)


def pick_up_block(bus, block_position, move_to_duration):
    """Assignment 8's pick: 3 cm above the block gripper open (50), down, close (5), lift.

    Args:
        bus: from :func:`setup_motors`.
        block_position: the block's centre (x, y, z) [m].
        move_to_duration: [s] of the first move, to above the block; the others take 1 s.

    Returns:
        The bus (as the course's helper does).
    """
    moves = course_guarded_call(bus, "pick_up_block",
                                lambda: pick_up_moves(block_position, move_to_duration))
    for cfg, duration in moves:
        move_to_pose(bus, cfg, duration)
    return bus


def place_block(bus, target_position, move_to_duration):
    """Assignment 8's place: 3 cm above the target gripper closed (5), down, open (50), back up.

    Args:
        bus: from :func:`setup_motors`.
        target_position: where the block's centre goes (x, y, z) [m].
        move_to_duration: [s] of the first move, to above the target; the others take 1 s.

    Returns:
        The bus.
    """
    moves = course_guarded_call(bus, "place_block",
                                lambda: place_moves(target_position, move_to_duration))
    for cfg, duration in moves:
        move_to_pose(bus, cfg, duration)
    return bus
