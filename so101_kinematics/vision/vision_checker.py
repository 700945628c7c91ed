"""``so101-check-vision``: check a student's camera-to-base transform and tag pose, by name.

``so101-check-vision PATH/TO/my_vision.py`` (or ``so101 check-vision``) imports the file in
the checkers' sandbox (``checker/sandbox.py``: a child process, time-bounded, confined to a
temporary folder) and calls its ``camera_to_base`` and ``tag_pose_in_base``
(``checker/vision_compare.py`` states the call shapes) with the inputs of a few cameras
looking at the target tag in the simulator (``vision_cases.py``); each answer is compared
with the simulator's truth and, when wrong, with the usual mistakes' answers: OpenCV's
camera axes taken as MuJoCo's, the rotation transposed or the transform inverted, pixels
for metres, the tag's size in millimetres or the printed square's for the marker's.

Exit status: 0 both functions right, 1 one wrong or missing, 2 the file cannot be checked
(missing, crashes on import, times out, has neither function) or the options are wrong.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from so101_kinematics.checker import sandbox, vision_compare
from so101_kinematics.checker.fk import (
    add_class_options,
    check_outputs,
    exit_status,
    run_and_print,
    run_check,
)
from so101_kinematics.cli import EXIT_BAD_INPUT, ArgumentParser, number, range_help
from so101_kinematics.errors import OpenCVMissing, RenderError, VisionError
from so101_kinematics.outputs import report_of, stamp, write_text_atomic
from so101_kinematics.vision.vision_cases import vision_cases

__all__ = ["check_vision_file", "main", "vision_report"]

PROG = "so101-check-vision"
REPORT = report_of(PROG)  # --json/--gradescope replace only its own report
FUNCTIONS = tuple(vision_compare.VISION_POINTS)


def check_vision_file(path: str | Path, tolerance: dict | None = None,
                      timeout: float = sandbox.DEFAULT_TIMEOUT_S) -> dict:
    """Check one file's ``camera_to_base`` and ``tag_pose_in_base`` in a child process.

    Returns:
        A JSON-ready dict: file, student, verdict ("pass", "fail", "error"), reason, tests
        (one per function: ``vision_compare.judge_vision``), the module's output, seconds.
    """
    tolerance = dict(vision_compare.VISION_TOLERANCE, **(tolerance or {}))
    if not Path(path).is_file():  # said as the other checkers say it, nothing rendered
        return run_check(path, {}, [list(t) for t in tolerance.values()], timeout)[0]
    cases = list(vision_cases())
    stem = Path(path).stem
    check, run = run_check(path, vision_compare.build_request(
        cases, stem if stem.isidentifier() else "student_vision"),
        [list(t) for t in tolerance.values()], timeout)
    if run is None:
        return check
    if run.status in ("import_error", "timeout") or "names" not in run.results:
        check["reason"] = run.reason or "the module could not be imported"
        return check
    if not any(name in run.results["names"] for name in FUNCTIONS):
        check["reason"] = (f"it defines neither {' nor '.join(FUNCTIONS)} (it defines "
                           f"{', '.join(run.results['names']) or 'no functions'})")
        return check
    check["tests"] = vision_compare.judge_vision(run.results, cases, tolerance)
    if run.status != "ok":
        check["reason"] = run.reason
        return check
    check["verdict"] = "pass" if all(t["status"] == "ok" for t in check["tests"]) else "fail"
    return check


def _score(check: dict) -> float:
    return sum(vision_compare.VISION_POINTS[t["function"]] for t in check["tests"]
               if t["status"] == "ok")


def test_text(test: dict) -> str:
    """One function's line and its causes."""
    if test["status"] == "missing":
        return f"{test['function']}: MISSING"
    error = "" if test["max_error_mm"] is None else f", worst {test['max_error_mm']:.2f} mm"
    if test["max_error_deg"] is not None:
        error += f", {test['max_error_deg']:.2f} deg"
    lines = [f"{test['function']}: {'ok' if test['status'] == 'ok' else 'WRONG'}{error} "
             f"against the simulator's truth ({test['count']} answers)"]
    return "\n".join(lines + [f"  {cause}" for cause in test["causes"]])


