"""The course's pick-and-place plan, and plans read from waypoint files (JSON or TOML).

The six configurations of the assignment and the waypoints around them
(:func:`default_plan`, :func:`pick_and_place_plan`), checked against joint
limits and durations (:func:`validate_plan`), or loaded from a file
(:func:`load_plan`: UTF-8, a BOM tolerated, every field checked).
"""

from __future__ import annotations

import difflib
import json
import math
import sys
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from so101_kinematics.clearance import check_plan_clearance
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINTS
from so101_kinematics.inputs import (
    RADIANS_BOUND,
    Limits,
    check_configuration,
    check_duration,
    describe_value,
    looks_like_radians,
)
from so101_kinematics.planning.motion import Plan, Step

__all__ = [
    "FINAL_CONFIGURATION", "GRIPPER_CLOSED", "STARTING_CONFIGURATION", "data_kind",
    "default_plan", "load_plan", "parse_data", "pick_and_place_plan", "pick_and_place_steps",
    "read_text_file", "validate_plan",
]

# The course's pick-and-place. The six configurations of the assignment are
# start_open, start_closed, lift, carry, final_closed and final_open; the first
# and last two are the course's, lift and carry (ours) raise the cube 11.6 cm
# clear of the table. Four extra waypoints (approach, pre_grasp, retreat,
# depart) make the grasp robust and leave the placed cube alone; they are
# moves of the arm only, the jaws stay open.
STARTING_CONFIGURATION = {
    "shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0,
    "wrist_flex": 90.0, "wrist_roll": 0.0, "gripper": 50.0,
}
FINAL_CONFIGURATION = dict(STARTING_CONFIGURATION, shoulder_pan=45.0)
GRIPPER_CLOSED = 5.0

# Why the approach: the fixed jaw is the jaw nearer the base, its flat inner
# face flush with the near face of a cube standing at the FK start position.
# Coming straight down, a cube 5 mm nearer the base (or turned 10 deg about z,
# its corner then sticks out 2 mm) would be hit by the fixed jaw's tip. So the
# open gripper comes down 12 mm nearer the base (pre_grasp: gripper vertical,
# same height as start_open) and then slides out to start_open: the fixed
# jaw's flat face pushes a misplaced cube to where the grasp expects it. A
# cube further out is pushed back by the closing moving jaw. The numbers are
# FK-derived (so101_forward_kinematics), rounded to whole degrees:
#   approach:  object frame 15 mm nearer the base and 52 mm up, tilted 5 deg;
#   pre_grasp: 12 mm nearer the base, gripper vertical, same height;
#   lift/carry: 116 mm up (the cube's bottom 11.6 cm above the table), tilted 25 deg;
#   retreat:   pre_grasp at the final pan: the fixed jaw backs off the placed
#              cube horizontally;
#   depart:    approach at the final pan: the open gripper rises clear of the
#              cube before the arm returns to its initial pose (a joint-space
#              return straight from retreat can sweep a jaw through a cube
#              placed near the base).
APPROACH = {"shoulder_lift": 24.0, "elbow_flex": -32.0, "wrist_flex": 93.0}
PRE_GRASP = {"shoulder_lift": 35.0, "elbow_flex": -28.0, "wrist_flex": 83.0}
LIFT = {"shoulder_lift": 0.0, "elbow_flex": -20.0, "wrist_flex": 85.0}
PICK_STEP = "start_open"
"""Name of the default plan's step whose FK is where the cube stands."""
PLACE_STEP = "final_open"
"""Name of the default plan's step whose FK is where the cube is placed."""


def default_plan(move_duration: float = 2.0, hold_duration: float = 0.5) -> Plan:
    """The course's pick-and-place plan.

    Args:
        move_duration: time for each main move [s]; the short approach,
            sweep, grip, release, retreat and depart moves take half of it.
        hold_duration: pause after each of the six course configurations [s].

    Returns:
        The plan: approach, pre_grasp, then the course's six configurations
        (start_open, start_closed, lift, carry, final_closed, final_open),
        retreat, depart, then back to the initial pose.
    """
    start, final = STARTING_CONFIGURATION, FINAL_CONFIGURATION
    return pick_and_place_plan(
        approach=dict(start, **APPROACH), pre_grasp=dict(start, **PRE_GRASP), grasp=start,
        lift=dict(start, **LIFT), carry=dict(final, **LIFT), release=final,
        retreat=dict(final, **PRE_GRASP), depart=dict(final, **APPROACH),
        move_duration=move_duration, hold_duration=hold_duration)


