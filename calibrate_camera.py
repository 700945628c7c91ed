"""Calibrate the SO-101's cameras with a ChArUco board, in the simulator, graded against the model.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.

Three calibrations, each from views of the printed board (``so101 tags --board``):

1. the intrinsics of the overhead and the wrist camera (``cv2.calibrateCamera`` on the board's
   corners, the board held in front of each camera, tilted a different way each time);
2. hand-eye for the wrist camera: the board on the table, the arm posed N times; the gripper's
   pose from the arm's FK; ``cv2.calibrateHandEye`` gives the camera in the gripper frame;
3. eye to hand for the overhead camera: the board held in the jaws, the arm posed N times;
   the same solver on the inverted gripper poses gives the camera in the base frame.

In the simulator each result is graded against the model (the cameras' fovy and poses in the
MJCF); the issue's acceptance: focal lengths within 1 %, camera poses within 2 mm and 0.5 deg.
"""

from __future__ import annotations

import so101_kinematics.display as so101_display  # noqa: F401 - first: EGL without a display

# isort: split
import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from so101_kinematics.cli import EXIT_FAILED, NOTHING_WRITTEN, ArgumentParser, number, run_script
from so101_kinematics.errors import InputError, OpenCVMissing, VisionError
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.outputs import (
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)
from so101_kinematics.vision.calibration_grades import ACCEPTANCE, passes, run_calibration
from so101_kinematics.vision.calibration_photos import MOUNTS, POSES_FILE, calibrate_from_photos

PROGRAM = "calibrate_camera.py"
REPORT = report_of(PROGRAM)  # --json replaces only a report of this program
VIEWS = (4, 40)  # --views: from what the intrinsics need to what stays quick
MAX_SEED = 2**32 - 1


def summary(report: dict) -> str:
    """The report as a few lines: each result's error against the model and its residual."""
    lines = ["camera     fx error  fy error  reprojection RMS"]
    for camera in ("overhead", "wrist"):
        grade = report["intrinsics"][camera]
        lines.append(f"{camera:<10} {grade['fx_error_pct']:+7.3f} % {grade['fy_error_pct']:+7.3f}"
                     f" % {grade['rms_px']:8.3f} px ({grade['views_used']} views)")
    lines.append("pose                 error [mm]  error [deg]  residual [mm, deg]")
    names = {"wrist": "wrist in gripper", "fixed": "overhead in base"}
    for key, name in names.items():
        grade = report["hand_eye"][key]
        lines.append(f"{name:<20} {grade['translation_mm']:9.3f}  {grade['rotation_deg']:11.3f}"
                     f"  {grade['residual_mm']:.3f}, {grade['residual_deg']:.3f} "
                     f"({grade['views_used']} poses, {grade['method']})")
    verdict = "meets" if passes(report) else "does NOT meet"
    lines.append(f"The calibration {verdict} the acceptance (focal lengths within "
                 f"{ACCEPTANCE['focal_pct']:g} %, camera poses within "
                 f"{ACCEPTANCE['translation_mm']:g} mm and {ACCEPTANCE['rotation_deg']:g} deg).")
    return "\n".join(lines)


def photos_summary(report: dict) -> str:
    """A real camera's calibration: its numbers and residuals (no truth to grade against)."""
    grade = report["intrinsics"]
    K = grade["K"]
    lines = [f"intrinsics: fx {K[0][0]:.2f} px, fy {K[1][1]:.2f} px, centre ({K[0][2]:.1f}, "
             f"{K[1][2]:.1f}) px; reprojection RMS {grade['rms_px']:.3f} px "
             f"({grade['views_used']} pictures)"]
    for mount, pose in report.get("hand_eye", {}).items():
        key = MOUNTS[mount]
        position = 1000.0 * np.asarray(pose[key])[:3, 3]
        lines.append(f"{key}: at ({position[0]:.1f}, {position[1]:.1f}, {position[2]:.1f}) mm; "
                     f"residual {pose['residual_mm']:.2f} mm, {pose['residual_deg']:.2f} deg, "
                     f"{pose['chain_rms_px']:.3f} px ({pose['views_used']} poses)")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line, calibrate, print the summary; returns the exit code."""
    parser = ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="""The simulator renders each view headless (MUJOCO_GL=egl without a display),
with a webcam's blur and noise (seeded by --seed); the arm is posed by setting
its joints, as a student poses the real arm by hand with the torque off.

A real camera (--photos DIR): pictures of the printed board (so101 tags
--board) taken by the student, the arm posed by hand with the torque off and
its angles read by read_position.py; see docs/final_project.md ("On the real
arm").

Exit code: 0 done, 1 the board was seen in too few views or (with --strict) the
acceptance was not met, 2 bad input (options, output file, no OpenCV), 130
interrupted.""")
    parser.add_argument("--headless", action="store_true",
                        help="no window (the simulator's views are always rendered offscreen)")
    parser.add_argument("--views", type=number(*VIEWS, "views", integer=True), default=12,
                        help=f"views per calibration (board poses for the intrinsics, arm poses "
                        f"for each hand-eye), from {VIEWS[0]} to {VIEWS[1]} (default %(default)s)")
    parser.add_argument("--seed", type=number(0, MAX_SEED, integer=True), default=0,
                        help="seed of the views and of the image noise (default %(default)s)")
    parser.add_argument("--photos", type=Path, metavar="DIR",
                        help="calibrate a real camera from its pictures instead of the simulator: "
                        "DIR/intrinsics/*.png|jpg (the board, tilted), and for its pose "
                        f"DIR/{POSES_FILE} (image,{','.join(ARM_JOINTS)} [deg])")
    parser.add_argument("--mount", choices=sorted(MOUNTS), default="wrist",
                        help="with --photos: the camera on the gripper (the board on the table) "
                        "or fixed over the table (the board in the jaws) (default %(default)s)")
    parser.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    add_overwrite_argument(parser)
    parser.add_argument("--strict", action="store_true",
                        help="exit 1 unless every result meets the acceptance")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details (and show "
                        "the traceback of an unexpected error)")
    return run_script(parser, argv, _run, refused=(InputError, OpenCVMissing),
                      interrupted=NOTHING_WRITTEN)


def _run(args: argparse.Namespace) -> int:
    """Check the output, calibrate, report (see :func:`main`)."""
    require_opencv()  # before the output is touched: one line naming the fix
    json_path = None if args.json is None else check_output_path(
        args.json, "--json", kind=REPORT, overwrite=args.overwrite,
        inputs=[] if args.photos is None else [args.photos / POSES_FILE])
    try:
        if args.photos is not None:
            report = calibrate_from_photos(args.photos, args.mount)
        else:
            report = run_calibration(views=args.views, seed=args.seed)
    except VisionError as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_FAILED
    print(photos_summary(report) if args.photos is not None else summary(report))
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(stamp(report, PROGRAM), indent=2) + "\n")
        print(f"Report: {json_path}")
    graded = args.photos is None  # real pictures have no truth: the residuals are the grade
    return EXIT_FAILED if args.strict and graded and not passes(report) else 0


if __name__ == "__main__":
    sys.exit(main())
