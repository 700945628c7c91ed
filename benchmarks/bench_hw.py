"""Benchmark group "hw": the hardware control loop and the bus cycle, against the virtual SO-101.

Figures (need the hw extra, lerobot):
  - hw_loop_hz_<rate>, hw_period_p50_ms_<rate>, hw_period_p99_error_ms_<rate>:
    so101_control's deadline-scheduled loop at 100 Hz and 200 Hz, talking to
    the virtual arm with wire timing at 1 Mbaud (goal: p99 period error < 1 ms);
  - wire_cycle_ms: one 6-motor sync_read + sync_write through lerobot's bus,
    wire_time_ms: the bytes' time on a 1 Mbaud wire (88 bytes, 10 bits each),
    wire_cycle_emulator_added_ms: what the virtual arm adds beyond the wire and
    lerobot's own host cost (goal < 0.3 ms).
"""

from __future__ import annotations

from benchmarks.common import summarize


def bench_hw(quick: bool) -> dict:
    """Run the group; ``quick`` measures shorter."""
    try:
        import lerobot  # noqa: F401
    except ImportError:
        return {"_hw_skipped": "lerobot is not installed (pip install -e '.[hw]')"}
    from virtual_so101 import measure_cycle

    out: dict = {}
    samples: dict[str, list[float]] = {}
    for _ in range(1 if quick else 3):
        timing = measure_loop_timing(rates_hz=(100.0, 200.0), seconds=2.0 if quick else 5.0,
                                     wire_timing=True)
        for rate, stats in timing.items():
            tag = f"{rate:.0f}hz"
            samples.setdefault(f"hw_loop_hz_{tag}", []).append(stats["achieved_hz"])
            samples.setdefault(f"hw_period_p50_ms_{tag}", []).append(stats["period_p50_ms"])
            samples.setdefault(f"hw_period_p99_error_ms_{tag}", []).append(
                stats["period_p99_error_ms"])
    cycles = [measure_cycle(n=300 if quick else 2000, wire_timing=True)
              for _ in range(1 if quick else 3)]
    samples["wire_cycle_ms"] = [c["cycle_median_ms"] for c in cycles]
    samples["wire_time_ms"] = [c["wire_ms"] for c in cycles]
    samples["wire_cycle_emulator_added_ms"] = [c["emulator_added_median_ms"] for c in cycles]
    for key, values in samples.items():
        out[key] = summarize(values)
    return out


def measure_loop_timing(rates_hz=(100.0, 200.0), seconds: float = 3.0, wire_timing: bool = True,
                        ) -> dict[float, dict[str, float]]:
    """Run the control loop against the virtual SO-101 and measure its timing at each rate.

    The arm swings wrist_flex by +-10 deg so each cycle does the full work
    (interpolate, sync_write, sync_read, check, log).

    Returns:
        rate -> ``achieved_hz``, ``period_p50_ms``, ``period_p99_error_ms``,
        ``period_max_error_ms``, ``cycles``, ``overruns``, ``skipped``.
    """
    from so101_bus import configure, connect, disconnect, enable_torque_in_place, release_torque
    from so101_calibration import load_calibration
    from so101_control import ArmSession, gc_frozen
    from virtual_so101 import DEFAULT_CALIBRATION_PATH, VirtualSO101

    results = {}
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, wire_timing=wire_timing) as arm:
        bus = connect(arm.port, load_calibration(DEFAULT_CALIBRATION_PATH))
        try:
            configure(bus)
            enable_torque_in_place(bus)
            for rate in rates_hz:
                with gc_frozen():
                    results[rate] = _swing_wrist(ArmSession(bus, rate_hz=rate), seconds)
        finally:
            release_torque(bus)
            disconnect(bus)
    return results


def _swing_wrist(session, seconds: float) -> dict[str, float]:
    """Swing wrist_flex +-10 deg for ``seconds`` [s]; returns the session's loop timing."""
    home = session.read_pose()
    session.command = dict(home)
    swings, elapsed = 0, 0.0
    while elapsed < seconds:
        sign = 1.0 if swings % 2 == 0 else -1.0
        session.move(dict(home, wrist_flex=home["wrist_flex"] + sign * 10.0), 0.5)
        session.hold(0.25)
        swings += 1
        elapsed = session.cycles[-1].wall_s
    session.move(home, 0.5)
    return session.timing()