def pick_and_place_plan(
    approach: Mapping[str, float],
    pre_grasp: Mapping[str, float],
    grasp: Mapping[str, float],
    lift: Mapping[str, float],
    carry: Mapping[str, float],
    release: Mapping[str, float],
    retreat: Mapping[str, float],
    depart: Mapping[str, float],
    move_duration: float = 2.0,
    hold_duration: float = 0.5,
) -> Plan:
    """Assemble the pick-and-place's ten steps from its key configurations.

    The one place that fixes the waypoints' names, order, gripper states and
    timing, for the joint-space plan (:func:`default_plan`) and the Cartesian
    one (``so101_kinematics.planning.cartesian_plan``) alike.

    Args:
        approach: the open gripper above the cube.
        pre_grasp: the open gripper beside the cube, at grasp height.
        grasp: the open gripper around the cube (start_open); it then closes there.
        lift: the cube held above the pick position (gripper set to ``GRIPPER_CLOSED``).
        carry: the cube held above the place position (gripper set likewise).
        release: the open gripper at the place position (final_open).
        retreat: the open gripper backed off the placed cube.
        depart: the open gripper raised clear of the placed cube.
        move_duration: time for each main move [s]; the short moves near the
            cube take half of it.
        hold_duration: pause after each of the course's six configurations [s].

    Returns:
        The plan: approach, pre_grasp, start_open, start_closed, lift, carry,
        final_closed, final_open, retreat, depart; then back to the initial pose.
    """
    move_duration = check_duration(move_duration, "move_duration")
    hold_duration = check_duration(hold_duration, "hold_duration")
    closed = {"gripper": GRIPPER_CLOSED}
    short = 0.5 * move_duration
    waypoints = [
        ("approach", approach, move_duration, 0.0),
        ("pre_grasp", pre_grasp, short, 0.0),
        ("start_open", grasp, short, hold_duration),
        ("start_closed", dict(grasp, **closed), short, hold_duration),
        ("lift", dict(lift, **closed), move_duration, hold_duration),
        ("carry", dict(carry, **closed), move_duration, hold_duration),
        ("final_closed", dict(release, **closed), move_duration, hold_duration),
        ("final_open", release, short, hold_duration),
        ("retreat", retreat, short, 0.0),
        ("depart", depart, short, 0.0),
    ]
    return Plan([Step(name, dict(cfg), duration, hold)
                 for name, cfg, duration, hold in waypoints], return_duration=move_duration)


def pick_and_place_steps(plan: Plan) -> tuple[Step, Step]:
    """The steps at which the cube is picked and placed.

    Args:
        plan: a plan.

    Returns:
        (pick, place): the steps named ``PICK_STEP`` and ``PLACE_STEP`` if the
        plan has them; else the first step whose name ends in ``_PICK_STEP`` and
        the last ending in ``_PLACE_STEP`` (a stacking plan's first pick and top
        placement, ``block1_start_open`` ... ``blockN_final_open``); else its
        first and last steps.
    """
    by_name = {step.name: step for step in plan.steps}
    picks = [s for s in plan.steps if s.name.endswith("_" + PICK_STEP)]
    places = [s for s in plan.steps if s.name.endswith("_" + PLACE_STEP)]
    return (by_name.get(PICK_STEP, picks[0] if picks else plan.steps[0]),
            by_name.get(PLACE_STEP, places[-1] if places else plan.steps[-1]))


def validate_plan(plan: Plan, limits: Limits, source: str = "",
                  base_height: float = 0.0) -> Plan:
    """Check every step before anything moves.

    Args:
        plan: the plan.
        limits: joint name -> (lower, upper) [deg] (gripper [0, 100]).
        source: where the plan came from, for messages (e.g. the file).
        base_height: the table is this far below the base frame [m]: the path from
            the first waypoint on stays clear of it (``clearance.check_plan_clearance``).

    Returns:
        The same plan with configurations and durations normalised to floats.

    Raises:
        PlanError: empty plan, duplicate names, bad durations (each in
            [0, ``MAX_DURATION``] s), a ``return_to_start`` that is not a
            boolean, or bad configurations; ClearanceError: the path goes into the table.
    """
    prefix = f"{source}, " if source else ""
    check_plan_settings(plan, source)
    for i, step in enumerate(plan.steps):
        where = f"{prefix}waypoint {i + 1} '{step.name}'"
        step.configuration = check_configuration(step.configuration, limits, where)
    check_plan_clearance(plan, base_height=base_height, where=source)
    return plan


