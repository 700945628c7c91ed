"""Draw text, an SVG picture or a shape with a pen in the simulator, and score the ink.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/drawing/``: strokes, the page in reach, the pen's path, the ink).
"""

from __future__ import annotations

import so101_kinematics.display  # noqa: F401 - first: EGL when there is no display

# isort: split
import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics.cli import (
    NOTHING_WRITTEN,
    ArgumentParser,
    add_calibration_argument,
    add_servo_arguments,
    number,
    range_help,
    run_script,
    servo_from_arguments,
)
from so101_kinematics.drawing.draw_run import drawing_strokes, run_drawing
from so101_kinematics.drawing.glyphs import DEFAULT_FONT, SHAPES
from so101_kinematics.drawing.ink_score import COVER_MM, STRAY_MM, save_drawing
from so101_kinematics.drawing.page import PAGES, Page
from so101_kinematics.drawing.pen import PenPose
from so101_kinematics.drawing.pen_plan import DEFAULT_SPEED_MM_S
from so101_kinematics.drawing.registration import read_page_pose
from so101_kinematics.errors import (
    ARM_NOT_STARTED,
    OutputPathError,
    PlanError,
)
from so101_kinematics.outputs import (
    PNG,
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)

REPORT = report_of("draw.py")  # --json replaces only a report of this program
HEIGHT_RANGE = (2.0, 200.0)  # [mm]
SPEED_RANGE = (1.0, 1000.0)  # [mm/s]: the servos' own limit is checked on the plan
TILT_RANGE = (-30.0, 45.0)  # [deg]
PAGE_AT_DEFAULT = (0.2, 0.0)  # [m]: the page's centre, in front of the arm


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, draw, print and write the figures; the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""The strokes (a Hershey stroke font, an SVG's paths, or a shape) are
placed on the page, ordered to shorten the pen-up travel, checked against
the arm's reach, and drawn by the simulated arm (the measured STS3215
servos, each command leading by the servo's lag) with a pen in a holder
that leaves ink where its tip presses on the page. The ink is scored
against the strokes: mean and worst distance [mm], coverage (ink within
{COVER_MM:g} mm) and the longest stray ink (farther than {STRAY_MM:g} mm).

Exit code: 0 drawn, 2 bad input (one line; nothing drawn), 1 a run on an
arm that aborted or an unexpected error, 130 interrupted.""")
    what = parser.add_mutually_exclusive_group()
    what.add_argument("--text", help="one line of text, in a Hershey stroke font")
    what.add_argument("--svg", metavar="FILE", help="an SVG picture: its paths are drawn")
    what.add_argument("--shape", choices=SHAPES, help="a simple shape")
    parser.add_argument("--height-mm", type=number(*HEIGHT_RANGE, "mm"), default=30.0,
                        metavar="H", help="the text's line height (cap line to descenders: "
                        "capitals are 3/4 of it) or the picture's height, "
                        f"{range_help(*HEIGHT_RANGE, 'mm')} (default %(default)g)")
    parser.add_argument("--font", default=DEFAULT_FONT, help="the Hershey font (default "
                        "%(default)s: single-stroke Roman)")
    parser.add_argument("--page", choices=tuple(PAGES), default=None,
                        help="the page, laid landscape (default a5)")
    parser.add_argument("--page-at", type=number(-0.5, 0.5, "m"), nargs=2,
                        metavar=("X", "Y"), default=None,
                        help="the page's centre on the table [m] in the base frame (default "
                        f"{PAGE_AT_DEFAULT[0]:g} {PAGE_AT_DEFAULT[1]:g})")
    parser.add_argument("--page-yaw", type=number(-180.0, 180.0, "deg"), default=None,
                        metavar="DEG", help="the page turned about the vertical [deg] (0, the "
                        "default: its top away from the arm)")
    parser.add_argument("--page-pose", type=Path, metavar="PATH",
                        help="the page, its centre and turn from register_page.py's file (the "
                        "marks touched on the real table), instead of --page, --page-at, "
                        "--page-yaw")
    parser.add_argument("--tilt-deg", type=number(*TILT_RANGE, "deg"), default=0.0,
                        help="the pen's lean from the vertical in the arm's plane, tip away "
                        f"from the base, {range_help(*TILT_RANGE, 'deg')} (default %(default)g)")
    parser.add_argument("--speed-mm-s", type=number(*SPEED_RANGE, "mm/s"),
                        default=DEFAULT_SPEED_MM_S, metavar="V",
                        help=f"the pen's speed on the paper, {range_help(*SPEED_RANGE, 'mm/s')} "
                        "(default %(default)g)")
    parser.add_argument("--no-lead", action="store_true",
                        help="send the plan as it is (no lead for the servo's lag): shows "
                        "what the lag does to the drawing")
    parser.add_argument("--headless", action="store_true",
                        help="no viewer (this program always runs offscreen)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    parser.add_argument("--image", type=Path, metavar="PATH.png",
                        help="write the page with the ink (and the target, faint) as a PNG")
    add_overwrite_argument(parser)
    arm = parser.add_argument_group("on an arm (through lerobot's bus; the virtual arm too)")
    arm.add_argument("--port", metavar="PORT",
                     help="the arm's serial port (virtual_so101.py prints the virtual arm's): "
                     "the same plan through lerobot's bus; the JSON's arm_tip is the tip's "
                     "read-back path against the strokes (the arm has no page that records ink)")
    add_calibration_argument(arm)
    arm.add_argument("--no-pen", action="store_true",
                     help="the arm holds no pen over a page (the virtual arm): its goals are "
                     "not offset for the pen's weight and push")
    add_servo_arguments(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    refused = (OutputPathError, PlanError, *ARM_NOT_STARTED)
    return run_script(parser, argv, _run, refused=refused,
                      interrupted=NOTHING_WRITTEN)


def _check_outputs(args: argparse.Namespace) -> tuple[Path | None, Path | None]:
    """The --json and --image paths, checked before anything runs."""
    inputs = [p for p in (args.svg, args.page_pose) if p]
    image = json_path = None
    if args.image is not None:
        image = check_output_path(args.image, "--image", inputs, args.overwrite,
                                  suffixes=(".png",), kind=PNG)
    if args.json is not None:
        json_path = check_output_path(args.json, "--json", inputs, args.overwrite, kind=REPORT)
        if json_path == image:
            raise OutputPathError(f"--json {args.json}: is the --image file too. Fix: give the "
                                  "report its own name, e.g. drawing.json.")
    return image, json_path


def _run_on_arm(args: argparse.Namespace, page: Page, strokes, json_path: Path | None) -> int:
    """--port: the plan through lerobot's bus (``lab/draw_arm.py``); the tip's path scored."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.lab.draw_arm import draw_on_arm
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    if args.image is not None:
        raise PlanError("--image with --port: the arm has no page that records ink (nothing "
                        "was run). Fix: leave out --image, or draw in the simulator first.")
    calibration = load_calibration(args.calibration or DEFAULT_CALIBRATION_PATH)
    report = draw_on_arm(args.port, calibration, strokes, page, PenPose(args.tilt_deg),
                         args.speed_mm_s, load=not args.no_pen)
    tip = report["arm_tip"]
    ended = "" if report["aborted"] is None else f" ABORTED ({report['aborted']})"
    count = report["strokes"]
    print(f"Drew {count} stroke{'s' if count != 1 else ''} on the arm at {args.port}{ended}: "
          "the tip's read-back path "
          + ("was never on the page" if tip["mean_mm"] is None else
             f"{tip['mean_mm']:.2f} mm mean, {tip['worst_mm']:.2f} mm worst from the strokes, "
             f"coverage {tip['coverage_pct']:.0f} %"))
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "draw.py"), indent=2) + "\n")
    return 0 if report["aborted"] is None else 1


