"""``so101-check-fk``: check one student's FK module, or a whole class in parallel.

Exit status: 0 when every file is within the tolerance, 1 when one is outside it,
2 when one cannot be checked (missing, crashes on import, times out) or the options
are wrong. With several files the worst status wins.
"""

from __future__ import annotations

import os
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from so101_kinematics.checker import fk_compare, report, sandbox
from so101_kinematics.cli import EXIT_BAD_INPUT, ArgumentParser, number, range_help
from so101_kinematics.errors import OutputPathError
from so101_kinematics.outputs import (
    OutputKind,
    add_overwrite_argument,
    check_output_path,
    csv_kind,
    report_of,
    stamp,
    write_text_atomic,
)

__all__ = [
    "add_class_options", "add_tolerance_options", "check_file", "check_outputs", "exit_status",
    "main", "run_and_print", "run_check",
]

REPORT = report_of("so101-check-fk")  # --json/--gradescope replace only its own report

EXIT_PASS, EXIT_OUTSIDE, EXIT_UNCHECKED = 0, 1, 2


def check_file(path: str | Path, tolerance=(1.0, 1.0), timeout: float = sandbox.DEFAULT_TIMEOUT_S,
               count: int = fk_compare.RANDOM_COUNT) -> dict:
    """Check one FK module; the student's code runs in a child process.

    Args:
        path: the student's ``so101_forward_kinematics.py``.
        tolerance: (position [mm], rotation [deg]) a test must be within.
        timeout: time the module gets for its import and all calls [s].
        count: random configurations for the whole FK.

    Returns:
        A JSON-ready dict: file, student, verdict ("pass", "fail", "error"), reason,
        tests (see :func:`fk_compare.compare_all`), note, the module's output, seconds.
    """
    check, run = run_check(path, fk_compare.build_request(count), tolerance, timeout)
    if run is None:
        return check
    if run.status in ("import_error", "timeout") or not run.results.get("names"):
        check["reason"] = run.reason or "the module could not be imported"
        return check
    check.update(fk_compare.compare_all(run.results, tolerance, count))
    if run.status != "ok":
        check["note"] = (check["note"] + " " if check["note"] else "") + \
            f"Not every call finished: {run.reason}."
    passed = all(t["status"] in report.PASSING for t in check["tests"])
    check["verdict"] = "pass" if passed and run.status == "ok" else "fail"
    return check


def run_check(path: str | Path, request: dict, tolerance, timeout: float,
              probe: Path = sandbox.PROBE):
    """Run the probe on one file: ``(check, run)``, ``run`` None when there is no file.

    ``check`` is the JSON-ready dict both checkers fill in: file, student (the folder's
    name), verdict ("error" until judged), reason, tests, note, the module's output,
    seconds, tolerance. ``probe`` is the child's script (the trajectory checker's own).
    """
    path = Path(path)
    check = {"file": str(path), "student": path.resolve().parent.name, "verdict": "error",
             "reason": "", "tests": [], "note": "", "output": "", "output_size": 0,
             "seconds": 0.0, "tolerance": list(tolerance)}
    if not path.is_file():
        check["reason"] = f"no such file {path}" if not path.exists() else f"{path} is a folder"
        return check, None
    run = sandbox.run_probe(path, request, timeout, probe=probe)
    check["seconds"] = run.seconds
    check["output"] = run.results.get("output", "")
    check["output_size"] = run.results.get("output_size", 0)
    refused = run.results.get("refused_writes") or []
    if refused:  # not checked: what it computes may hang on the write it was refused
        check["reason"] = (
            f"it writes outside its temporary folder: {'; '.join(refused[:3])}"
            + (f" (and {len(refused) - 3} more)" if len(refused) > 3 else "")
            + " (refused: nothing was written there). Fix: a submission may write only into "
            "its working folder (e.g. a plain file name), or not at all")
        return check, None
    return check, run


def add_tolerance_options(parser: ArgumentParser) -> None:
    """``--tolerance-mm``, ``--tolerance-deg``, ``--timeout``: shared by both checkers."""
    parser.add_argument("--tolerance-mm", type=number(0, 1000, "mm", low_open=True), default=1.0,
                        help=f"position tolerance, {range_help(0, 1000, 'mm', True)} (1)")
    parser.add_argument("--tolerance-deg", type=number(0, 180, "deg", low_open=True),
                        default=1.0, help=f"rotation tolerance, {range_help(0, 180, 'deg', True)}")
    parser.add_argument("--timeout", type=number(0.5, 600, "s"), default=sandbox.DEFAULT_TIMEOUT_S,
                        help=f"time per file, {range_help(0.5, 600, 's')} (10)")