def check_plan_settings(plan: Plan, source: str = "") -> Plan:
    """Check a plan's structure, names and durations (everything but the joint limits).

    Args:
        plan: the plan.
        source: where the plan came from, for messages.

    Returns:
        The same plan, durations as floats.

    Raises:
        PlanError: naming the waypoint and the field.
    """
    prefix = f"{source}, " if source else ""
    if not plan.steps:
        raise PlanError(f"{prefix}the plan has no steps. Fix: give at least one waypoint.")
    seen = set()
    for i, step in enumerate(plan.steps):
        if not isinstance(step.name, str) or not step.name:
            raise PlanError(f"{prefix}waypoint {i + 1}: name must be non-empty text, got "
                            f"{describe_value(step.name)}. Fix: give it a name in quotes.")
        if not step.name.isprintable():  # every message names the waypoint on one line
            raise PlanError(f"{prefix}waypoint {i + 1}: the name {step.name!r} holds a line "
                            "break or another control character. Fix: give it a one-line name.")
        where = f"{prefix}waypoint {i + 1} '{step.name}'"
        if step.name in seen:
            raise PlanError(f"{where}: the name is used twice. Fix: give each waypoint its own "
                            "name.")
        seen.add(step.name)
        if not isinstance(step.configuration, Mapping):
            raise PlanError(f"{where}: configuration must be a table of joint values, got "
                            f"{describe_value(step.configuration)}.")
        step.duration = check_duration(step.duration, f"{where}: duration")
        step.hold = check_duration(step.hold, f"{where}: hold")
    if not isinstance(plan.return_to_start, (bool, np.bool_)):
        raise PlanError(f"{prefix}return_to_start must be true or false, got "
                        f"{describe_value(plan.return_to_start)}. Fix: write true or false "
                        "without quotes.")
    plan.return_to_start = bool(plan.return_to_start)
    plan.return_duration = check_duration(plan.return_duration, f"{prefix}return_duration")
    return plan


STEP_KEYS = ("name", "configuration", "duration", "hold")
"""Keys of a waypoint in a plan file."""

PLAN_KEYS = ("steps", "return_to_start", "return_duration")
"""Top-level keys of a plan file."""


def data_kind(path: Path) -> str:
    """"TOML" for a ``.toml`` file, else "JSON": how waypoint and trim files are read."""
    return "TOML" if path.suffix.lower() == ".toml" else "JSON"


def parse_data(text: str, kind: str):
    """``text`` parsed as ``kind`` ("JSON" or "TOML").

    Raises:
        ValueError: not valid (JSONDecodeError and TOMLDecodeError are ValueErrors).
        RecursionError: nested too deeply.
    """
    if kind == "JSON":
        return json.loads(text)
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    return tomllib.loads(text)


