"""Benchmark group "hw": the hardware control loop and the bus cycle, against the virtual SO-101.

Figures (need the hw extra, lerobot):
  - hw_loop_hz_<rate>, hw_period_p50_ms_<rate>, hw_period_p99_error_ms_<rate>:
    so101_kinematics.hw.control's deadline-scheduled loop at 100 Hz and 200 Hz, talking to
    the virtual arm with wire timing at 1 Mbaud (goal: p99 period error < 1 ms);
  - wire_cycle_ms: one 6-motor sync_read + sync_write through lerobot's bus,
    wire_time_ms: the bytes' time on a 1 Mbaud wire (88 bytes, 10 bits each),
    wire_cycle_emulator_added_ms: what the virtual arm adds beyond the wire and
    lerobot's own host cost (goal < 0.3 ms).
"""

from __future__ import annotations

import statistics
import time

from benchmarks.common import summarize
from so101_kinematics.virtual.protocol import INST_SYNC_READ


def bench_hw(quick: bool) -> dict:
    """Run the group; ``quick`` measures shorter."""
    try:
        import lerobot  # noqa: F401
    except ImportError:
        return {"_hw_skipped": "lerobot is not installed (pip install -e '.[hw]')"}

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
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.bus import configure, connect, disconnect, read_pose, release_torque
    from so101_kinematics.hw.control import ArmSession
    from so101_kinematics.hw.feedforward import read_feedforward, torque_on_in_place
    from so101_kinematics.hw.signals import gc_frozen
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    results = {}
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, wire_timing=wire_timing) as arm:
        bus = connect(arm.port, load_calibration(DEFAULT_CALIBRATION_PATH))
        try:
            start = read_pose(bus)
            configure(bus)
            feedforward = read_feedforward(bus)  # as every run: the arm holds, not sags
            torque_on_in_place(bus, feedforward, start)
            for rate in rates_hz:
                with gc_frozen():
                    session = ArmSession(bus, rate_hz=rate, feedforward=feedforward)
                    results[rate] = _swing_wrist(session, seconds)
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


def virtual_arm_bus(arm, degrees: bool = True):
    """A lerobot ``FeetechMotorsBus`` for the arm with its calibration (needs lerobot).

    Args:
        arm: the virtual arm.
        degrees: arm joints in DEGREES (else RANGE_M100_100); the gripper is RANGE_0_100.
    """
    from lerobot.motors import Motor, MotorCalibration, MotorNormMode
    from lerobot.motors.feetech import FeetechMotorsBus

    body = MotorNormMode.DEGREES if degrees else MotorNormMode.RANGE_M100_100
    motors = {name: Motor(entry["id"], "sts3215",
                          MotorNormMode.RANGE_0_100 if name == "gripper" else body)
              for name, entry in arm.calibration.items()}
    calibration = {name: MotorCalibration(**entry) for name, entry in arm.calibration.items()}
    return FeetechMotorsBus(port=arm.port, motors=motors, calibration=calibration)


class _LoopbackSerial:
    """A stand-in for the bus's pyserial port that answers SYNC_READs instantly, in-process.

    Timing lerobot against it gives the host's own cost of a cycle (packing,
    parsing, decoding), which a real arm costs too.
    """

    def __init__(self, replies: bytes):
        self.replies = replies
        self.buffer = bytearray()
        self.is_open = True

    def write(self, data) -> int:
        if len(data) > 4 and data[4] == INST_SYNC_READ:
            self.buffer += self.replies
        return len(data)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self.buffer[:size])
        del self.buffer[:size]
        return out

    @property
    def in_waiting(self) -> int:
        return len(self.buffer)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self.buffer.clear()

    def close(self) -> None:
        self.is_open = False