def add_class_options(parser: ArgumentParser) -> None:
    """``--jobs``, ``--quiet`` and ``--overwrite``: shared by both checkers."""
    parser.add_argument("--jobs", type=number(1, 256, integer=True), default=os.cpu_count() or 1,
                        help="files checked at once (the number of cores)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="one line per file, even for a single file")
    add_overwrite_argument(parser)


def check_outputs(args, kinds: dict[str, OutputKind], prog: str) -> dict | None:
    """The output paths asked for, checked before anything runs; None after a one-line error.

    Args:
        args: the parsed command line (the options named in ``kinds``, ``files``, ``overwrite``).
        kinds: option name -> what it writes (an existing file of another kind is refused).
        prog: the checker's name, for the message.
    """
    outputs = {}
    try:
        for option, kind in kinds.items():
            if getattr(args, option):
                outputs[option] = check_output_path(getattr(args, option), f"--{option}",
                                                    inputs=args.files, kind=kind,
                                                    overwrite=args.overwrite)
    except OutputPathError as error:
        print(f"{prog}: error: {error}", file=sys.stderr)
        return None
    return outputs


def run_and_print(files, check, text_report, jobs: int, quiet: bool) -> list[dict]:
    """Check ``files`` ``jobs`` at a time; print one report, or one line per file."""
    with ThreadPoolExecutor(max_workers=min(jobs, len(files))) as pool:
        checks = list(pool.map(check, files))
    for one in checks:
        if len(checks) == 1 and not quiet:
            print(text_report(one))
        else:
            print(text_report(one).splitlines()[-1].replace("Verdict", f"{one['file']}", 1)
                  + (f" {one['reason']}" if one["reason"] else ""))
    return checks


def exit_status(checks: list[dict]) -> int:
    """The worst of the files: 2 if one was not checked, 1 if one is outside the tolerance."""
    verdicts = {check["verdict"] for check in checks}
    return EXIT_UNCHECKED if "error" in verdicts else EXIT_OUTSIDE if "fail" in verdicts \
        else EXIT_PASS


def _points(items: list[str]) -> dict[str, float]:
    points = dict(report.DEFAULT_POINTS)
    for item in items:
        name, _, value = item.partition("=")
        if name not in points:
            raise ValueError(f"--points {item}: unknown test {name!r}; the tests are "
                             f"{', '.join(points)}. Fix: e.g. --points get_g5t=5")
        try:
            points[name] = number(0, 1000, "points")(value)
        except Exception:
            raise ValueError(f"--points {item}: {value!r} is not a number in [0, 1000]. Fix: "
                             f"e.g. --points {name}=5") from None
    return points


def build_parser() -> ArgumentParser:
    """The command line."""
    parser = ArgumentParser(prog="so101-check-fk", description=(
        "Check so101_forward_kinematics.py against the so101_kinematics package: which "
        "factor is wrong, by how much, and why."))
    parser.add_argument("files", nargs="+", type=Path, metavar="FILE",
                        help="one or more so101_forward_kinematics.py files")
    add_tolerance_options(parser)
    parser.add_argument("--random", type=number(1, 100000, integer=True),
                        default=fk_compare.RANDOM_COUNT, help="random configurations (1000)")
    parser.add_argument("--json", type=Path, help="write the full comparison (JSON)")
    parser.add_argument("--gradescope", type=Path, metavar="RESULTS_JSON",
                        help="write Gradescope's results.json (one file only)")
    parser.add_argument("--csv", type=Path, help="write one row per file")
    parser.add_argument("--points", action="append", default=[], metavar="TEST=POINTS",
                        help="points of a test, e.g. get_forward_kinematics=40 (repeatable; "
                        "defaults: " + ", ".join(f"{k}={v:g}" for k, v in
                                                 report.DEFAULT_POINTS.items()) + ")")
    add_class_options(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the checker; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        points = _points(args.points)
    except ValueError as error:
        parser.error(str(error))
    if args.gradescope and len(args.files) > 1:
        parser.error("--gradescope writes one submission's results.json; got "
                     f"{len(args.files)} files. Fix: run once per submission, or use --csv")
    outputs = check_outputs(args, {"json": REPORT, "gradescope": REPORT,
                                   "csv": csv_kind(report.CSV_COLUMNS, "a CSV of so101-check-fk")},
                            "so101-check-fk")
    if outputs is None:
        return EXIT_BAD_INPUT
    tolerance = (args.tolerance_mm, args.tolerance_deg)
    checks = run_and_print(
        args.files, lambda path: check_file(path, tolerance, args.timeout, args.random),
        lambda check: report.text_report(check, points), args.jobs, args.quiet)
    if "json" in outputs:
        write_text_atomic(outputs["json"], report.json_report(stamp(checks, "so101-check-fk")))
    if "gradescope" in outputs:
        import json

        results = report.gradescope_results(checks[0], points)
        results["extra_data"] = stamp(results.get("extra_data", {}), "so101-check-fk")
        write_text_atomic(outputs["gradescope"], json.dumps(results, indent=1))
    if "csv" in outputs:
        write_text_atomic(outputs["csv"], report.csv_report(checks, points))
    return exit_status(checks)
