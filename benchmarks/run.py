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
import statistics
import sys
import time
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))
if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
    os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

SEED = 0
TEST_CONFIGURATION = {"shoulder_pan": -45.0, "shoulder_lift": 45.0, "elbow_flex": -45.0,
                      "wrist_flex": 90.0, "wrist_roll": 0.0}


def summarize(samples: list[float]) -> dict:
    """Median and spread of repeated measurements."""
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples),
            "repeats": len(samples)}


def per_call_us(fn: Callable[[], object], calls: int, repeats: int) -> list[float]:
    """Time ``fn`` in [us] per call, ``repeats`` times over ``calls`` calls."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter() - start) / calls * 1e6)
    return samples


# -- The assignment's style of FK, kept here only as a baseline. ---------------
def _rot(axis: str, thetadeg: float) -> np.ndarray:
    t = np.deg2rad(thetadeg)
    c, s = np.cos(t), np.sin(t)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _seed_style_forward_kinematics(cfg: dict) -> tuple[np.ndarray, np.ndarray]:
    """FK written as the course's starter code does: np.block per factor, every call."""
    import so101_forward_kinematics as fk

    def factor(name, theta):
        displacement, rotations = fk._FIXED[name]
        rotation = np.eye(3)
        for axis, angle in rotations:
            rotation = rotation @ _rot(axis, angle)
        rotation = rotation @ _rot("z", theta)
        return np.block([[rotation, np.array(displacement).reshape(3, 1)], [0, 0, 0, 1]])

    g = (factor("w1", cfg["shoulder_pan"]) @ factor("12", cfg["shoulder_lift"])
         @ factor("23", cfg["elbow_flex"]) @ factor("34", cfg["wrist_flex"])
         @ factor("45", cfg["wrist_roll"]))
    displacement, rotations = fk._FIXED["5t"]
    rotation = np.eye(3)
    for axis, angle in rotations:
        rotation = rotation @ _rot(axis, angle)
    g = g @ np.block([[rotation, np.array(displacement).reshape(3, 1)], [0, 0, 0, 1]])
    return g[0:3, 3], g[0:3, 0:3]


def bench_fk(quick: bool) -> dict:
    """FK per call (seed style, ours, MuJoCo) and the batch FK per configuration."""
    import mujoco

    import so101_forward_kinematics as fk
    import so101_mujoco_utils as utils

    calls, repeats = (2000, 5) if quick else (20000, 9)
    m = utils.load_model()
    d = mujoco.MjData(m)
    addresses = [int(m.joint(name).qposadr[0]) for name in fk.ARM_JOINTS]
    site = m.site(fk.TOOL_SITE).id
    q = np.radians([TEST_CONFIGURATION[name] for name in fk.ARM_JOINTS])

    def mujoco_fk():
        d.qpos[addresses] = q
        mujoco.mj_kinematics(m, d)
        return d.site_xpos[site].copy(), d.site_xmat[site].reshape(3, 3).copy()

    seed = per_call_us(lambda: _seed_style_forward_kinematics(TEST_CONFIGURATION), calls // 4, repeats)
    single = per_call_us(lambda: fk.get_forward_kinematics(TEST_CONFIGURATION), calls, repeats)
    reference = per_call_us(mujoco_fk, calls, repeats)

    n = 100_000 if quick else 1_000_000
    rng = np.random.default_rng(SEED)
    lower = np.degrees([m.joint(name).range[0] for name in fk.ARM_JOINTS])
    upper = np.degrees([m.joint(name).range[1] for name in fk.ARM_JOINTS])
    angles = rng.uniform(lower, upper, size=(n, len(fk.ARM_JOINTS)))
    batch = []
    for _ in range(3 if quick else 5):
        start = time.perf_counter()
        fk.get_forward_kinematics_batch(angles)
        batch.append((time.perf_counter() - start) / n * 1e9)
    out = {
        "fk_seed_style_us": summarize(seed),
        "fk_single_us": summarize(single),
        "mujoco_kinematics_us": summarize(reference),
        "fk_batch_ns_per_config": summarize(batch),
    }
    out["fk_single_vs_mujoco"] = out["fk_single_us"]["median"] / out["mujoco_kinematics_us"]["median"]
    out["fk_batch_speedup_vs_mujoco_loop"] = (
        out["mujoco_kinematics_us"]["median"] * 1e3 / out["fk_batch_ns_per_config"]["median"])
    out["fk_batch_configs"] = n
    return out


from benchmarks.bench_pick_place import bench_pick_place  # noqa: E402

BENCHMARKS: dict[str, Callable[[bool], dict]] = {
    "fk": bench_fk,
    "pick_place": bench_pick_place,
}

GOALS = {
    # key: (comparison, bound, what)
    "fk_single_vs_mujoco": ("<=", 3.0, "single FK <= 3x MuJoCo per call"),
    "fk_batch_ns_per_config": ("<=", 300.0, "batch FK <= 0.3 us per configuration"),
    "pick_place_realtime_factor": (">=", 100.0, "headless pick-and-place >= 100x real time"),
    "record_wall_vs_video": ("<=", 1.0, "recording no slower than the video's duration"),
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
            ok = _value(entry) <= bound if op == "<=" else _value(entry) >= bound
            goal = f"{op} {bound:g} {'ok' if ok else 'MISSED'}"
        if isinstance(entry, dict):
            rows.append((key, f"{entry['median']:.4g}", f"{entry['min']:.4g}", f"{entry['max']:.4g}", goal))
        else:
            rows.append((key, f"{entry:.4g}" if isinstance(entry, float) else str(entry), "", "", goal))
    widths = [max(len(row[i]) for row in rows) for i in range(5)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def main() -> int:
    """Run the benchmarks, print the table, optionally write JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats (under 2 minutes)")
    parser.add_argument("--json", type=Path, help="write the results as JSON here")
    parser.add_argument("--only", nargs="+", choices=sorted(BENCHMARKS), help="run only these groups")
    args = parser.parse_args()

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
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2))
        print(f"wrote {args.json}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
