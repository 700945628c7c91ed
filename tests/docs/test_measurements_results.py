"""The benchmarks' committed results, which the measurements page is generated from: each
file is dated, names its machine, and holds figures in benchmarks/run.py's shape."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
RESULTS = sorted((REPO / "benchmarks" / "results").glob("*.json"))


def test_there_is_a_committed_run():
    assert RESULTS, "the measurements page needs benchmarks/results/*.json"


@pytest.mark.parametrize("path", RESULTS, ids=[p.name for p in RESULTS])
def test_a_run_is_dated_names_its_machine_and_has_figures(path):
    results = json.loads(path.read_text())
    meta = results["_meta"]
    assert re.match(r"\d{4}-\d{2}-\d{2}", meta["date"])
    assert meta["machine"] and meta["python"]
    figures = {k: v for k, v in results.items() if not k.startswith("_") and k != "generator"}
    assert figures
    for key, entry in figures.items():
        if isinstance(entry, dict):
            assert entry["min"] <= entry["median"] <= entry["max"], key
        else:
            assert isinstance(entry, (int, float)), key