def read_text_file(path: str | Path, what: str, error: type[Exception] = PlanError) -> str:
    """The text of a UTF-8 file (a byte-order mark is tolerated).

    Args:
        path: the file.
        what: what the file is, for messages, e.g. "Waypoint file".
        error: the exception class to raise.

    Raises:
        error: the file cannot be read, or is not UTF-8 text (the message
            names the file and says to save it as UTF-8).
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as problem:
        raise error(f"Cannot read {what.lower()} '{path}': {problem.strerror}. Fix: check the "
                    "path.") from None
    except ValueError as problem:  # e.g. an embedded NUL character
        raise error(f"Cannot read {what.lower()} '{path}': {problem}. Fix: check the "
                    "path.") from None
    if data.startswith((b"\xff\xfe", b"\xfe\xff")) and _is_text(data, "utf-16"):
        raise error(f"{what} '{path}' is UTF-16 text, not UTF-8. Fix: save it as UTF-8.")
    if b"\x00" in data or data.startswith((b"\xff\xfe", b"\xfe\xff")):
        at = data.find(b"\x00")
        raise error(f"{what} '{path}' is not text but binary data (" + (
            f"a NUL byte at {at}" if at >= 0 else "its bytes decode to no text")
            + f"). Fix: give the {what.lower()} itself (.json or .toml text), not another file.")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as problem:
        raise error(f"{what} '{path}' is not UTF-8 text (byte {problem.start} is "
                    f"0x{data[problem.start]:02x}). Fix: save it as UTF-8.") from None


def _is_text(data: bytes, encoding: str) -> bool:
    """Whether ``data`` decodes in ``encoding`` to printable text (tabs and newlines too)."""
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError:
        return False
    return all(c.isprintable() or c in "\t\r\n\ufeff" for c in text)


def load_plan(path: str | Path, limits: Limits | None = None) -> Plan:
    """Read a plan from a JSON or TOML waypoint file.

    The file is UTF-8 (a byte-order mark is tolerated) and holds ``steps``: a
    list of tables with ``name`` (text), ``configuration`` (all six joints,
    [deg], gripper [0, 100]) and optional ``duration`` and ``hold`` [s] (each
    in [0, ``MAX_DURATION``]); optionally ``return_to_start`` (true or
    false) and ``return_duration`` [s].

    Args:
        path: a ``.json`` or ``.toml`` file.
        limits: if given, the configurations are checked against them too.

    Returns:
        The plan; its structure, names and durations are checked.

    Raises:
        PlanError: unreadable file, wrong structure or a bad value, naming the
            file, the waypoint, the field and the fix.
    """
    path = Path(path)
    text = read_text_file(path, "Waypoint file")
    kind = data_kind(path)
    try:
        data = parse_data(text, kind)
    except RecursionError:
        raise PlanError(f"Waypoint file '{path}' is nested too deeply to be a plan. Fix: see "
                        "waypoints/example.json for the layout.") from None
    except ValueError as error:  # JSONDecodeError and TOMLDecodeError are ValueErrors
        message = str(error).replace("\n", " ")
        raise PlanError(f"Waypoint file '{path}' is not valid {kind}: {message}. Fix: correct "
                        "the syntax there.") from None
    if not isinstance(data, dict) or not isinstance(data.get("steps"), list):
        raise PlanError(f"Waypoint file '{path}' must contain a list 'steps' of waypoints. "
                        "Fix: see waypoints/example.json for the layout.")
    _refuse_unknown_keys(data, PLAN_KEYS, f"Waypoint file '{path}'")
    steps = []
    for i, raw in enumerate(data["steps"]):
        where = f"'{path}', waypoint {i + 1}"
        if not isinstance(raw, dict) or not isinstance(raw.get("configuration"), dict):
            raise PlanError(_configuration_problem(raw, where))
        _refuse_unknown_keys(raw, STEP_KEYS, where)
        steps.append(Step(raw.get("name", f"waypoint_{i + 1}"), dict(raw["configuration"]),
                          raw.get("duration", 2.0), raw.get("hold", 0.5)))
    plan = Plan(steps, data.get("return_to_start", True), data.get("return_duration", 2.0))
    if steps and all(looks_like_radians(step.configuration) for step in steps):
        raise PlanError(f"Waypoint file '{path}': every arm angle of every waypoint is within "
                        f"+-{RADIANS_BOUND:g}: these are radians, but a plan's angles are "
                        "degrees (the arm would go to almost 0 deg on every joint). Fix: "
                        "multiply each angle by 180/pi (math.degrees).")
    if limits is not None:
        validate_plan(plan, limits, f"'{path}'")
    else:
        check_plan_settings(plan, f"'{path}'")
        for i, step in enumerate(plan.steps):  # numbers only; the limits come later
            check_configuration(step.configuration, {j: (-math.inf, math.inf) for j in JOINTS},
                                f"'{path}', waypoint {i + 1} '{step.name}'")
    return plan


def _configuration_problem(raw, where: str) -> str:
    """Why waypoint ``raw`` has no configuration table, in one line with the fix."""
    layout = "Fix: see waypoints/example.json."
    if not isinstance(raw, dict):
        return (f"{where}: a waypoint is a table (name, configuration, duration, hold), got "
                f"{describe_value(raw)}. {layout}")
    if "configuration" not in raw:
        return f"{where}: each waypoint needs a 'configuration' table of joint values. {layout}"
    value = raw["configuration"]
    if isinstance(value, (list, tuple)):
        return (f"{where}: 'configuration' is a list of {len(value)} values; a plan names each "
                f"joint. Fix: write it as a table of joint = value ({', '.join(JOINTS[:2])}, "
                f"..., gripper), as in waypoints/example.json.")
    return (f"{where}: 'configuration' must be a table of joint values, got "
            f"{describe_value(value)}. {layout}")


def _refuse_unknown_keys(table: Mapping, known: tuple[str, ...], where: str) -> None:
    """PlanError for keys of ``table`` not in ``known``, with a "did you mean"."""
    extra = [key for key in table if key not in known]
    if extra:
        close = difflib.get_close_matches(str(extra[0]), known, n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise PlanError(f"{where}: unknown key(s) {sorted(map(str, extra))}; allowed: "
                        f"{', '.join(known)}.{hint}")

