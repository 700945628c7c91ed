"""Hands from the shell: the commands ``virtual_so101.py`` reads on its standard input.

One command a line; each is answered with one line on stdout, ``ok ...`` or
``error ...`` (a motion is answered when it has ended). The commands are a
dispatch table, :data:`COMMANDS`: a new one is a function registered with
:func:`command`::

    @command("where", "where", "the measured joint positions")
    def _where(arm, args):
        return format_pose(arm.joint_positions())

A handler gets the :class:`~so101_kinematics.virtual.arm.VirtualSO101` and the
words after the command's name, returns the text after ``ok`` and raises
:class:`ShellError` (or ValueError / KeyError / OSError) for an ``error`` line.

Moves are a hand's (``virtual/hand.py``): only the limp arm moves, within the
joint limits, never into the table; the hand keeps holding the arm where it
put it until ``limp``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import TextIO

from so101_kinematics.calibration import ServoCalibration, ticks_to_user
from so101_kinematics.frames import JOINT_LIMITS, JOINTS
from so101_kinematics.sensors.cube_wire import MAX_CUBES

__all__ = ["COMMANDS", "SWEEP_BASES", "UPRIGHT", "run_line", "serve"]

QUIT = "quit"
REACHED = 1.0  # [deg, gripper %] a hand move that ends further off has failed
MIDDLE_TICKS = 2047  # lerobot-calibrate's homing puts the range's middle here
UPRIGHT = {"shoulder_lift": -90.0, "elbow_flex": 0.0, "wrist_flex": 0.0}
"""The arm pointing up: every joint but shoulder_lift sweeps its whole range from here."""
SWEEP_BASES = {"shoulder_lift": {"elbow_flex": -90.0, "wrist_flex": -15.0, "gripper": 0.0}}
"""Where the other joints are held while a joint sweeps (default :data:`UPRIGHT`); from the
model: shoulder_lift's full sweep clears the table only with the elbow folded, the wrist
at -15 deg and the jaws closed (or the elbow at 75 and the wrist at 90)."""
DEMO = (
    {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
     "wrist_roll": 0.0, "gripper": 10.0},
    {"shoulder_pan": 30.0, "shoulder_lift": -60.0, "elbow_flex": 60.0, "wrist_flex": 45.0},
    {"shoulder_pan": 30.0, "shoulder_lift": -60.0, "elbow_flex": 60.0, "wrist_flex": 45.0},
    {"gripper": 60.0, "wrist_roll": 45.0},
    {"gripper": 60.0, "wrist_roll": 45.0},
    {"shoulder_pan": -30.0, "shoulder_lift": -40.0, "elbow_flex": 40.0, "wrist_flex": 60.0,
     "wrist_roll": -30.0},
    {"shoulder_pan": -30.0, "shoulder_lift": -40.0, "elbow_flex": 40.0, "wrist_flex": 60.0},
    {"gripper": 10.0, "wrist_roll": 0.0},
    {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0},
    {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0},
)
"""``demo``: what a hand does with a leader arm: moves with pauses, clear of the table."""


class ShellError(ValueError):
    """A command that cannot run: the message (one line) says why and what to type instead."""


@dataclass(frozen=True)
class Command:
    """One shell command: its handler, usage line and one-line summary."""

    handler: Callable[[object, list[str]], str]
    usage: str
    summary: str


COMMANDS: dict[str, Command] = {}
"""Command name -> :class:`Command`; extend with :func:`command`."""


def command(name: str, usage: str, summary: str) -> Callable:
    """Register the decorated ``handler(arm, args) -> str`` as the shell command ``name``."""
    def register(handler: Callable[[object, list[str]], str]) -> Callable:
        COMMANDS[name] = Command(handler, usage, summary)
        return handler
    return register


def run_line(arm, line: str) -> str:
    """Run one command line; return its answer (``ok ...`` / ``error ...``, one line)."""
    words = line.split()
    if not words:
        return "error empty line; type `help` for the commands"
    spec = COMMANDS.get(words[0])
    if spec is None:
        return f"error unknown command {words[0]!r}; commands: {', '.join(COMMANDS)}"
    try:
        text = spec.handler(arm, words[1:])
    except (ValueError, KeyError, OSError) as exc:
        # A KeyError's str() is its message's repr: take the message itself. Never strip
        # quotes off a message's ends: that unbalances the quotes inside it.
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        message = " ".join(str(message).split())
        return f"error {words[0]}: {message} (usage: {spec.usage})"
    return f"ok {text}".rstrip()


def serve(arm, lines: Iterable[str], out: TextIO) -> bool:
    """Answer each command of ``lines`` on ``out``; True when ``quit`` ended it, False at EOF."""
    for line in lines:
        if not line.strip():
            continue
        answer = run_line(arm, line)
        print(answer, file=out, flush=True)
        if answer == f"ok {QUIT}":
            return True
    return False


# --- helpers -------------------------------------------------------------------------------
def format_pose(cfg: Mapping[str, float]) -> str:
    """``shoulder_pan=1.2 ...`` ([deg], gripper [0, 100])."""
    return " ".join(f"{joint}={value:.2f}" for joint, value in cfg.items())


def parse_pose(args: list[str]) -> dict[str, float]:
    """``JOINT=DEG ...`` -> configuration; ShellError naming the bad word."""
    if not args:
        raise ShellError("no JOINT=DEG given")
    cfg = {}
    for word in args:
        joint, _, value = word.partition("=")
        if joint not in JOINT_LIMITS:
            raise ShellError(f"unknown joint {joint!r} in {word!r}; joints: {', '.join(JOINTS)}")
        try:
            cfg[joint] = float(value)
        except ValueError:
            raise ShellError(f"{word!r}: {value!r} is not a number") from None
        lo, hi = JOINT_LIMITS[joint]
        if not lo <= cfg[joint] <= hi:
            raise ShellError(f"{joint} = {cfg[joint]:g} is outside its limits [{lo:g}, {hi:g}]")
    return cfg


def move(arm, waypoints: list[Mapping[str, float]]) -> str:
    """The hand moves the arm through ``waypoints``; answers when done: where the arm is.

    Raises:
        ShellError: the arm did not get there (a servo took over, enabling torque).
    """
    arm.hand_move(waypoints)
    arm.hand_wait()
    where = arm.joint_positions()
    target = {joint: value for w in waypoints for joint, value in w.items()}
    missed = [f"{joint} at {where[joint]:.1f} (target {value:g})" for joint, value in target.items()
              if abs(where[joint] - value) > REACHED]
    if missed:
        raise ShellError(f"the arm did not get there: {', '.join(missed)}; a torqued servo holds "
                         "its joint (the host enabled torque?)")
    return format_pose(where)


def middle_pose(arm) -> dict[str, float]:
    """Each joint where its calibrated range's middle is (Present_Position 2047)."""
    return {joint: ticks_to_user(joint, MIDDLE_TICKS, ServoCalibration(**cal))
            for joint, cal in arm.calibration.items()}


