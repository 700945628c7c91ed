"""Joint-space motion shared by the simulated and the real SO-101.

One place for what both backends must agree on:
  - configurations: dicts joint name -> value, arm joints in [deg], gripper in
    [0, 100] (0 = closed end of its range, 100 = open end), and their
    validation against joint limits (:func:`check_configuration`);
  - the interpolation between two configurations (:class:`Trajectory`, with a
    linear or a minimum-jerk profile);
  - the pick-and-place plan (:class:`Step`, :func:`default_plan`,
    :func:`load_plan`) and the runner that executes it through a backend's
    ``move_to_pose`` / ``hold_position`` (:func:`run_plan`).

The backends (``so101_mujoco_utils`` for MuJoCo, ``so101_control`` for a
lerobot bus) only decide how time passes and how a command reaches the arm.
"""

from __future__ import annotations

import difflib
import json
import math
import numbers
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from so101_kinematics.errors import JointLimitError as JointLimitError
from so101_kinematics.errors import PlanError as PlanError
from so101_kinematics.frames import JOINTS

Configuration = dict[str, float]
Limits = Mapping[str, tuple[float, float]]


MAX_DURATION = 600.0
"""Longest move, hold or return [s] of a plan or a simulated motion (ten minutes).

A simulated second is 250 physics steps; a longer duration is almost surely a
typo (milliseconds for seconds) and would keep the simulator busy for hours.
"""

"""Gripper opening at the user boundary [0, 100]: 0 closed end, 100 open end of its range."""


def unit(joint: str) -> str:
    """Unit of a joint's value at the user boundary: "deg" or "%" (gripper)."""
    return "%" if joint == "gripper" else "deg"