def vision_report(check: dict) -> str:
    """The short report a student reads; its last line is the verdict."""
    tolerance = check["tolerance"]
    lines = [f"Checking {check['file']} (tolerance: camera_to_base {tolerance[0][0]:g} mm; "
             f"tag_pose_in_base {tolerance[1][0]:g} mm, {tolerance[1][1]:g} deg)"]
    if check["verdict"] == "error":
        lines.append(f"Cannot check it: {check['reason']}")
    lines += [test_text(test) for test in check["tests"]]
    if check.get("output_size"):
        shown = " | ".join((check.get("output") or "").strip().splitlines()[:3])[:200]
        lines.append(f"(your module printed {check['output_size']} characters: {shown})")
    verdict = {"pass": "OK: both functions agree with the simulator",
               "fail": "not right yet", "error": "not checked"}[check["verdict"]]
    lines.append(f"Verdict: {verdict}. Score {_score(check):g}/"
                 f"{sum(vision_compare.VISION_POINTS.values()):g}.")
    return "\n".join(lines)


def gradescope_results(check: dict) -> dict:
    """Gradescope's autograder ``results.json``: one test per function."""
    tests = []
    for name, points in vision_compare.VISION_POINTS.items():
        test = next((t for t in check["tests"] if t["function"] == name), None)
        passed = test is not None and test["status"] == "ok"
        tests.append({"name": name, "score": points if passed else 0.0, "max_score": points,
                      "status": "passed" if passed else "failed",
                      "output": test_text(test) if test else f"not checked: {check['reason']}"})
    return {"score": _score(check), "execution_time": round(check["seconds"], 2),
            "output": vision_report(check).splitlines()[-1], "visibility": "visible",
            "stdout_visibility": "hidden", "tests": tests}


def build_parser() -> ArgumentParser:
    """The command line."""
    parser = ArgumentParser(prog=PROG, description=(
        "Check camera_to_base(cam_pos, cam_xmat, p_cam) and tag_pose_in_base(corners, K, "
        "cam_pos, cam_xmat) against the simulator's truth over several camera poses: what "
        "is wrong and why (OpenCV vs MuJoCo camera axes, a transposed rotation, pixels vs "
        "metres, the tag's size)."))
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE",
                        help="one or more files defining the two functions")
    parser.add_argument("--tolerance-mm", type=number(0, 1000, "mm", low_open=True),
                        default=vision_compare.VISION_TOLERANCE["tag_pose_in_base"][0],
                        help=f"tag_pose_in_base's position tolerance, "
                        f"{range_help(0, 1000, 'mm', True)} (5; camera_to_base: 1 mm)")
    parser.add_argument("--tolerance-deg", type=number(0, 180, "deg", low_open=True),
                        default=vision_compare.VISION_TOLERANCE["tag_pose_in_base"][1],
                        help=f"its rotation tolerance, {range_help(0, 180, 'deg', True)} (3)")
    parser.add_argument("--timeout", type=number(0.5, 600, "s"), default=sandbox.DEFAULT_TIMEOUT_S,
                        help=f"time per file, {range_help(0.5, 600, 's')} (10)")
    parser.add_argument("--json", type=Path, help="write the full comparison (JSON)")
    parser.add_argument("--gradescope", type=Path, metavar="RESULTS_JSON",
                        help="write Gradescope's results.json (one file only)")
    add_class_options(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the checker; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.gradescope and len(args.files) > 1:
        parser.error("--gradescope writes one submission's results.json; got "
                     f"{len(args.files)} files. Fix: run once per submission")
    outputs = check_outputs(args, {"json": REPORT, "gradescope": REPORT}, PROG)
    if outputs is None:
        return EXIT_BAD_INPUT
    tolerance = {"tag_pose_in_base": (args.tolerance_mm, args.tolerance_deg)}
    try:  # rendered once, here (one OpenGL context), before the files' threads
        if any(Path(path).is_file() for path in args.files):
            vision_cases()
    except (OpenCVMissing, RenderError, VisionError) as error:
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    checks = run_and_print(
        args.files, lambda path: check_vision_file(path, tolerance, args.timeout),
        vision_report, args.jobs, args.quiet)
    if "json" in outputs:
        stamped = stamp(checks, PROG)
        write_text_atomic(outputs["json"], json.dumps(stamped[0] if len(stamped) == 1
                                                      else stamped, indent=1))
    if "gradescope" in outputs:
        results = gradescope_results(checks[0])
        results["extra_data"] = stamp({}, PROG)
        write_text_atomic(outputs["gradescope"], json.dumps(results, indent=1))
    return exit_status(checks)


if __name__ == "__main__":
    sys.exit(main())
