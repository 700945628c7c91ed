"""``so101-check-ik``: check a student's IK (assignment 7's shape) with this package's FK.

``so101-check-ik PATH/TO/so101_inverse_kinematics.py`` (or ``python -m
so101_kinematics.checker.ik PATH``) runs ``get_inverse_kinematics(target_position,
target_orientation)`` in a child process with a time limit (the FK checker's sandbox) at
reachable top-down targets across the workspace (:mod:`.ik_targets`), checks FK(IK(p))
with this package's FK and says where and why it fails (:mod:`.ik_compare`).

The student's module may import its own ``so101_forward_kinematics`` from beside it; with
none there, the checker's fallback (this package's factors, the course's names) is used,
and the report says which.

Exit status: 0 when every file is within the tolerance, 1 when one is outside it, 2 when
one cannot be checked (missing, crashes on import, times out) or the options are wrong.
"""

from __future__ import annotations

import csv
import io
import json
import sys
from pathlib import Path

from so101_kinematics.checker import ik_compare, ik_targets, sandbox
from so101_kinematics.checker.fk import (
    add_class_options,
    add_tolerance_options,
    check_outputs,
    exit_status,
    run_and_print,
    run_check,
)
from so101_kinematics.cli import EXIT_BAD_INPUT, ArgumentParser, number
from so101_kinematics.outputs import csv_kind, report_of, stamp, write_text_atomic

__all__ = ["check_ik_file", "main"]

REPORT = report_of("so101-check-ik")  # --json replaces only its own report


def check_ik_file(path: str | Path, tolerance=(1.0, 1.0),
                  timeout: float = sandbox.DEFAULT_TIMEOUT_S,
                  count: int = ik_targets.TARGET_COUNT) -> dict:
    """Check one IK module; the student's code runs in a child process.

    Args:
        path: the student's ``so101_inverse_kinematics.py``.
        tolerance: (position [mm], angle [deg]) every answer must be within.
        timeout: time the module gets for its import and all calls [s].
        count: random targets (the named ones come on top).

    Returns:
        A JSON-ready dict: file, student, verdict ("pass", "fail", "error"), reason,
        tests (one: see :func:`ik_compare.compare_ik`), note, the module's output, seconds.
        A time-out during the calls is an "error" whose test judges the answers before it.
    """
    check, run = run_check(path, ik_compare.build_request(count), tolerance, timeout)
    if run is None:
        return check
    if run.status == "import_error" or not run.results.get("names"):
        check["reason"] = run.reason or "the module could not be imported"
        return check
    test = ik_compare.compare_ik(run.results, tolerance, count)
    check["tests"] = [test] if test.get("targets", 1) else []
    fk = test.get("fk_module")
    check["note"] = ("" if fk is None else
                     "Your module imports no so101_forward_kinematics." if fk == "" else
                     "No so101_forward_kinematics.py beside your file: the checker's "
                     "(this package's factors) was used." if fk == "fallback" else
                     f"Your so101_forward_kinematics was used: {fk}.")
    if run.status != "ok":  # a hang or a crash in a call: the answers before it are judged
        check["reason"] = run.reason
        if run.status == "timeout":
            check["reason"] += " (or an IK that is only slow: give it more time with --timeout)"
        return check
    check["verdict"] = "pass" if test["status"] == "ok" else "fail"
    return check


def _zones(rows: list[dict]) -> str:
    return ", ".join(f"{row['name']} {row['failing']}/{row['targets']}" for row in rows)