# --- the commands --------------------------------------------------------------------------
@command("pose", "pose JOINT=DEG ...", "a hand moves the named joints there (gripper: 0-100)")
def _pose(arm, args):
    return move(arm, [parse_pose(args)])


@command("sweep", "sweep [JOINT ...]",
         "each joint (default all) through its full range and back, one at a time")
def _sweep(arm, args):
    joints = args or list(JOINTS)
    unknown = [j for j in joints if j not in JOINT_LIMITS]
    if unknown:
        raise ShellError(f"unknown joints {unknown}; joints: {', '.join(JOINTS)}")
    waypoints = [UPRIGHT]
    for joint in joints:
        base = dict(UPRIGHT, **SWEEP_BASES.get(joint, {}))
        lo, hi = JOINT_LIMITS[joint]
        waypoints += [base, {joint: lo}, {joint: hi}, {joint: base.get(joint, (lo + hi) / 2)}]
    waypoints.append(UPRIGHT)
    return move(arm, waypoints)


@command("middle", "middle", "every joint to the middle of its range (lerobot-calibrate)")
def _middle(arm, args):
    if args:
        raise ShellError("middle takes no arguments")
    target = middle_pose(arm)
    try:
        return move(arm, [target])
    except ValueError:  # the straight way goes into the table: up first
        return move(arm, [UPRIGHT, target])


@command("play", "play FILE", "the hand replays a waypoint file (the project's plan format)")
def _play(arm, args):
    from so101_kinematics.planning.plans import load_plan

    if len(args) != 1:
        raise ShellError("give one plan file")
    plan = load_plan(args[0])
    return move(arm, [step.configuration for step in plan.steps])


@command("demo", "demo", "the hand moves the arm around (a built-in tour, about 15 s)")
def _demo(arm, args):
    return move(arm, list(DEMO))


@command("where", "where", "the measured joint positions ([deg], gripper 0-100)")
def _where(arm, args):
    return format_pose(arm.joint_positions())


@command("limp", "limp", "torque off on every servo and the hand lets go")
def _limp(arm, args):
    arm.set_torque(False)
    arm.hand_release()
    return "limp"


@command("plug", "plug", "factory mode: plug the next servo into the bus")
def _plug(arm, args):
    return f"plugged {arm.plug()}"


@command("supply", "supply VOLTS", "set the servos' supply voltage [V]")
def _supply(arm, args):
    if len(args) != 1:
        raise ShellError("give the voltage, e.g. supply 12")
    volts = float(args[0])
    if not 0.0 <= volts <= 25.0:
        raise ShellError(f"{volts:g} V is outside 0..25 V")
    arm.set_supply(volts)
    return f"supply {volts:g} V"


@command("help", "help", "list the commands")
def _help(arm, args):
    return "; ".join(f"{spec.usage}: {spec.summary}" for spec in COMMANDS.values())


@command("cube", "cube [X Y [YAW]]",
         "where the cube is (centre [m], tilt [deg], held or free; then any other cubes); with "
         "X Y [m] and YAW [deg], put it there on the table first, as a hand would")
def _cube(arm, args):
    if args:
        if len(args) not in (2, 3):
            raise ShellError(f"cube takes X Y [YAW], got {' '.join(args)!r}")
        try:
            values = [float(a) for a in args]
        except ValueError:
            raise ShellError(f"{' '.join(args)!r}: X Y [YAW] must be numbers") from None
        arm.place_cube(*values)
    reading = arm.cube()
    if reading is None:
        return "nocube"
    readings = [reading]
    while len(readings) < MAX_CUBES and (more := arm.cube(len(readings))) is not None:
        readings.append(more)  # the others of a stacking table, on the same line
    return " | ".join(
        f"{'cube' if i == 0 else f'cube_{i + 1}'} {r.position_m[0]:.4f} {r.position_m[1]:.4f} "
        f"{r.position_m[2]:.4f} tilt {r.tilt_deg:.1f} " + ("held" if r.held else "free")
        for i, r in enumerate(readings))


@command("nocube", "nocube", "take the cube off the table")
def _nocube(arm, args):
    arm.remove_cube()
    return "nocube"


@command(QUIT, QUIT, "stop the virtual arm")
def _quit(arm, args):
    return QUIT
