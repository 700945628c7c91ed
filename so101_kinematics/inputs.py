"""Checked inputs, one way for the whole project: numbers, durations, configurations.

Configurations are dicts joint name -> value, arm joints in [deg], the gripper
in [0, 100] (0 = closed end of its range, 100 = open end). Every check names
the parameter, the value, the allowed range and the fix.
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Mapping

import numpy as np

from so101_kinematics.errors import CallShapeError, JointLimitError, PlanError
from so101_kinematics.frames import ARM_JOINTS, JOINTS

__all__ = [
    "Configuration", "LIMIT_TOLERANCE", "Limits", "MAX_DURATION", "MISSING", "RADIANS_BOUND",
    "START_MISMATCH", "check_configuration", "check_duration", "check_number",
    "describe_value", "format_limit", "format_range", "is_finite_number", "limit_excess",
    "limit_message", "looks_like_radians", "move_arguments", "radians_warning",
    "start_mismatch", "unit",
]

Configuration = dict[str, float]
Limits = Mapping[str, tuple[float, float]]


MAX_DURATION = 600.0
"""Longest move, hold or return [s] of a plan or a simulated motion (ten minutes).

A simulated second is 250 physics steps; a longer duration is almost surely a
typo (milliseconds for seconds) and would keep the simulator busy for hours.
"""

"""Gripper opening at the user boundary [0, 100]: 0 closed end, 100 open end of its range."""

LIMIT_TOLERANCE = 1e-5
"""How far beyond a joint limit a value still counts as on it [deg] (gripper [%]): 10 micro-degrees.

The model's ranges are radians written to six digits, so a limit that is a round
number of degrees lands a little off it: shoulder_lift's -100 deg is
-99.99999999999959, wrist_flex's 95 deg is 94.9999966 (3.4 micro-degrees
inside). A configuration on a limit's round number, or copied from a message
(:data:`LIMIT_DECIMALS`), is within it. Every joint-limit check compares
through :func:`limit_excess`; a value accepted this way is clamped onto the limit.
"""

LIMIT_DECIMALS = 5
"""Decimals of a joint limit in messages (:func:`format_limit`).

