"""so101: the project's tools, one subcommand each, beside the course's own scripts.

The course's files (``pick_place_sim.py``, ``pick_place_hw.py``, ...) run the week's
assignment; the tools that work on their outputs live here::

    so101 compare run.csv --report report.png      # a hardware log replayed in the simulator
    so101 sheet sheet.pdf --paper letter           # the placement sheet (print at 100 %)
    so101 tags tags.pdf                            # the ArUco tags, true size (print at 100 %)
    so101 tags board.pdf --board                   # the ChArUco calibration board, true size
    so101 check-fk my_fk.py                        # the checkers (as so101-check-fk/ik/traj/vision)
    so101 virtual-calibration my_arm.json          # the virtual arm's calibration file

Also ``python -m so101_kinematics ...``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from so101_kinematics import outputs
from so101_kinematics.cli import NOTHING_WRITTEN, ArgumentParser, run_script
from so101_kinematics.errors import InputError, OpenCVMissing

__all__ = ["COMPARE_REPORT", "MOVED_FROM_HW", "MOVED_FROM_SIM", "MOVED_FROM_VIRTUAL", "main"]

PROG = "so101"

COMPARE_REPORT = outputs.report_of(PROG)
"""``so101 compare --json`` replaces only a report of this command (or with --overwrite)."""

MOVED_FROM_SIM = {
    "--compare": "so101 compare LOG.csv [LOG.csv ...] --report PATH.png [--json PATH]",
    "--report": "so101 compare LOG.csv [LOG.csv ...] --report PATH.png [--json PATH]",
}
"""pick_place_sim.py's old options -> their new spelling (refused in one line, exit 2)."""

MOVED_FROM_HW = {
    "--sheet": "so101 sheet PATH.pdf [--paper a4|letter] [--plan | --pick/--place | --stack]",
    "--paper": "so101 sheet PATH.pdf --paper a4|letter",
}
"""pick_place_hw.py's old options -> their new spelling (refused in one line, exit 2)."""

MOVED_FROM_VIRTUAL = {
    "--write-default-calibration": "so101 virtual-calibration PATH [--overwrite]",
    "--force": "so101 virtual-calibration PATH --overwrite",
}
"""virtual_so101.py's old options -> their new spelling (refused in one line, exit 2)."""


def _checker(module: str) -> Callable[[list[str]], int]:
    def run(argv: list[str]) -> int:
        from importlib import import_module
        return import_module(module if "." in module
                             else f"so101_kinematics.checker.{module}").main(argv)
    return run


CHECKERS = {"check-fk": ("fk", "check a student's forward kinematics (as so101-check-fk)"),
            "check-ik": ("ik", "check a student's inverse kinematics (as so101-check-ik)"),
            "check-traj": ("traj", "check a student's cubic move (as so101-check-traj)"),
            "check-vision": ("so101_kinematics.vision.vision_checker",
                             "check a student's camera-to-base transform and tag pose (as "
                             "so101-check-vision)")}