def is_finite_number(value) -> bool:
    """True for a finite int or float (numpy scalars included), False for bools and the rest.

    Integers too large for a float (``10**400``) are not finite numbers here.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond the float range
        return False


def describe_value(value) -> str:
    """A short, one-line description of a value for an error message.

    Example:
        >>> describe_value(10**400), describe_value("2.0"), describe_value(float("nan"))
        ('an integer of about 401 digits', "'2.0' (text)", 'nan')
    """
    if isinstance(value, (bool, np.bool_)):
        return f"{bool(value)} (a boolean)"
    if isinstance(value, str):
        text = value if len(value) <= 40 else value[:37] + "..."
        return f"{text!r} (text)"
    if isinstance(value, numbers.Integral):
        number = int(value)
        if abs(number) < 10**24:
            return str(number)
        digits = int(abs(number).bit_length() * math.log10(2.0)) + 1  # no str(): 4300-digit cap
        return f"{'-' if number < 0 else ''}an integer of about {digits} digits"
    if isinstance(value, numbers.Real):
        return f"{float(value):g}"
    if value is None:
        return "None (null)"
    text = repr(value).replace("\n", " ")
    return (text if len(text) <= 40 else text[:37] + "...") + f" (a {type(value).__name__})"


def format_range(low: float, high: float, unit: str = "", low_open: bool = False) -> str:
    """An interval for messages: ``in [0, 600] s``, ``in (0, 0.01] s``, ``>= 1 frames/s``."""
    text = "in " + ("(" if low_open else "[") + f"{low:g}, {high:g}]"
    if math.isinf(high):
        text = (">" if low_open else ">=") + f" {low:g}"
    return f"{text} {unit}".rstrip()


def check_number(value, name: str, low: float = -math.inf, high: float = math.inf,
                 unit: str = "", *, low_open: bool = False, fix: str = "",
                 error: type[Exception] = PlanError) -> float:
    """A finite real number within ``[low, high]`` (``(low, high]`` if ``low_open``) as a float.

    Booleans, text and ``None`` are not numbers here; NaN, infinities and
    integers beyond the float range are not finite.

    Args:
        value: the value to check.
        name: what the user calls it (for the message), e.g. ``"waypoint 2 'lift': duration"``.
        low: smallest allowed value.
        high: largest allowed value.
        unit: unit for the message, e.g. ``"s"``.
        low_open: exclude ``low`` itself.
        fix: what to do instead (default: give a number in the range).
        error: the exception class to raise (a ValueError subclass of the caller's family).

    Returns:
        The value as a float.

    Raises:
        error: one line naming ``name``, the value, the allowed range and the fix.

    Example:
        >>> check_number(2, "duration", 0.0, 600.0, "s")
        2.0
        >>> check_number("2", "duration", 0.0, 600.0, "s")
        Traceback (most recent call last):
        ...
        so101_kinematics.errors.PlanError: duration must be a number in [0, 600] s, got '2' \
(text). Fix: write the number without quotes.
    """
    allowed = format_range(low, high, unit, low_open)
    if not is_finite_number(value):
        default = f"give a number {allowed}."
        if isinstance(value, str):
            default = "write the number without quotes."
            fix = f"write the number without quotes; {fix}" if fix else ""
        kind = "a finite number" if isinstance(value, numbers.Real) and not isinstance(
            value, (bool, np.bool_)) else "a number"
        raise error(f"{name} must be {kind} {allowed}, got {describe_value(value)}. "
                    f"Fix: {fix or default}")
    number = float(value)
    if number < low or number > high or (low_open and number == low):
        raise error(f"{name} = {describe_value(value)} {unit}".rstrip()
                    + f" is not {allowed}. Fix: {fix or f'give a number {allowed}.'}")
    return number


def check_duration(value, name: str, error: type[Exception] = PlanError) -> float:
    """A duration [s] in ``[0, MAX_DURATION]`` as a float (see :func:`check_number`)."""
    return check_number(value, name, 0.0, MAX_DURATION, "s", error=error,
                        fix=f"give a number of seconds (not milliseconds) in [0, "
                            f"{MAX_DURATION:g}].")


def check_configuration(cfg: Mapping[str, float], limits: Limits, where: str = "") -> Configuration:
    """Validate a configuration and return it as a plain dict of floats.

    Args:
        cfg: joint name -> value ([deg]; gripper [0, 100]). All six joints are
            required unless ``limits`` lists fewer.
        limits: joint name -> (lower, upper) in the same units.
        where: context for messages, e.g. "waypoint 'lift'".

    Returns:
        The configuration, keys in ``JOINTS`` order, values as floats.

    Raises:
        PlanError: a joint is missing, unknown, or not a finite number.
        JointLimitError: a value is outside its limits (names joint, value,
            limit and the fix).
    """
    prefix = f"{where}: " if where else ""
    unknown = [name for name in cfg if name not in JOINTS]
    if unknown:
        name = unknown[0]
        close = difflib.get_close_matches(name, JOINTS, n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise PlanError(f"{prefix}unknown joint '{name}'.{hint} Joints are: {', '.join(JOINTS)}.")
    out = {}
    for joint in (j for j in JOINTS if j in limits):
        if joint not in cfg:
            raise PlanError(f"{prefix}joint '{joint}' is missing; give all of {', '.join(limits)}.")
        value = cfg[joint]
        if not is_finite_number(value):
            lower, upper = limits[joint]
            within = (f" within its limits [{lower:g}, {upper:g}] {unit(joint)}"
                      if math.isfinite(lower) and math.isfinite(upper) else f" [{unit(joint)}]")
            raise PlanError(f"{prefix}joint '{joint}' must be a finite number{within}, got "
                            f"{describe_value(value)}. Fix: give {joint} a number"
                            + (" without quotes." if isinstance(value, str) else "."))
        lower, upper = limits[joint]
        if not lower <= value <= upper:
            bound = lower if value < lower else upper
            raise JointLimitError(
                f"{prefix}{joint} = {value:g} {unit(joint)} is outside its limits "
                f"[{lower:g}, {upper:g}] {unit(joint)} (beyond {bound:g} by "
                f"{abs(value - bound):.3g}). Fix: choose a {joint} within the limits."
            )
        out[joint] = float(value)
    return out


def minimum_jerk(s: float) -> float:
    """Minimum-jerk time scaling: 0 -> 0, 1 -> 1, zero velocity and acceleration at both ends."""
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def linear(s: float) -> float:
    """Linear time scaling (the course's interpolation)."""
    return s


PROFILES: dict[str, Callable[[float], float]] = {"linear": linear, "minimum_jerk": minimum_jerk}


@dataclass(frozen=True)
class Trajectory:
    """Joint-space path from ``start`` to ``goal`` in ``duration`` [s].

    Example:
        >>> path = Trajectory({"gripper": 0.0}, {"gripper": 100.0}, 2.0, "minimum_jerk")
        >>> path.at(1.0)  # halfway in time is halfway in space for this profile
        {'gripper': 50.0}
    """

    start: Mapping[str, float]
    goal: Mapping[str, float]
    duration: float
    profile: str = "minimum_jerk"

    def __post_init__(self):
        if not isinstance(self.profile, str) or self.profile not in PROFILES:
            raise PlanError(f"Unknown profile {self.profile!r}; use one of {', '.join(PROFILES)}.")
        # Finite and >= 0; no upper bound here: a trajectory only stores its ends.
        object.__setattr__(self, "duration", check_number(self.duration, "Trajectory duration",
                                                          0.0, math.inf, "s"))

    def fraction(self, t: float) -> float:
        """Fraction of the way from start to goal at time ``t`` [s] (0 before, 1 after)."""
        s = 1.0 if self.duration <= 0.0 else min(max(t / self.duration, 0.0), 1.0)
        return PROFILES[self.profile](s)

    def fractions(self, times: np.ndarray) -> np.ndarray:
        """:meth:`fraction` for an array of times [s] at once."""
        if self.duration <= 0.0:
            return np.ones(np.shape(times))
        return PROFILES[self.profile](np.clip(np.asarray(times, dtype=float) / self.duration,
                                              0.0, 1.0))

    def at(self, t: float) -> Configuration:
        """Configuration at time ``t`` [s] after the start (held at the ends)."""
        alpha = self.fraction(t)
        return {j: self.start[j] + alpha * (self.goal[j] - self.start[j]) for j in self.goal}


@dataclass
class Step:
    """One waypoint: move to ``configuration`` in ``duration`` [s], then hold ``hold`` [s]."""

    name: str
    configuration: Configuration
    duration: float = 2.0
    hold: float = 0.5


@dataclass
class Plan:
    """A named sequence of steps; ``return_to_start`` ends back at the initial pose."""

    steps: list[Step] = field(default_factory=list)
    return_to_start: bool = True
    return_duration: float = 2.0

    def configurations(self) -> dict[str, Configuration]:
        """Step name -> configuration."""
        return {step.name: step.configuration for step in self.steps}


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
    one (``so101_cartesian_plan``) alike.

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
        plan has them, else its first and last steps.
    """
    by_name = {step.name: step for step in plan.steps}
    return by_name.get(PICK_STEP, plan.steps[0]), by_name.get(PLACE_STEP, plan.steps[-1])


def validate_plan(plan: Plan, limits: Limits, source: str = "") -> Plan:
    """Check every step before anything moves.

    Args:
        plan: the plan.
        limits: joint name -> (lower, upper) [deg] (gripper [0, 100]).
        source: where the plan came from, for messages (e.g. the file).

    Returns:
        The same plan with configurations and durations normalised to floats.

    Raises:
        PlanError: empty plan, duplicate names, bad durations (each in
            [0, ``MAX_DURATION``] s), a ``return_to_start`` that is not a
            boolean, or bad configurations.
    """
    prefix = f"{source}, " if source else ""
    check_plan_settings(plan, source)
    for i, step in enumerate(plan.steps):
        where = f"{prefix}waypoint {i + 1} '{step.name}'"
        step.configuration = check_configuration(step.configuration, limits, where)
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
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise error(f"{what} '{path}' is UTF-16 text, not UTF-8. Fix: save it as UTF-8.")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as problem:
        raise error(f"{what} '{path}' is not UTF-8 text (byte {problem.start} is "
                    f"0x{data[problem.start]:02x}). Fix: save it as UTF-8.") from None


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
    kind = "TOML" if path.suffix.lower() == ".toml" else "JSON"
    try:
        if kind == "TOML":
            if sys.version_info >= (3, 11):
                import tomllib
            else:  # pragma: no cover - Python 3.10
                import tomli as tomllib
            data = tomllib.loads(text)
        else:
            data = json.loads(text)
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
            raise PlanError(f"{where}: each waypoint needs a 'configuration' table "
                            "of joint values. Fix: see waypoints/example.json.")
        _refuse_unknown_keys(raw, STEP_KEYS, where)
        steps.append(Step(raw.get("name", f"waypoint_{i + 1}"), dict(raw["configuration"]),
                          raw.get("duration", 2.0), raw.get("hold", 0.5)))
    plan = Plan(steps, data.get("return_to_start", True), data.get("return_duration", 2.0))
    if limits is not None:
        validate_plan(plan, limits, f"'{path}'")
    else:
        check_plan_settings(plan, f"'{path}'")
        for i, step in enumerate(plan.steps):  # numbers only; the limits come later
            check_configuration(step.configuration, {j: (-math.inf, math.inf) for j in JOINTS},
                                f"'{path}', waypoint {i + 1} '{step.name}'")
    return plan


def _refuse_unknown_keys(table: Mapping, known: tuple[str, ...], where: str) -> None:
    """PlanError for keys of ``table`` not in ``known``, with a "did you mean"."""
    extra = [key for key in table if key not in known]
    if extra:
        close = difflib.get_close_matches(str(extra[0]), known, n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise PlanError(f"{where}: unknown key(s) {sorted(map(str, extra))}; allowed: "
                        f"{', '.join(known)}.{hint}")


def run_plan(
    plan: Plan,
    move_to_pose: Callable[[Mapping[str, float], float], None],
    hold_position: Callable[[float], None],
    initial: Mapping[str, float] | None = None,
    on_step: Callable[[Step], None] | None = None,
) -> None:
    """Execute a validated plan through a backend.

    Args:
        plan: the plan (already validated).
        move_to_pose: ``move_to_pose(cfg, duration)`` of the backend.
        hold_position: ``hold_position(duration)`` of the backend.
        initial: the pose to return to at the end (if ``plan.return_to_start``).
        on_step: called with each step before it starts (progress reporting).
    """
    for step in plan.steps:
        if on_step is not None:
            on_step(step)
        move_to_pose(step.configuration, step.duration)
        if step.hold > 0:
            hold_position(step.hold)
    if plan.return_to_start and initial is not None:
        if on_step is not None:
            on_step(Step("return_to_start", dict(initial), plan.return_duration, 0.0))
        move_to_pose(initial, plan.return_duration)
