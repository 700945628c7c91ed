"""Find the page's pose on the table from 3 or 4 marks touched with the pen's tip.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work
(``so101_kinematics/drawing/registration.py``: the fit; ``lab/page_touch.py``: the touches).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from so101_kinematics.cli import (
    NOTHING_WRITTEN,
    ArgumentParser,
    add_calibration_argument,
    number,
    run_script,
)
from so101_kinematics.drawing.page import PAGES
from so101_kinematics.drawing.registration import (
    MARK_INSET_MM,
    MARK_NAMES,
    MAX_RMS_MM,
    check_fit,
    fit_page,
    page_marks,
    read_touched_points,
)
from so101_kinematics.errors import (
    ARM_NOT_STARTED,
    OutputPathError,
    PlanError,
)
from so101_kinematics.outputs import (
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)

POSE_FILE = report_of("register_page.py")  # --out replaces only a page pose of this program
RMS_RANGE = (0.1, 20.0)  # [mm]


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, touch or read the points, fit, print, write; the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"""Mark crosses {MARK_INSET_MM:g} mm in from the page's corners and touch them
in the order {', '.join(MARK_NAMES)} (the page read the right way up; 3 marks:
the first three). The page's pose is the rotation about the vertical and
the translation that take the marks nearest the touched points (a rigid
fit: no scale); each point's residual and their RMS are printed. A fit
whose RMS is over --max-rms-mm is refused with its likely cause (points
touched in the wrong order, a page moved). draw.py --page-pose reads the
file --out writes.

Exit code: 0 fitted, 2 bad input or a fit refused (one line; nothing
written), 1 an unexpected error, 130 interrupted.""")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--port", help="the arm's serial port: torque off, touch each mark "
                        "with the pen's tip and press Enter")
    source.add_argument("--points", type=Path, metavar="FILE", help='touched points from a '
                        'JSON file {"points_m": [[x, y], ...]}, base frame [m]')
    add_calibration_argument(parser)
    parser.add_argument("--page", choices=tuple(PAGES), default="a5",
                        help="the page, laid landscape (default %(default)s)")
    parser.add_argument("--marks", type=int, choices=(3, 4), default=4,
                        help="how many marks are touched (default %(default)s)")
    parser.add_argument("--max-rms-mm", type=number(*RMS_RANGE, "mm"), default=MAX_RMS_MM,
                        metavar="MM", help="the largest RMS residual accepted [mm] (default "
                        "%(default)g)")
    parser.add_argument("--out", type=Path, metavar="PATH", required=True,
                        help="the page pose file to write (JSON; draw.py --page-pose reads it)")
    add_overwrite_argument(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show the traceback of an unexpected error")
    refused = (OutputPathError, PlanError, *ARM_NOT_STARTED)
    return run_script(parser, argv, _run, refused=refused,
                      interrupted=NOTHING_WRITTEN)


def _touched(args: argparse.Namespace):
    """The touched points (n, 2) [m]: from the file, or from the arm, torque off."""
    if args.points is not None:
        touched = read_touched_points(args.points)
        if len(touched) != args.marks:
            raise PlanError(f"--points {args.points}: {len(touched)} points for --marks "
                            f"{args.marks}. Fix: give --marks {len(touched)}, or "
                            f"{args.marks} points.")
        return touched
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.lab.page_touch import touch_marks
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    calibration = load_calibration(args.calibration or DEFAULT_CALIBRATION_PATH)
    print("Torque off: hold the arm. Touch each mark with the pen's tip, lightly.")
    return touch_marks(args.port, calibration, args.marks, input)


def _run(args: argparse.Namespace) -> int:
    """Check the output, get the points, fit, refuse or write (see :func:`main`)."""
    inputs = [args.points] if args.points else []
    out = check_output_path(args.out, "--out", inputs, args.overwrite, kind=POSE_FILE)
    marks = page_marks(args.page, args.marks)
    touched = _touched(args)
    fit = fit_page(marks, touched, args.page)
    for index, residual in enumerate(fit.residuals_mm):
        x, y = touched[index]
        print(f"mark {index + 1} ({MARK_NAMES[index]}): touched at ({x:.4f}, {y:.4f}) m, "
              f"residual {residual:.2f} mm")
    print(f"RMS residual {fit.rms_mm:.2f} mm")
    check_fit(fit, marks, touched, args.max_rms_mm)
    write_text_atomic(out, json.dumps(stamp(fit.as_json(), "register_page.py"), indent=2) + "\n")
    print(f"The {args.page.upper()} page's centre is at ({fit.centre[0]:.4f}, "
          f"{fit.centre[1]:.4f}) m, turned {fit.yaw:.2f} deg: written to {out} "
          f"(draw.py --page-pose {out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