def build_parser() -> argparse.ArgumentParser:
    """The ``so101`` parser: one subparser per tool."""
    parser = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0],
                            formatter_class=argparse.RawDescriptionHelpFormatter,
                            epilog="Run `so101 SUBCOMMAND --help` for a subcommand's options.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND",
                                parser_class=ArgumentParser)
    compare = sub.add_parser(
        "compare", help="replay hardware logs in the simulator and compare (the lab's report)",
        description="Replay hardware logs (pick_place_hw.py --log, e.g. one per --profile) in "
                    "the simulator and compare, per profile the arm beside the simulator.")
    compare.add_argument("logs", type=Path, nargs="+", metavar="LOG.csv")
    compare.add_argument("--report", type=Path, metavar="PATH.png", required=True,
                         help="the comparison's figure")
    compare.add_argument("--json", type=Path, metavar="PATH", help="the comparison as JSON")
    sheet = sub.add_parser(
        "sheet", help="the placement sheet of a plan (PDF, print at 100 %%); no arm needed",
        description="Write the placement sheet of a plan: where the cubes start and go, true "
                    "to size (print at 100 %).")
    sheet.add_argument("sheet", type=Path, metavar="PATH.pdf")
    sheet.add_argument("--paper", choices=("a4", "letter"), default="a4",
                       help="paper (default a4)")
    sheet.add_argument("--plan", type=Path, help="waypoint file (JSON or TOML) instead of the "
                       "course's plan")
    from so101_kinematics.planning.cartesian_plan import add_cartesian_arguments
    from so101_kinematics.planning.stacking import add_stack_arguments
    add_cartesian_arguments(sheet)
    add_stack_arguments(sheet)
    tags = sub.add_parser(
        "tags", help="the ArUco tags of the cube and the target (PDF, print at 100 %%)",
        description="Write the ArUco tags (the cube's and the target's), or with --board the "
                    "ChArUco calibration board, at their true size on an A4 page, the same "
                    "images as the simulator's textures. Needs OpenCV (the hw extra).")
    tags.add_argument("tags", type=Path, metavar="PATH.pdf")
    tags.add_argument("--board", action="store_true", help="write the ChArUco calibration "
                      "board instead (calibrate_camera.py; A4, print at 100 %%)")
    calibration = sub.add_parser(
        "virtual-calibration", help="write the virtual arm's calibration (from the model)",
        description="Write the lerobot calibration the virtual SO-101 ships with, derived from "
                    "the model, to PATH.")
    calibration.add_argument("path", type=Path, metavar="PATH")
    for name, (_, text) in CHECKERS.items():
        sub.add_parser(name, help=text, add_help=False)
    for command in (compare, sheet, tags, calibration):
        outputs.add_overwrite_argument(command)
        command.add_argument("-v", "--verbose", action="store_true", help="log details (and "
                             "show the traceback of an unexpected error)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one subcommand; returns its exit code (2: bad input, nothing was run)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in CHECKERS:  # the checker parses its own options
        try:
            return _checker(CHECKERS[argv[0]][0])(argv[1:])
        except SystemExit as stop:  # its one-line refusal (or --help): the exit code
            return stop.code
    parser = build_parser()
    work = {"compare": _compare, "sheet": _sheet, "tags": _tags,
            "virtual-calibration": _virtual_calibration}
    return run_script(parser, argv, lambda args: work[args.command](args),
                      refused=(InputError, OpenCVMissing),
                      interrupted=NOTHING_WRITTEN)


def _compare(args: argparse.Namespace) -> int:
    """The sim-versus-arm report.

    One log: its report, then its profile's figures; several: the profiles' table.
    """
    from so101_kinematics.hw.log import sidecar_path
    from so101_kinematics.lab.profile_compare import compare_profiles, draw_profiles
    from so101_kinematics.lab.sim_vs_arm import draw_report

    inputs = [p for log in args.logs for p in (log, sidecar_path(log))]
    report = outputs.check_output_path(args.report, "--report", inputs=inputs,
                                       suffixes=(".png",), kind=outputs.PNG,
                                       overwrite=args.overwrite)
    json_path = args.json and outputs.check_output_path(
        args.json, "--json", inputs=inputs, kind=COMPARE_REPORT, overwrite=args.overwrite)
    profiles = compare_profiles(args.logs)
    if len(profiles.runs) == 1:
        result = profiles.runs[0].comparison
        print(result.summary())
        print(f"Report: {draw_report(result, report, f'{args.logs[0]}: simulator vs arm')}")
        comparison = {**result.as_json(), "profile_comparison": profiles.as_json()}
    else:
        print(f"Report: {draw_profiles(profiles, report, 'profiles: simulator vs arm')}")
        comparison = profiles.as_json()
    print(profiles.table())
    if json_path:
        outputs.write_text_atomic(json_path, json.dumps(
            outputs.stamp(comparison, f"{PROG} compare"), indent=2) + "\n")
    return 0


def _sheet(args: argparse.Namespace) -> int:
    """The placement sheet of the course's plan, a waypoint file, --pick/--place or a stack."""
    from so101_kinematics.hw.preflight import validate_plan_for_arm
    from so101_kinematics.lab.sheet import write_sheet
    from so101_kinematics.planning.cartesian_plan import plan_from_arguments
    from so101_kinematics.planning.plans import default_plan, load_plan
    from so101_kinematics.planning.stacking import stack_from_arguments

    stack = stack_from_arguments(args)
    plan = stack.plan if stack else plan_from_arguments(args) or (
        load_plan(args.plan) if args.plan else default_plan())
    validate_plan_for_arm(plan, None, base_height=args.base_height)
    path = outputs.check_output_path(args.sheet, "so101 sheet", inputs=(args.plan,),
                                     suffixes=(".pdf",), kind=outputs.PDF,
                                     overwrite=args.overwrite)
    origin = args.plan or ("--pick/--place" if args.pick else "the course's plan")
    print(write_sheet(plan, path, args.paper, source=str(origin), stack=stack,
                      base_height=args.base_height).summary())
    return 0


def _tags(args: argparse.Namespace) -> int:
    """The printable ArUco tags (vision/tags.py) or ChArUco board (vision/boards.py), 1:1."""
    from so101_kinematics.opencv_import import require_opencv
    from so101_kinematics.sim.tag_textures import TAG_DICTIONARY, TAGS
    from so101_kinematics.vision.boards import CALIBRATION_BOARD, write_board_sheet
    from so101_kinematics.vision.tags import write_tag_sheet

    require_opencv()  # before the output is touched: one line naming the fix
    path = outputs.check_output_path(args.tags, "so101 tags", suffixes=(".pdf",),
                                     kind=outputs.PDF, overwrite=args.overwrite)
    if args.board:
        write_board_sheet(path)
        board = CALIBRATION_BOARD
        print(f"ChArUco board ({TAG_DICTIONARY}, {board.squares[0]} x {board.squares[1]} squares "
              f"of {board.square * 1000:.0f} mm, markers {board.marker * 1000:.0f} mm) written "
              f"to {path}; print at 100 %, check the 50 mm bar with a ruler, glue it flat.")
        return 0
    write_tag_sheet(path)
    names = ", ".join(f"{t.name} id {t.tag_id} ({t.size * 1000:.0f} mm)" for t in TAGS.values())
    print(f"Tags ({TAG_DICTIONARY}: {names}) written to {path}; print at 100 % and check the "
          "50 mm bar with a ruler.")
    return 0


def _virtual_calibration(args: argparse.Namespace) -> int:
    """The calibration the virtual SO-101 ships with (derived from the model), to a file."""
    from so101_kinematics.sim.scene import load_model
    from so101_kinematics.virtual.shipped_calibration import make_default_calibration

    path = outputs.check_output_path(args.path, "so101 virtual-calibration",
                                     overwrite=args.overwrite)
    outputs.write_text_atomic(path, json.dumps(make_default_calibration(load_model()),
                                               indent=4) + "\n")
    print(f"Calibration written to {path}")
    return 0
