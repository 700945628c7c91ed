"""Shared helpers of the benchmark groups: seeding, repeats, summaries."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

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
