"""Soak: docs/virtual_arm.md's hardware command, N times in a row, both cores busy.

Usage:
    python benchmarks/soak_hw.py [--runs 20] [--busy 2] [--json PATH]

Starts a virtual SO-101 with wire timing (as docs/virtual_arm.md does), keeps
``--busy`` other processes spinning (a loaded lab PC), and runs
``pick_place_hw.py --port PTY --calibration calibration/virtual_so101.json --yes``
``--runs`` times. Prints a table (exit code, last line, outages ridden through,
loop p99 period error) and optionally writes it as JSON. Goal: every run
completes and ends "Done: back at the starting pose, torque off."
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import re
import subprocess
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))

from so101_kinematics import outputs  # noqa: E402
from so101_kinematics.errors import OutputPathError  # noqa: E402

DONE = "Done: back at the starting pose, torque off."


def _spin(stop_at: float) -> None:
    while time.time() < stop_at:
        pass


def soak(runs: int = 20, busy: int = 2) -> list[dict]:
    """Run that hardware command ``runs`` times with ``busy`` spinning processes."""
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    results = []
    spinners = [multiprocessing.Process(target=_spin, args=(time.time() + 3600,), daemon=True)
                for _ in range(busy)]
    for spinner in spinners:
        spinner.start()
    try:
        with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, wire_timing=True) as arm:
            for i in range(runs):
                started = time.perf_counter()
                run = subprocess.run(
                    [sys.executable, str(REPO / "pick_place_hw.py"), "--port", arm.port,
                     "--calibration", str(DEFAULT_CALIBRATION_PATH), "--yes"],
                    cwd=REPO, capture_output=True, text=True, timeout=600)
                # the script's last line: stdout when done, stderr when it stopped
                lines = (run.stdout if run.returncode == 0 else run.stderr).strip().splitlines()
                p99 = re.search(r"p99 error ([0-9.]+) ms", run.stdout)
                results.append({
                    "run": i + 1, "exit": run.returncode, "seconds": time.perf_counter() - started,
                    "last_line": lines[-1] if lines else "",
                    "outages": run.stdout.count("the plan paused and resumed"),
                    "p99_period_error_ms": float(p99.group(1)) if p99 else None,
                    "completed": run.returncode == 0 and DONE in run.stdout,
                })
                row = results[-1]
                print(f"{row['run']:>3} exit {row['exit']} {row['seconds']:6.1f} s outages "
                      f"{row['outages']} p99 {row['p99_period_error_ms']} ms  {row['last_line']}",
                      flush=True)
    finally:
        for spinner in spinners:
            spinner.terminate()
    return results


def main(argv: list[str] | None = None) -> int:
    """Run the soak and print the summary; exit 1 unless every run completed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--busy", type=int, default=2, help="spinning processes (default 2)")
    parser.add_argument("--json", type=Path, help="write the results as JSON")
    outputs.add_overwrite_argument(parser)
    args = parser.parse_args(argv)
    if args.json:  # checked before the minutes of runs, not after
        try:
            report = outputs.report_of("benchmarks/soak_hw.py")
            args.json = outputs.check_output_path(args.json, "--json", kind=report,
                                                  overwrite=args.overwrite)
        except OutputPathError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
    results = soak(args.runs, args.busy)
    completed = sum(r["completed"] for r in results)
    print(f"{completed} of {len(results)} runs completed with {args.busy} busy processes; "
          f"{sum(r['outages'] for r in results)} outages ridden through.")
    if args.json:
        report = outputs.stamp({"busy": args.busy, "runs": results}, "benchmarks/soak_hw.py")
        outputs.write_text_atomic(args.json, json.dumps(report, indent=2))
    return 0 if completed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
