"""Command-line plumbing shared by the scripts: one-line errors, checked numbers, exit codes.

Every script answers bad input with one line on stderr that names the option,
the value, the allowed range and the fix, and exits with status 2
(:class:`ArgumentParser`, :func:`number`); an unexpected exception is one
line with a hint to rerun with ``-v`` for the traceback, exit status 1
(:func:`report_unexpected`). :func:`run_script` is the one ending every
simulation script's ``main()`` shares.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from collections.abc import Callable, Sequence

from so101_kinematics import servo
from so101_kinematics.errors import PlanError
from so101_kinematics.inputs import format_range

__all__ = [
    "ArgumentParser", "EXIT_BAD_INPUT", "EXIT_FAILED", "NOTHING_WRITTEN", "StoreGiven",
    "add_calibration_argument", "add_gravity_ff_argument", "add_moved_options",
    "add_servo_arguments", "hide_expert_options", "ignored_with_plan", "number", "range_help",
    "requires", "run_script", "servo_from_arguments", "zero_duration_warning",
]

EXIT_BAD_INPUT = 2
"""Exit status for input the script refuses (nothing ran)."""

EXIT_FAILED = 1
"""Exit status for a run that failed (or an unexpected error)."""

EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT, as the shell reports it)."""


class ArgumentParser(argparse.ArgumentParser):
    """An ``argparse.ArgumentParser`` whose errors are one line (no usage block), exit status 2."""

    def error(self, message: str):
        """Print ``prog: error: message`` in one line and exit with status 2."""
        message = " ".join(message.split())
        if "Fix:" not in message:
            message = message.rstrip(".") + ". Fix: see --help."
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def number(low: float = -math.inf, high: float = math.inf, unit: str = "", *,
           low_open: bool = False, integer: bool = False) -> Callable[[str], float]:
    """An argparse ``type`` for a finite number within a range.

    Args:
        low: smallest allowed value.
        high: largest allowed value.
        unit: the unit, for messages and help, e.g. ``"s"``.
        low_open: exclude ``low``.
        integer: accept whole numbers only (returns an int).

    Returns:
        A function text -> number that raises ``argparse.ArgumentTypeError``
        with the value, the range and the fix (argparse adds the option's name).
    """
    allowed = format_range(low, high, unit, low_open)

    def parse(text: str):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            kind = "a whole number" if integer else "a number"
            if allowed.startswith("finite"):  # any number: no range to name
                raise argparse.ArgumentTypeError(f"{text!r} is not {kind}. Fix: give a finite "
                                                 f"{kind[2:]}.") from None
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {kind}; it must be {allowed}. "
                f"Fix: give {kind} {allowed}.") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a finite number. Fix: give a finite number"
                + ("." if allowed.startswith("finite") else f" {allowed}."))
        if value < low or value > high or (low_open and value == low):
            raise argparse.ArgumentTypeError(
                f"{text} is not {allowed}. Fix: give a number {allowed}.")
        return value

    parse.__name__ = "number"
    return parse


def range_help(low: float, high: float, unit: str = "", low_open: bool = False) -> str:
    """The allowed range as ``--help`` shows it, e.g. ``in [0, 600] s``."""
    return format_range(low, high, unit, low_open).replace("%", "%%")


MIN_USEFUL_MOVE_S = 0.3
"""A move shorter than this [s] is a jump the position servos cannot follow (a warning)."""


def zero_duration_warning(move_duration: float, hold: float) -> str:
    """A warning for moves too short to follow (``--move-duration 0``), or "".

    Example:
        >>> zero_duration_warning(2.0, 0.5)
        ''
    """
    if move_duration >= MIN_USEFUL_MOVE_S:
        return ""
    held = " and no hold to catch up (--hold 0)" if hold == 0 else ""
    return (f"warning: --move-duration {move_duration:g} s: each move is a jump{held}; the "
            "servos cannot follow, so the arm lags the plan and the cube is likely missed (by "
            "hundreds of mm). Fix: --move-duration 1 or more (the default is 2).")


class StoreGiven(argparse.Action):
    """``store``, remembering the option was given (its dest in ``args.given``).

    An option left at its default and one given its default's value differ: only the one
    given can be refused as doing nothing (:func:`ignored_with_plan`).
    """

    def __call__(self, parser, namespace, values, option_string=None):
        """Store the value; add the dest to ``namespace.given``."""
        setattr(namespace, self.dest, values)
        namespace.given = set(getattr(namespace, "given", ())) | {self.dest}


