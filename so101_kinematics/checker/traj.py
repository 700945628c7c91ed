"""``so101-check-traj``: check a student's ``move_to_pose_cubic`` (assignment 9) move by move.

``so101-check-traj PATH/TO/so101_mujoco_utils.py`` (or ``python -m
so101_kinematics.checker.traj PATH``) imports the file in the checkers' sandbox with
MuJoCo replaced by a recording stand-in (:mod:`.traj_probe`), runs
``move_to_pose_cubic(m, d, viewer, desired_position, duration)`` (or the explicit-start
shape ``(m, d, viewer, starting_position, desired_position, duration)``) on a few moves,
and compares every command with the course's cubic (:mod:`.traj_compare`): which
coefficient is wrong, time not clipped, a velocity that is not zero at an end, the
duration's or the angles' unit, a loop that never ends, the start ignored.

The file's own imports are its own: a ``so101_mujoco_utils`` beside it is used, else a
stand-in with the course's conversions. Exit status: 0 when every move is right, 1 when
one is not, 2 when the file cannot be checked (missing, crashes on import, times out, no
``move_to_pose_cubic``) or the options are wrong.
"""

from __future__ import annotations

import difflib
import json
import sys
from pathlib import Path

from so101_kinematics.checker import traj_compare
from so101_kinematics.checker.fk import (
    add_class_options,
    check_outputs,
    exit_status,
    run_and_print,
    run_check,
)
from so101_kinematics.cli import EXIT_BAD_INPUT, ArgumentParser, number, range_help
from so101_kinematics.outputs import report_of, stamp, write_text_atomic

__all__ = ["POINTS", "check_traj_file", "gradescope_results", "main"]

REPORT = report_of("so101-check-traj")  # --json/--gradescope replace only its own report

PROBE = Path(__file__).with_name("traj_probe.py")

DEFAULT_TIMEOUT_S = 20.0
"""Time a file gets for its import and every move together [s] (each move also has
``traj_compare.WALL_S``)."""

POINTS = {"forward": 40.0, "backward": 40.0, "zero": 20.0}
"""Gradescope points per move (100 in all)."""

SHAPES = {5: "move_to_pose_cubic(m, d, viewer, desired_position, duration)",
          6: "move_to_pose_cubic(m, d, viewer, starting_position, desired_position, duration)"}


def check_traj_file(path: str | Path, tolerance_deg: float = traj_compare.TOLERANCE_DEG,
                    timeout: float = DEFAULT_TIMEOUT_S) -> dict:
    """Check one file's ``move_to_pose_cubic``; the student's code runs in a child process.

    Args:
        path: the student's file (``so101_mujoco_utils.py`` or a script defining the function).
        tolerance_deg: how far a command may be from the course's cubic [deg].
        timeout: time the file gets for its import and all moves [s].

    Returns:
        A JSON-ready dict: file, student, verdict ("pass", "fail", "error"), reason, shape,
        tests (one per move: see :func:`traj_compare.judge`), causes (every distinct one),
        the module's output, seconds.
    """
    stem = Path(path).stem
    check, run = run_check(path, traj_compare.build_request(
        stem if stem.isidentifier() else "student_move"), (tolerance_deg,), timeout, probe=PROBE)
    check.update(causes=[], shape="")
    if run is None:
        return check
    if run.status == "import_error" or "names" not in run.results:
        check["reason"] = run.reason or "the module could not be imported"
        return check
    names = run.results["names"]
    if "move_to_pose_cubic" not in names:
        close = difflib.get_close_matches("move_to_pose_cubic", names, n=1, cutoff=0.6)
        check["reason"] = "no function move_to_pose_cubic" + (
            f" (did you mean to name {close[0]!r} move_to_pose_cubic?)" if close else
            f"; it defines {', '.join(names) or 'no functions'}")
        return check
    check["shape"] = SHAPES.get(run.results.get("parameters"),
                                f"{run.results.get('parameters')} positional parameters "
                                "(called as the 5-parameter shape)")
    check["tests"] = traj_compare.judge(run.results, tolerance_deg)
    check["causes"] = traj_compare.summary(check["tests"])
    if run.status != "ok":
        check["reason"] = run.reason
        return check
    right = [t for t in check["tests"] if t["status"] == "ok"]
    check["verdict"] = "pass" if len(right) == len(traj_compare.MOVES) else "fail"
    return check