def _page(args: argparse.Namespace) -> Page:
    """The page: from --page-pose's file, or from --page, --page-at and --page-yaw."""
    given = [name for name, value in (("--page", args.page), ("--page-at", args.page_at),
                                      ("--page-yaw", args.page_yaw)) if value is not None]
    if args.page_pose is None:
        name = args.page or "a5"
        return Page(name, PAGES[name], tuple(args.page_at or PAGE_AT_DEFAULT),
                    args.page_yaw or 0.0)
    if given:
        raise PlanError(f"--page-pose with {' and '.join(given)}: the file gives the page and "
                        f"its pose. Fix: leave out {' and '.join(given)}, or --page-pose.")
    return read_page_pose(args.page_pose)


def _run(args: argparse.Namespace) -> int:
    """Check the outputs, draw, report (see :func:`main`)."""
    image, json_path = _check_outputs(args)
    page = _page(args)
    strokes = drawing_strokes(args.height_mm, page, args.text, args.svg, args.shape, args.font)
    if args.port:
        return _run_on_arm(args, page, strokes, json_path)
    servo = servo_from_arguments(args)
    started = time.perf_counter()
    report, ink, prepared = run_drawing(strokes, page, PenPose(args.tilt_deg), args.speed_mm_s,
                                        servo, lead=not args.no_lead)
    report["run_s"] = round(time.perf_counter() - started, 1)
    report["source"] = ({"text": args.text, "font": args.font} if args.text is not None else
                        {"svg": str(args.svg)} if args.svg else {"shape": args.shape})
    report["height_mm"] = args.height_mm
    figures = report["ink"]
    if figures["mean_mm"] is None:
        line = "no ink on the page: the pen never pressed on it"
    else:
        line = (f"ink {figures['mean_mm']:.2f} mm mean, {figures['worst_mm']:.2f} mm worst from "
                f"the strokes; coverage {figures['coverage_pct']:.0f} %; longest stray ink "
                f"{figures['stray_mm']:.1f} mm")
    count = report["strokes"]
    print(f"Drew {count} stroke{'s' if count != 1 else ''} ({report['target_mm']:.0f} mm of "
          f"line) in {report['drawing_s']:.0f} s at {args.speed_mm_s:g} mm/s: {line}")
    if image is not None:
        save_drawing(image, page, prepared, ink, f"{line}\n{report['servo']}, "
                     f"{args.speed_mm_s:g} mm/s (target faint red, ink dark blue)")
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, "draw.py"), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