def ignored_with_plan(args) -> str:
    """A one-line refusal of ``--move-duration``/``--hold`` given with ``--plan``, or "".

    They time the built-in plan; a waypoint file carries each step's own ``duration`` and
    ``hold``, so with ``--plan`` they would be silently ignored.
    """
    given = [f"--{dest.replace('_', '-')}" for dest in ("move_duration", "hold")
             if dest in getattr(args, "given", ())]
    if not given or getattr(args, "plan", None) is None:
        return ""
    names = " and ".join(given)
    return (f"{names} time{'s' if len(given) == 1 else ''} the built-in plan; --plan "
            f"{args.plan} gives each waypoint its own 'duration' and 'hold', so {names} would "
            f"do nothing (nothing was run). Fix: leave out {names}, or change 'duration' and "
            "'hold' in the plan file.")


def requires(args, option: str, needed: str) -> str:
    """A one-line refusal when ``--option`` is given without ``--needed``, or "".

    Args:
        args: the parsed command line.
        option: the option that does nothing alone, e.g. "report".
        needed: the option it works with, e.g. "compare".
    """
    attribute, other = option.replace("-", "_"), needed.replace("-", "_")
    if getattr(args, attribute, None) in (None, False) or getattr(args, other, None) not in \
            (None, False):
        return ""
    return (f"--{option} works only with --{needed}: alone it does nothing (nothing was run). "
            f"Fix: add --{needed}, or leave out --{option}.")


def report_unexpected(error: BaseException, verbose: bool) -> int:
    """Report an unexpected exception in one line (or re-raise it with ``-v``).

    Args:
        error: the exception caught at the top of ``main()``.
        verbose: the script's ``-v``: re-raise for the full traceback.

    Returns:
        ``EXIT_FAILED``.
    """
    if verbose:
        raise error
    text = " ".join(str(error).split()) or "(no message)"
    print(f"error: unexpected {type(error).__name__}: {text} (a bug? rerun with -v for the "
          "traceback)", file=sys.stderr)
    return EXIT_FAILED


NOTHING_WRITTEN = "nothing was written; existing output files are as they were."
"""``run_script``'s ``interrupted`` for a program that writes its outputs only at its end."""


def run_script(parser: argparse.ArgumentParser, argv: Sequence[str] | None,
               run: Callable[[argparse.Namespace], int], *,
               refused: tuple[type[Exception], ...] = (),
               interrupted: str = "existing output files are as they were.",
               log_format: str = "%(message)s", log_level: int | None = None) -> int:
    """Parse the command line and run: the ending every simulation script's ``main()`` shares.

    Args:
        parser: the script's parser (an :class:`ArgumentParser`, with ``-v/--verbose``).
        argv: the arguments (None: ``sys.argv[1:]``).
        run: the script's work, given the parsed arguments; returns the exit code.
        refused: the errors that mean bad input: one line, ``EXIT_BAD_INPUT``.
        interrupted: what Ctrl-C left as it was, after "Interrupted (Ctrl-C): ".
        log_format: the logging format.
        log_level: the logging level (None: INFO with ``-v``, else WARNING).

    Returns:
        The exit code: the parser's (bad options, ``--help``), ``run``'s, ``EXIT_BAD_INPUT``,
        ``EXIT_INTERRUPTED``, or ``EXIT_FAILED`` for an unexpected error (its traceback with
        ``-v``).
    """
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # bad options (one line printed) or --help: the exit code
        return stop.code
    if log_level is None:
        log_level = logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=log_level, format=log_format)
    try:
        return run(args)
    except refused as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"Interrupted (Ctrl-C): {interrupted}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:
        return report_unexpected(error, args.verbose)


def add_calibration_argument(parser) -> None:
    """``--calibration PATH`` (default None: the virtual arm's): every script that runs an arm.

    ``parser``: the parser, or its group of the arm's options.
    """
    from pathlib import Path

    parser.add_argument("--calibration", type=Path, default=None, metavar="PATH",
                        help="the arm's lerobot calibration (default: the virtual arm's)")


def add_gravity_ff_argument(parser: argparse.ArgumentParser) -> None:
    """``--gravity-ff`` / ``--no-gravity-ff`` (default on): every script that moves the arm."""
    parser.add_argument("--gravity-ff", action=argparse.BooleanOptionalAction, default=True,
                        help="offset each goal by the sag gravity will cause there (the "
                        "servo's holding error at its P and supply; docs/servo.md); "
                        "--no-gravity-ff shows the raw sag (default on)")


