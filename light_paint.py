"""Light painting in the simulator: a light traces strokes in a vertical plane, a long exposure.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/drawing/light_paint.py``: the board, the light's path and brightness, the
long exposure through the fixed camera, the score).
"""

from __future__ import annotations

import so101_kinematics.display  # noqa: F401 - first: EGL when there is no display

# isort: split
import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics.cli import (
    ArgumentParser,
    add_calibration_argument,
    number,
    range_help,
    run_script,
)
from so101_kinematics.drawing.glyphs import DEFAULT_FONT, SHAPES, shape_strokes, text_strokes
from so101_kinematics.drawing.light_paint import EXPOSURE_CAMERA, paint, save_exposure
from so101_kinematics.drawing.light_switch import SWITCH_LEAD_S, TorchSwitch
from so101_kinematics.drawing.pen_plan import DEFAULT_SPEED_MM_S
from so101_kinematics.drawing.strokes import fit_to_height
from so101_kinematics.drawing.svg_paths import svg_strokes
from so101_kinematics.errors import (
    ARM_NOT_STARTED,
    OutputPathError,
    PlanError,
    UnreachableError,
)
from so101_kinematics.outputs import (
    PNG,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)

REPORT = report_of("light_paint.py")
SWITCH = TorchSwitch()  # the torch's button under the moving jaw: the defaults
SIZE_RANGE = (10.0, 150.0)  # [mm]
SPEED_RANGE = (1.0, 200.0)  # [mm/s]


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, paint, print and write the figures; the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""The light (an LED in the pen's holder) traces the strokes on a vertical
board in front of the arm, off between strokes and, while on, as bright as
its speed read back (so the exposure is even where it slows); the fixed
'{EXPOSURE_CAMERA}' camera takes the long exposure. Scored: the light's path from
the strokes (mean_mm) and the exposure per millimetre along it
(brightness_spread_pct: largest minus smallest over the mean).

Exit code: 0 painted, 2 bad input (one line), 1 an unexpected error.""")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--shape", choices=SHAPES, help="a simple shape")
    what.add_argument("--text", help="one line of text in a Hershey stroke font")
    what.add_argument("--svg", metavar="FILE", help="an SVG picture's paths")
    parser.add_argument("--size-mm", type=number(*SIZE_RANGE, "mm"), default=120.0,
                        metavar="S", help="the drawing's height (a text's line height), "
                        f"{range_help(*SIZE_RANGE, 'mm')} (default %(default)g)")
    parser.add_argument("--speed-mm-s", type=number(*SPEED_RANGE, "mm/s"),
                        default=DEFAULT_SPEED_MM_S, metavar="V",
                        help=f"the light's speed, {range_help(*SPEED_RANGE, 'mm/s')} "
                        "(default %(default)g)")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    parser.add_argument("--image", type=Path, metavar="PATH.png",
                        help="write the long exposure as a PNG")
    add_overwrite_argument(parser)
    arm = parser.add_argument_group("on an arm (through lerobot's bus; the virtual arm too)")
    arm.add_argument("--port", metavar="PORT",
                     help="the arm's serial port: the same path through lerobot's bus, a torch "
                     "on the fixed jaw switched by the gripper; the JSON's light has the "
                     "planned and measured on/off times")
    add_calibration_argument(arm)
    arm.add_argument("--switch-gripper", type=number(0.0, 100.0, "%"), nargs=3,
                     metavar=("RELEASED", "CLICK", "PRESSED"),
                     default=(SWITCH.released, SWITCH.click, SWITCH.pressed),
                     help="the gripper [%%] with the torch's button released, at its click, "
                     "held down (default %(default)s)")
    arm.add_argument("--switch-lead-s", type=number(0.0, 1.0, "s"), nargs=2,
                     default=SWITCH_LEAD_S, metavar=("ON", "OFF"),
                     help="press this long before the light is wanted on, release this long "
                     "before it is wanted off [s] (default %(default)s: the virtual arm's; a "
                     "run's JSON light.switch says how late yours is: add it)")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    refused = (OutputPathError, PlanError, *ARM_NOT_STARTED)
    return run_script(parser, argv, _run, refused=refused)


def _strokes(args: argparse.Namespace):
    """The target on the board [mm], ``--size-mm`` high, centred."""
    if args.text is not None:
        raw, lines = text_strokes(args.text, DEFAULT_FONT)
        return fit_to_height(raw, args.size_mm, lines)
    raw = shape_strokes(args.shape) if args.shape else svg_strokes(args.svg)
    return fit_to_height(raw, args.size_mm)


def _paint_on_arm(args: argparse.Namespace, json_path: Path | None) -> int:
    """--port: the light's path through lerobot's bus, the torch switched by the gripper."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.lab.light_arm import paint_on_arm
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    if args.image is not None:
        raise PlanError("--image with --port: the exposure is the simulator's (nothing was "
                        "run). Fix: leave out --image, or paint in the simulator first.")
    switch = TorchSwitch(*args.switch_gripper, *args.switch_lead_s)
    switch.check()  # before the port is opened
    calibration = load_calibration(args.calibration or DEFAULT_CALIBRATION_PATH)
    report = paint_on_arm(args.port, calibration, _strokes(args), args.speed_mm_s, switch)
    light, late = report["light"], report["light"]["switch"]
    ended = "" if report["aborted"] is None else f" ABORTED ({report['aborted']})"
    print(f"Painted on the arm at {args.port}{ended}: the light on "
          f"{len(light['measured'])} times for {len(light['planned'])} strokes"
          + ("" if late is None else f", switched {late['on_ms']:+.0f} ms (on) and "
             f"{late['off_ms']:+.0f} ms (off) from the plan")
          + ("" if light["mean_mm"] is None else
             f"; the lit path {light['mean_mm']:.2f} mm mean from the strokes"))
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "light_paint.py"), indent=2)
                          + "\n")
    return 0 if report["aborted"] is None else 1


def _run(args: argparse.Namespace) -> int:
    """Check the outputs, paint, report (see :func:`main`)."""
    inputs = [args.svg] if args.svg else []
    image = (None if args.image is None else check_output_path(
        args.image, "--image", inputs, args.overwrite, suffixes=(".png",), kind=PNG))
    json_path = (None if args.json is None else check_output_path(
        args.json, "--json", inputs, args.overwrite, kind=REPORT))
    try:
        if args.port:
            return _paint_on_arm(args, json_path)
        report, exposure = paint(_strokes(args), args.speed_mm_s)
    except UnreachableError as error:
        raise PlanError(f"{error} (the board's points must be in reach with the light "
                        "leaning forward). Fix: a smaller --size-mm.") from None
    figures = report["exposure"]
    line = (f"light within {figures['mean_mm']:.2f} mm (mean), {figures['worst_mm']:.2f} mm "
            f"(worst) of the strokes; exposure even within "
            f"{figures['brightness_spread_pct']:.0f} % along the path")
    print(f"Painted in {report['duration_s']:.0f} s at {args.speed_mm_s:g} mm/s: {line}")
    if image is not None:
        save_exposure(image, exposure,
                      f"{line}\nthe simulated long exposure of the fixed camera "
                      f"'{EXPOSURE_CAMERA}'")
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "light_paint.py"), indent=2)
                          + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