def test_text(test: dict) -> str:
    """One move's line and its causes."""
    error = ("" if test["max_error_deg"] is None
             else f", up to {test['max_error_deg']:.2f} deg off the course's cubic")
    lines = [f"{test['function']} ({test['what']}, {test['duration']:g} s): "
             f"{test['status'].upper() if test['status'] != 'ok' else 'ok'}{error}; "
             f"{test['steps']} steps (expected {test['expected_steps']})"
             + ("; velocity feed-forward checked" if test.get("velocity_commands") else "")]
    return "\n".join(lines + [f"  {cause}" for cause in test["causes"]])


def text_report(check: dict) -> str:
    """The short report a student reads; its last line is the verdict."""
    lines = [f"Checking {check['file']} (tolerance {check['tolerance'][0]:g} deg; "
             f"{check['shape'] or 'move_to_pose_cubic'} against a recording stand-in)"]
    if check["verdict"] == "error":
        lines.append(f"Cannot check it: {check['reason']}")
    lines += [test_text(test) for test in check["tests"]]
    if check["causes"] and check["verdict"] != "pass":
        lines.append("What to fix:")
        lines += [f"  - {cause}" for cause in check["causes"]]
    if check.get("output_size"):
        shown = " | ".join((check.get("output") or "").strip().splitlines()[:3])[:200]
        lines.append(f"(your module printed {check['output_size']} characters: {shown})")
    score = sum(p for name, p in POINTS.items() if _passed(check, name))
    verdict = {"pass": "OK: every move follows the course's cubic",
               "fail": "not the course's cubic", "error": "not checked"}[check["verdict"]]
    lines.append(f"Verdict: {verdict}. Score {score:g}/{sum(POINTS.values()):g}.")
    return "\n".join(lines)


def _passed(check: dict, move: str) -> bool:
    return any(t["move"] == move and t["status"] == "ok" for t in check["tests"])


def gradescope_results(check: dict) -> dict:
    """Gradescope's autograder ``results.json``: one test per move."""
    tests = []
    for move in traj_compare.MOVES:
        test = next((t for t in check["tests"] if t["move"] == move["name"]), None)
        passed = _passed(check, move["name"])
        tests.append({"name": f"move_to_pose_cubic: {move['what']}",
                      "score": POINTS[move["name"]] if passed else 0.0,
                      "max_score": POINTS[move["name"]], "status": "passed" if passed else
                      "failed", "output": test_text(test) if test else
                      f"not checked: {check['reason'] or 'an earlier move never ended'}"})
    summary = text_report(check).splitlines()[-1]
    if check["verdict"] == "error":
        summary = f"Could not check your file: {check['reason']}"
    return {"score": sum(t["score"] for t in tests), "execution_time": round(check["seconds"], 2),
            "output": summary + "".join(f"\n- {c}" for c in check["causes"]),
            "visibility": "visible", "stdout_visibility": "hidden", "tests": tests}


def build_parser() -> ArgumentParser:
    """The command line."""
    parser = ArgumentParser(prog="so101-check-traj", description=(
        "Check move_to_pose_cubic (assignment 9's cubic move) against the course's cubic on a "
        "few moves, with MuJoCo replaced by a recording stand-in: what is wrong and why."))
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE",
                        help="one or more files defining move_to_pose_cubic")
    parser.add_argument("--tolerance-deg", type=number(0, 90, "deg", low_open=True),
                        default=traj_compare.TOLERANCE_DEG,
                        help=f"{range_help(0, 90, 'deg', True)} ({traj_compare.TOLERANCE_DEG:g})")
    parser.add_argument("--timeout", type=number(1, 600, "s"), default=DEFAULT_TIMEOUT_S,
                        help=f"time per file, {range_help(1, 600, 's')} ({DEFAULT_TIMEOUT_S:g})")
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
    outputs = check_outputs(args, {"json": REPORT, "gradescope": REPORT},
                            "so101-check-traj")
    if outputs is None:
        return EXIT_BAD_INPUT
    checks = run_and_print(
        args.files, lambda path: check_traj_file(path, args.tolerance_deg, args.timeout),
        text_report, args.jobs, args.quiet)
    if "json" in outputs:
        stamped = stamp(checks, "so101-check-traj")
        write_text_atomic(outputs["json"], json.dumps(stamped[0] if len(stamped) == 1
                                                      else stamped, indent=1))
    if "gradescope" in outputs:
        results = gradescope_results(checks[0])
        results["extra_data"] = stamp({}, "so101-check-traj")
        write_text_atomic(outputs["gradescope"], json.dumps(results, indent=1))
    return exit_status(checks)


if __name__ == "__main__":
    sys.exit(main())