def add_servo_arguments(parser: argparse.ArgumentParser) -> None:
    """The simulated servo's options: --servo, --supply, --variant, --p-coefficient, --gravity-ff.

    :func:`servo_from_arguments` turns them into ``use_servo``'s keywords.
    """
    group = parser.add_argument_group("servo (docs/servo.md: what the real arm does)")
    group.add_argument("--servo", choices=servo.SIMULATED_SERVOS, default="sts3215",
                       help="sts3215: the measured servo at lerobot's settings (P 16, D 32, "
                       "Acceleration 254); ideal: the upstream model's kp = 998 servo, about "
                       "110x stiffer than the real one (default %(default)s)")
    highest = max(variant.max_volts for variant in servo.VARIANTS.values())
    group.add_argument("--supply", type=number(0.0, highest, "V", low_open=True), default=None,
                       metavar="VOLTS", help=f"the servos' supply [V], in (0, {highest:g}] "
                       f"(default {servo.DEFAULT_SUPPLY_V:g}: the course's follower; 5 for the "
                       "standard kit's C001s, 7.4 for a C001 on a 7.4 V pack; at most "
                       f"{servo.VARIANTS['C001'].max_volts:g} V for a C001)")
    group.add_argument("--variant", choices=tuple(servo.VARIANTS), default=None,
                       help="STS3215 variant (default: C018 above 9 V, else C001 with Rhoban "
                       "BAM's identified motor; C001-datasheet: the datasheet's, 1.75x weaker)")
    group.add_argument("--p-coefficient", type=number(1, 255, integer=True), default=None,
                       metavar="P",
                       help=f"P_Coefficient, in [1, 255] (default {servo.LEROBOT.p}: lerobot's)")
    add_gravity_ff_argument(group)


def servo_from_arguments(args: argparse.Namespace) -> dict:
    """``use_servo``'s keywords from :func:`add_servo_arguments`' options.

    Raises:
        PlanError: ``--servo ideal`` with an option only the STS3215 model has (it would be
            ignored), or a supply above the variant's Max_Voltage_Limit.
    """
    given = [name for name, value in (("--supply", args.supply), ("--variant", args.variant),
                                      ("--p-coefficient", args.p_coefficient))
             if value is not None]
    if args.servo == "ideal" and given:
        raise PlanError(f"{', '.join(given)} with --servo ideal: the ideal servo has no supply, "
                        "variant or P (it would be ignored). Fix: leave "
                        f"{' and '.join(given)} out, or use --servo sts3215.")
    volts = servo.DEFAULT_SUPPLY_V if args.supply is None else args.supply
    variant = args.variant or servo.default_variant(volts)
    problem = servo.supply_problem(variant, volts) if args.servo != "ideal" else None
    if problem:
        raise PlanError(problem)
    p = servo.LEROBOT.p if args.p_coefficient is None else int(args.p_coefficient)
    return {"mode": args.servo, "volts": volts, "variant": args.variant, "p": p,
            "feedforward": args.gravity_ff}


class _Moved(argparse.Action):
    """An option that moved to the ``so101`` command: refused in one line with its new spelling."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs):
        super().__init__(option_strings, dest, nargs="*", help=argparse.SUPPRESS, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        parser.exit(EXIT_BAD_INPUT, f"{parser.prog}: error: {option_string} moved to the so101 "
                                    f"command (nothing was run). Fix: run `{self.new}`.\n")


def add_moved_options(parser: argparse.ArgumentParser, moved: dict[str, str]) -> None:
    """Old options that moved: each is refused in one line with its new spelling, exit 2.

    Args:
        parser: the script's parser.
        moved: old option -> the command to run now, e.g.
            ``{"--compare": "so101 compare LOG.csv ... --report PATH.png"}``.

    Example:
        >>> parser = ArgumentParser(prog="pick_place_sim.py")
        >>> add_moved_options(parser, {"--compare": "so101 compare LOG.csv --report R.png"})
        >>> parser.parse_args(["--compare", "run.csv"])  # doctest: +SKIP
        pick_place_sim.py: error: --compare moved to the so101 command (nothing was run). \
Fix: run `so101 compare LOG.csv --report R.png`.
    """
    for option, new in moved.items():
        parser.add_argument(option, action=_Moved, new=new, dest=f"moved_{option.strip('-')}")


class _HelpAll(argparse.Action):
    """``--help-all``: the help with the expert options listed too."""

    def __init__(self, option_strings, dest, hidden=None, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS,
                         help="list every option, the expert ones too, and exit", **kwargs)
        self.hidden = hidden or {}

    def __call__(self, parser, namespace, values, option_string=None):
        for action, text in self.hidden.items():
            action.help = text
        parser.print_help()
        parser.exit()


def hide_expert_options(parser: argparse.ArgumentParser, dests: set[str]) -> None:
    """Keep ``--help`` to the week's options: ``dests`` stay accepted, listed by ``--help-all``."""
    hidden = {action: action.help for action in parser._actions if action.dest in dests}
    for action in hidden:
        action.help = argparse.SUPPRESS
    parser.add_argument("--help-all", action=_HelpAll, hidden=hidden)