def _time_cycles(bus, n: int, warmup: int, on_warm=None) -> list[float]:
    """Durations [s] of n sync_read(Present_Position) + sync_write(Goal_Position) cycles."""
    times = []
    for i in range(n + warmup):
        t0 = time.perf_counter()
        try:
            present = bus.sync_read("Present_Position", normalize=False)
        except ConnectionError:  # a reply lost on a loaded host: not a cycle to time
            bus.port_handler.ser.reset_input_buffer()
            bus.port_handler.is_using = False
            continue
        bus.sync_write("Goal_Position", present, normalize=False)
        if i == warmup - 1 and on_warm is not None:
            on_warm()
        if i >= warmup:
            times.append(time.perf_counter() - t0)
    return sorted(times)


def measure_cycle(n: int = 1000, wire_timing: bool = True, arm=None,
                  warmup: int = 50) -> dict[str, float]:
    """Time lerobot's 6-motor sync_read + sync_write cycle against the virtual arm (needs lerobot).

    Each cycle reads Present_Position and writes it back as Goal_Position (raw
    ticks), as a teleoperation loop does. The same cycles are then timed
    against an in-process loopback port, which gives lerobot's own (host) cost;
    what remains of the cycle after the wire time and the host cost is what
    the emulator adds (its wake-up and processing).

    Args:
        n: cycles to time.
        wire_timing: emulate the wire's byte time.
        arm: an existing virtual arm (else one is started and closed).
        warmup: cycles run before timing.

    Returns:
        ``cycle_median_ms`` / ``cycle_p99_ms`` (client side); ``wire_ms``
        (88 bytes x 10 bits at the bus's baud rate, 0 without wire timing);
        ``overhead_median_ms`` / ``_p99_ms`` (cycle - wire); ``host_median_ms``
        (lerobot's cost, loopback); ``emulator_added_median_ms`` (cycle median -
        wire - host median: without wire timing, the emulator's whole share,
        i.e. wake-ups, processing and the pty; with wire timing the host's work
        partly overlaps the sync_write's wire time, so it reads lower); the
        emulator's lateness behind each reply's due time
        (``emulator_lateness_median_ms`` / ``_p99_ms``) and ``late_replies``.
    """
    from so101_kinematics.hw.bus import connect_with_retries
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.protocol import BITS_PER_BYTE, cycle_wire_bytes, status_packet

    own = arm is None
    arm = arm or VirtualSO101(wire_timing=wire_timing)
    bus = None
    try:
        arm.set_wire_timing(wire_timing)
        bus = virtual_arm_bus(arm)
        connect_with_retries(bus)
        times = _time_cycles(bus, n, warmup, on_warm=arm.clear_stats)
        stats = arm.reply_stats()
        wire_ms = cycle_wire_bytes() * BITS_PER_BYTE / bus.port_handler.getBaudRate() * 1e3
        wire_ms = wire_ms if wire_timing else 0.0
        present = bus.sync_read("Present_Position", normalize=False)
        replies = b"".join(status_packet(bus.motors[name].id, 0, value.to_bytes(2, "little"))
                           for name, value in present.items())
        serial_port = bus.port_handler.ser
        bus.port_handler.ser = _LoopbackSerial(replies)
        try:
            host = _time_cycles(bus, n, warmup)
        finally:
            bus.port_handler.ser = serial_port
        median, p99 = 1e3 * statistics.median(times), 1e3 * times[int(0.99 * (len(times) - 1))]
        host_median = 1e3 * statistics.median(host)
        return {
            "cycles": n, "wire_timing": wire_timing, "wire_ms": wire_ms,
            "cycle_median_ms": median, "cycle_p99_ms": p99,
            "overhead_median_ms": median - wire_ms, "overhead_p99_ms": p99 - wire_ms,
            "host_median_ms": host_median,
            "emulator_added_median_ms": median - wire_ms - host_median,
            "emulator_lateness_median_ms": stats["lateness_median_ms"],
            "emulator_lateness_p99_ms": stats["lateness_p99_ms"],
            "late_replies": stats["late_replies"],
        }
    finally:
        if bus is not None:
            bus.disconnect(disable_torque=False)
        if own:
            arm.close()


