"""benchmarks/run.py --quick runs end to end and writes every figure the project reports."""

import json
import subprocess
import sys

import pytest
from conftest import REPO

EXPECTED_KEYS = [
    "fk_seed_style_us", "fk_product_us", "fk_single_us", "mujoco_kinematics_us",
    "fk_batch_ns_per_config",
    "fk_single_vs_mujoco", "fk_batch_speedup_vs_mujoco_loop",
    "ik_solve_us", "ik_success_rate",
    "sim_realtime_factor", "record_fps", "record_wall_over_video_duration",
    "hw_loop_hz_100hz", "hw_period_p50_ms_100hz", "hw_period_p99_error_ms_100hz",
    "hw_loop_hz_200hz", "hw_period_p50_ms_200hz", "hw_period_p99_error_ms_200hz",
    "wire_cycle_ms", "wire_time_ms", "wire_cycle_emulator_added_ms",
    "render_fps_640x480", "render_reference_fps_640x480", "detect_pose_ms",
    "see_and_pick_cycle_s", "see_and_pick_reference_s",
]


@pytest.mark.hw
@pytest.mark.slow
def test_quick_benchmark_writes_every_key(tmp_path):
    pytest.importorskip("lerobot")
    out = tmp_path / "bench.json"
    run = subprocess.run([sys.executable, str(REPO / "benchmarks" / "run.py"), "--quick",
                          "--json", str(out)], capture_output=True, text=True, timeout=600,
                         cwd=REPO)
    assert run.returncode == 0, run.stderr[-3000:]
    results = json.loads(out.read_text())
    missing = [key for key in EXPECTED_KEYS if key not in results]
    assert not missing, f"benchmark JSON lacks {missing}"
    for key in EXPECTED_KEYS:
        entry = results[key]
        value = entry["median"] if isinstance(entry, dict) else entry
        assert isinstance(value, float | int) and value > 0, f"{key} = {value!r}"
        if isinstance(entry, dict):
            assert entry["min"] <= entry["median"] <= entry["max"], key
    # The printed table names every key too.
    for key in EXPECTED_KEYS:
        assert key in run.stdout, f"table lacks {key}"
    # Sanity of what is measured, not of speed: 1 Mbaud wire time of 88 bytes.
    assert results["wire_time_ms"]["median"] == pytest.approx(0.88, rel=1e-6)
    assert results["ik_success_rate"] == 1.0