def text_report(check: dict) -> str:
    """The short report a student reads."""
    tolerance = check["tolerance"]
    lines = [f"Checking {check['file']} (tolerance {tolerance[0]:g} mm, {tolerance[1]:g} deg; "
             "FK(IK(p)) with so101_kinematics' FK)"]
    if check["verdict"] == "error":
        lines.append(f"Cannot check it: {check['reason']}")
    for test in check["tests"]:
        if "counts" not in test:
            lines.append(f"{test['function']}: {test['status'].upper()}: "
                         + "; ".join(test["causes"]))
            continue
        counts = test["counts"]
        lines.append(
            f"get_inverse_kinematics: {counts['right']} of {test['targets']} reachable top-down "
            f"targets right; wrong {counts['wrong']}, NaN {counts['nan']}, raised "
            f"{counts['raised']}, malformed {counts['broken']}")
        if test["error_mm"]["max"] is not None:
            lines.append(f"  errors: position median {test['error_mm']['median']:.2f} mm, max "
                         f"{test['error_mm']['max']:.2f} mm; z tilt max "
                         f"{test['tilt_deg']['max']:.2f} deg; yaw (mod 90) max "
                         f"{test['yaw_error_deg']['max']:.2f} deg")
        lines += [f"  {cause}" for cause in test["causes"]]
        if test["status"] != "ok":
            lines.append("  failing / targets by reach: " + _zones(test["by_reach"]))
            lines.append("  by side: " + _zones(test["by_side"]))
            lines.append("  by height: " + _zones(test["by_height"]))
            lines.append("  by branch: " + _zones(test["by_branch"]))
            for example in test["examples"]:
                if example["error_mm"] is None:
                    got = "returned NaN" if example["kind"] == "nan" else example["problem"]
                else:
                    got = (f"{example['error_mm']} mm, tilt {example['tilt_deg']} deg, yaw "
                           f"{example['yaw_error_deg']} deg off" + (
                               f", beyond the limit: {', '.join(example['beyond'])}"
                               if example["beyond"] else "")
                           + f"; answer {example['answer_deg']}")
                lines.append(f"  e.g. target {example['target']} m, yaw {example['yaw_deg']} deg: "
                             + got)
        for answer in test["out_of_reach"]:
            lines.append(f"  out of reach (not graded), {answer['name']}: {answer['answer']}")
        if test["at_limit"]:
            lines.append("  at a limit (within 0.5 deg, allowed): " + ", ".join(
                f"{joint} {n}" for joint, n in test["at_limit"].items()))
    if check.get("note"):
        lines.append(check["note"].strip())
    if check.get("output_size"):
        shown = " | ".join((check.get("output") or "").strip().splitlines()[:3])[:200]
        lines.append(f"(your module printed {check['output_size']} characters: {shown})")
    verdict = {"pass": "within the tolerance", "fail": "outside the tolerance",
               "error": "not checked"}[check["verdict"]]
    lines.append(f"Verdict: {verdict}.")
    return "\n".join(lines)


CSV_COLUMNS = ("student", "file", "verdict", "targets", "right", "wrong", "nan", "raised",
               "malformed", "max_mm", "median_mm", "max_deg", "causes", "seconds")


def csv_report(checks: list[dict]) -> str:
    """One row per submission (the folder name is the student)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for check in checks:
        test = next((t for t in check["tests"] if "counts" in t), None)
        counts = test["counts"] if test else {}
        writer.writerow({
            "student": check["student"], "file": check["file"], "verdict": check["verdict"],
            "targets": test["targets"] if test else 0, "right": counts.get("right", 0),
            "wrong": counts.get("wrong", 0), "nan": counts.get("nan", 0),
            "raised": counts.get("raised", 0), "malformed": counts.get("broken", 0),
            "max_mm": _round(test and test["error_mm"]["max"]),
            "median_mm": _round(test and test["error_mm"]["median"]),
            "max_deg": _round(test and test["max_error_deg"]),
            "causes": " | ".join([check["reason"]] if check["reason"] else
                                 [c for t in check["tests"] for c in t["causes"]]),
            "seconds": round(check["seconds"], 2)})
    return buffer.getvalue()


def _round(value) -> str:
    return "" if value is None else f"{value:.3f}"


def build_parser() -> ArgumentParser:
    """The command line."""
    parser = ArgumentParser(prog="so101-check-ik", description=(
        "Check so101_inverse_kinematics.py (get_inverse_kinematics(target_position, "
        "target_orientation) -> joint angles [deg]) with the so101_kinematics FK: where it "
        "fails and why."))
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE",
                        help="one or more so101_inverse_kinematics.py files")
    add_tolerance_options(parser)
    parser.add_argument("--targets", type=number(1, 100000, integer=True),
                        default=ik_targets.TARGET_COUNT,
                        help=f"random targets, half on the table ({ik_targets.TARGET_COUNT})")
    parser.add_argument("--json", type=Path, help="write the full comparison (JSON)")
    parser.add_argument("--csv", type=Path, help="write one row per file")
    add_class_options(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the checker; returns the exit status."""
    args = build_parser().parse_args(argv)
    outputs = check_outputs(args, {"json": REPORT,
                                   "csv": csv_kind(CSV_COLUMNS, "a CSV of so101-check-ik")},
                            "so101-check-ik")
    if outputs is None:
        return EXIT_BAD_INPUT
    tolerance = (args.tolerance_mm, args.tolerance_deg)
    checks = run_and_print(
        args.files, lambda path: check_ik_file(path, tolerance, args.timeout, args.targets),
        text_report, args.jobs, args.quiet)
    if "json" in outputs:
        stamped = stamp(checks, "so101-check-ik")
        write_text_atomic(outputs["json"], json.dumps(stamped[0] if len(stamped) == 1 else stamped,
                                                      indent=1))
    if "csv" in outputs:
        write_text_atomic(outputs["csv"], csv_report(checks))
    return exit_status(checks)


if __name__ == "__main__":
    sys.exit(main())