Rounding to 5 decimals moves a limit by at most 5e-6, half of
:data:`LIMIT_TOLERANCE`, so a limit as printed is always accepted, and a value
refused (beyond by more than the tolerance) never prints equal to its limit.
"""


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
    """An interval for messages: ``in [0, 600] s``, ``in (0, 0.01] s``, ``>= 1 frames/s``.

    A side at infinity is left out (``<= 5 m``); with both, any finite number is allowed:
    ``finite`` (never ``>= -inf``).
    """
    text = "in " + ("(" if low_open else "[") + f"{low:g}, {high:g}]"
    if math.isinf(low) and math.isinf(high):
        text = "finite"
    elif math.isinf(high):
        text = (">" if low_open else ">=") + f" {low:g}"
    elif math.isinf(low):
        text = f"<= {high:g}"
    return f"{text} {unit}".rstrip()


def format_limit(value: float) -> str:
    """A joint limit or a refused value for a message, to the precision that decides.

    Example:
        >>> format_limit(-99.99999999999959), format_limit(96.82986737710912)
        ('-100', '96.82987')
    """
    text = f"{value:.{LIMIT_DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def limit_excess(value: float, lower: float, upper: float) -> float:
    """How far ``value`` is beyond ``[lower, upper]`` (0 inside); refused when > LIMIT_TOLERANCE.

    Example:
        >>> limit_excess(-100.0, -99.99999999999959, 100.0) <= LIMIT_TOLERANCE
        True
    """
    return lower - value if value < lower else value - upper if value > upper else 0.0


def limit_message(joint: str, value: float, lower: float, upper: float,
                  limits: str = "its limits") -> str:
    """``"shoulder_lift = -180 deg is outside its limits [-100, 100] deg (beyond -100 by 80)"``."""
    bound = lower if value < lower else upper
    return (f"{joint} = {format_limit(value)} {unit(joint)} is outside {limits} "
            f"[{format_limit(lower)}, {format_limit(upper)}] {unit(joint)} (beyond "
            f"{format_limit(bound)} by {abs(value - bound):.3g})")


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
    unbounded = allowed.startswith("finite")
    if unbounded:  # any finite number: "a finite number [unit]", no range
        allowed = unit
    if not is_finite_number(value):
        default = f"give a {'finite ' if unbounded else ''}number {allowed}".rstrip() + "."
        if isinstance(value, str):
            default = "write the number without quotes."
            fix = f"write the number without quotes; {fix}" if fix else ""
        kind = "a finite number" if isinstance(value, numbers.Real) and not isinstance(
            value, (bool, np.bool_)) else "a number"
        raise error(f"{name} must be {kind} {allowed}".rstrip()
                    + f", got {describe_value(value)}. "
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
        JointLimitError: a value is beyond its limits by more than
            :data:`LIMIT_TOLERANCE` (names joint, value, limit and the fix).
    """
    prefix = f"{where}: " if where else ""
    unknown = [name for name in cfg if name not in JOINTS]
    if unknown:
        name = unknown[0]
        close = difflib.get_close_matches(name, JOINTS, n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise PlanError(f"{prefix}unknown joint '{name}'.{hint} Joints are: {', '.join(JOINTS)}. "
                        "Fix: use those names (as lerobot and the model spell them).")
    out = {}
    for joint in (j for j in JOINTS if j in limits):
        if joint not in cfg:
            raise PlanError(f"{prefix}joint '{joint}' is missing; give all of {', '.join(limits)}.")
        value = cfg[joint]
        if not is_finite_number(value):
            lower, upper = limits[joint]
            within = (f" within its limits [{format_limit(lower)}, {format_limit(upper)}] "
                      f"{unit(joint)}"
                      if math.isfinite(lower) and math.isfinite(upper) else f" [{unit(joint)}]")
            raise PlanError(f"{prefix}joint '{joint}' must be a finite number{within}, got "
                            f"{describe_value(value)}. Fix: give {joint} a number"
                            + (" without quotes." if isinstance(value, str) else "."))
        lower, upper = limits[joint]
        if limit_excess(value, lower, upper) > LIMIT_TOLERANCE:
            raise JointLimitError(f"{prefix}{limit_message(joint, value, lower, upper)}. "
                                  f"Fix: choose a {joint} within the limits.")
        out[joint] = min(upper, max(lower, float(value)))  # on a limit within LIMIT_TOLERANCE
    return out


START_MISMATCH = 3.0
"""[deg] (gripper [%]): a starting configuration given to ``move_to_pose`` farther than this
from the last command is named in a warning (a servo's steady-state error under load is a
degree or two). The move starts from the last command either way: no jump."""

MISSING = object()
"""An argument not given at all (None is a value: a bad one)."""


def move_arguments(args: tuple, keywords: Mapping[str, object], shapes: str,
                   first: str) -> tuple[Configuration | None, object, object]:
    """(starting configuration or None, target, duration) from a course ``move_to_pose`` call.

    The course's shapes: ``(cfg, duration)``, and assignment 8's suggested
    improvement ``(starting_cfg, cfg, duration)``; keywords (given as
    ``MISSING`` when absent) follow the positional arguments in that order.

    Args:
        args: the positional arguments after ``first``.
        keywords: name -> value of the keyword-or-positional parameters, in order.
        shapes: the accepted shapes, as the messages name them.
        first: what comes before ``args`` in a call, e.g. "m, d, viewer" or "bus".

    Raises:
        CallShapeError: any other shape, or a starting configuration that is not
            a dict joint -> finite number.
    """
    values = list(args) + [v for v in keywords.values() if v is not MISSING]
    fix = f"Fix: call {shapes}."
    if len(values) not in (2, 3):
        got = (f"one argument ({describe_value(values[0])})" if len(values) == 1 else
               f"{len(values)} arguments" if values else "no argument")
        raise CallShapeError(f"move_to_pose got {got} after {first}: it needs the target "
                             f"configuration and the duration [s]. {fix}")
    start, cfg, duration = ([None] + values) if len(values) == 2 else values
    if isinstance(duration, Mapping):
        raise CallShapeError(f"move_to_pose got a configuration ({describe_value(duration)}) "
                             f"where the duration [s] belongs. {fix}")
    if isinstance(start, Mapping) and not isinstance(cfg, Mapping):
        raise CallShapeError(f"move_to_pose got a configuration, then {describe_value(cfg)} "
                             f"and {describe_value(duration)}: after the target configuration "
                             "only the duration [s] comes (a second configuration, the target, "
                             f"comes only after a starting one). {fix}")
    if start is not None:
        if not isinstance(start, Mapping):
            raise CallShapeError(f"move_to_pose's starting configuration must be a dict joint "
                                 f"name -> value, got {describe_value(start)}. {fix}")
        try:
            start = check_configuration(start, {j: (-math.inf, math.inf) for j in start},
                                        "move_to_pose starting configuration")
        except PlanError as error:
            raise CallShapeError(str(error)) from None
    return start, cfg, duration


def start_mismatch(start: Mapping[str, float] | None, command: Mapping[str, float],
                   allowance: Mapping[str, float] | None = None) -> str | None:
    """A warning when ``start`` is more than :data:`START_MISMATCH` from ``command``, else None.

    ``allowance``: joint -> what the servo itself leaves between a command and the pose
    [deg] (the sag without the feed-forward): a measured start that far off is no mistake.
    """
    if not start:
        return None
    allowance = allowance or {}
    joint = max(start, key=lambda j: abs(start[j] - command[j]) - allowance.get(j, 0.0))
    gap = abs(start[joint] - command[joint])
    if gap <= START_MISMATCH + allowance.get(joint, 0.0):
        return None
    return (f"move_to_pose: the starting configuration is {gap:.1f} {unit(joint)} from the last "
            f"command ({joint}: {start[joint]:g} given, {command[joint]:g} commanded); the move "
            f"starts from the last command (starting elsewhere would be a jump). Fix: pass the "
            f"previous move's target as the starting configuration.")


RADIANS_BOUND = 3.2
"""A target whose every arm angle is within +-this (pi = 3.14), not all zero, looks like
radians given for degrees (``d.qpos`` copied as it is): 3.2 deg is less than any real move."""


def looks_like_radians(cfg: Mapping[str, float]) -> bool:
    """Whether every arm angle of ``cfg`` is within +-``RADIANS_BOUND`` and not all are zero."""
    values = [cfg[j] for j in ARM_JOINTS if j in cfg and is_finite_number(cfg[j])]
    return (len(values) == len(ARM_JOINTS) and all(abs(v) <= RADIANS_BOUND for v in values)
            and any(v != 0 for v in values))


def radians_warning(cfg: Mapping[str, float], current: Mapping[str, float] | None,
                    what: str = "move_to_pose") -> str | None:
    """A warning when ``cfg`` looks like radians while the arm stands elsewhere, else None.

    Args:
        cfg: the target ([deg] expected).
        current: where the arm is (or its last command) [deg]; None: unknown.
        what: the call, for the message.
    """
    if not looks_like_radians(cfg) or (current is not None and looks_like_radians(current)):
        return None
    shown = ", ".join(f"{j} {cfg[j]:g}" for j in ARM_JOINTS)
    return (f"{what}: every arm angle of the target is within +-{RADIANS_BOUND:g} ({shown}): "
            "these look like radians, but the angles are degrees, so the arm swings to almost "
            "0 deg on every joint (and a gripper of 0-1 is closed). Fix: convert with "
            "math.degrees (numpy.degrees for d.qpos), e.g. {j: math.degrees(v) ...}.")
