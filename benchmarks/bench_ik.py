"""Benchmark group: inverse kinematics per target and success on reachable targets."""

from __future__ import annotations

import statistics
import time

from benchmarks.common import SEED, summarize


def bench_ik(quick: bool) -> dict:
    """IK per target (top-down with a yaw; free yaw; position only); success on reachable ones."""
    import so101_inverse_kinematics as ik
    from so101_kinematics.ik.solver import sample_top_down_targets

    _, positions, yaws = sample_top_down_targets(20_000 if quick else 100_000, seed=SEED)
    n = 300 if quick else 1000
    targets = [(tuple(p), float(y)) for p, y in zip(positions[:n], yaws[:n], strict=True)]
    calls = {
        "ik_solve_us": lambda t: ik.get_inverse_kinematics(t[0], approach="down", yaw_deg=t[1]),
        "ik_solve_free_yaw_us":
            lambda t: ik.get_inverse_kinematics(t[0], approach="down", yaw_deg=None),
        "ik_solve_position_only_us": lambda t: ik.get_inverse_kinematics(t[0], approach=None),
    }
    out = {}
    for key, call in calls.items():
        medians = []
        for _ in range(3 if quick else 7):
            per_target = []
            for target in targets:
                start = time.perf_counter()
                call(target)
                per_target.append((time.perf_counter() - start) * 1e6)
            medians.append(statistics.median(per_target))
        out[key] = summarize(medians)
    # Success on targets known reachable: FK of random in-limit configurations.
    _, positions, yaws = sample_top_down_targets(50_000 if quick else 500_000, seed=SEED + 1)
    solved = 0
    for position, yaw in zip(positions, yaws, strict=True):
        try:
            ik.get_inverse_kinematics(position, approach="down", yaw_deg=float(yaw))
            solved += 1
        except ik.UnreachableError:
            pass
    out["ik_success_rate"] = solved / len(positions)
    out["ik_reachable_samples"] = len(positions)
    return out

