"""Benchmarks: every speed figure of the project beside its reference, in one run.

Usage:
    python benchmarks/run.py [--quick] [--json PATH] [--only NAME ...]

Each figure is the median over repeats with its spread (min, max). Ratios
compare against a reference measured in the same run (MuJoCo's own
kinematics, the simulated clock, the video's duration, the control period),
because a shared 2-core machine is noisy. Nothing here runs in the tests,
except that a test checks that ``--quick`` writes every key.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))

import so101_kinematics.display as so101_display  # noqa: E402, F401  (before mujoco: EGL when there is no display)

# isort: split
from benchmarks.bench_fk import bench_fk  # noqa: E402
from benchmarks.bench_hw import bench_hw  # noqa: E402
from benchmarks.bench_ik import bench_ik  # noqa: E402
from benchmarks.bench_pick_place import bench_pick_place  # noqa: E402
from benchmarks.bench_vision import bench_vision  # noqa: E402
from so101_kinematics.outputs import (  # noqa: E402
    add_overwrite_argument,
    check_output_path,
    report_of,
    stamp,
    write_text_atomic,
)

REPORT = report_of("benchmarks/run.py")  # --json replaces only a report of this program

BENCHMARKS: dict[str, Callable[[bool], dict]] = {
    "fk": bench_fk,
    "ik": bench_ik,
    "pick_place": bench_pick_place,
    "hw": bench_hw,
    "vision": bench_vision,
}

GOALS = {
    # key: (comparison, bound, what)
    "fk_single_vs_mujoco": ("<=", 3.0, "single FK <= 3x MuJoCo per call"),
    "fk_batch_ns_per_config": ("<=", 300.0, "batch FK <= 0.3 us per configuration"),
    "ik_solve_us": ("<=", 100.0, "IK <= 100 us median per target"),
    "ik_success_rate": (">=", 1.0, "IK solves every reachable sample"),
    "sim_realtime_factor": (">=", 100.0, "headless pick-and-place >= 100x real time"),
    "record_wall_over_video_duration": ("<=", 1.0, "recording no slower than the video's duration"),
    "record_fps": (">=", 30.0, "recording renders >= 30 frames per wall second"),
    "hw_period_p99_error_ms_100hz": ("<", 1.0, "100 Hz loop: p99 period error < 1 ms"),
    "hw_period_p99_error_ms_200hz": ("<", 1.0, "200 Hz loop: p99 period error < 1 ms"),
    "wire_cycle_emulator_added_ms": ("<", 0.3, "virtual arm adds < 0.3 ms to a cycle"),
    "render_fps_640x480": (">=", 30.0, "a camera renders >= 30 frames/s at 640x480 headless"),
}


def _value(entry):
    return entry["median"] if isinstance(entry, dict) else entry


def format_table(results: dict) -> str:
    """Render the results as a plain-text table."""
    rows = [("key", "median", "min", "max", "goal")]
    for key, entry in results.items():
        if key.startswith("_"):
            continue
        goal = ""
        if key in GOALS:
            op, bound, _ = GOALS[key]
            ok = {"<=": _value(entry) <= bound, "<": _value(entry) < bound,
                  ">=": _value(entry) >= bound}[op]
            goal = f"{op} {bound:g} {'ok' if ok else 'MISSED'}"
        if isinstance(entry, dict):
            cells = [f"{entry[part]:.4g}" for part in ("median", "min", "max")]
            rows.append((key, *cells, goal))
        else:
            text = f"{entry:.4g}" if isinstance(entry, float) else str(entry)
            rows.append((key, text, "", "", goal))
    widths = [max(len(row[i]) for row in rows) for i in range(5)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()
             for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def main() -> int:
    """Run the benchmarks, print the table, optionally write JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats (under 2 minutes)")
    parser.add_argument("--json", type=Path, help="write the results as JSON here")
    parser.add_argument("--only", nargs="+", choices=sorted(BENCHMARKS),
                        help="run only these groups")
    add_overwrite_argument(parser)
    args = parser.parse_args()
    if args.json:  # checked before the minutes of measuring, not after
        args.json = check_output_path(args.json, "--json", kind=REPORT,
                                      overwrite=args.overwrite)

    results: dict = {}
    started = time.perf_counter()
    for name, bench in BENCHMARKS.items():
        if args.only and name not in args.only:
            continue
        print(f"running {name} ...", file=sys.stderr, flush=True)
        results.update(bench(args.quick))
    results["_meta"] = {
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.system()}",
        "python": platform.python_version(),
        "quick": args.quick,
        "wall_s": time.perf_counter() - started,
    }
    print(format_table(results))
    if args.json:
        write_text_atomic(args.json, json.dumps(stamp(results, "benchmarks/run.py"), indent=2))
        print(f"wrote {args.json}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
