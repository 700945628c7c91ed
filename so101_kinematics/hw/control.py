"""The deadline-scheduled control loop of the real arm and the course's move_to_pose/hold_position.

The motion side of the hardware backend of the shared motion code
(``so101_motion``), on a lerobot bus opened with ``so101_bus``:
  - the speed cap (:func:`capped_duration`) and the deadline scheduler
    (:class:`RateLoop`, :func:`loop_timing_stats`);
  - the control loop (:class:`ArmSession`) behind the course's interface
    ``move_to_pose(bus, cfg, duration)`` and ``hold_position(bus, duration)``,
    with every stop signal (Ctrl-C, SIGTERM, SIGHUP) turned into a stop at a
    cycle boundary (:func:`stop_on_signals`) and the garbage collector frozen
    during motion (:func:`gc_frozen`).

The fault policy (docs/hardware_safety.md): a position-controlled servo holds
its last goal by itself, so holding is always safer than letting go. A failed
read is retried within the cycle; while the arm is unobserved the
trajectory's clock stands still and the last goal is repeated, so the plan
resumes where it paused when the reads come back. Only an outage longer than
``OUTAGE_TOLERANCE_S``, a stall, or a servo's error bit ends the motion, with
a controlled stop (goal = present position, torque on): see
:meth:`ArmSession.stop_here`.
"""

from __future__ import annotations

import gc
import logging
import signal
import sys
import threading
import time
import weakref
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import NamedTuple

from so101_kinematics.calibration import calibrated_limits
from so101_kinematics.errors import (
    BusError as BusError,
)
from so101_kinematics.errors import (
    FreezeRequested as FreezeRequested,
)
from so101_kinematics.errors import (
    ServoFault as ServoFault,
)
from so101_kinematics.errors import (
    StopRequested as StopRequested,
)
from so101_kinematics.errors import (
    TrackingError as TrackingError,
)
from so101_kinematics.frames import JOINTS
from so101_kinematics.hw.bus import (
    PORT_SETTLE_S,
    PortLost,
    discard_stale_input,
    port_lost,
    recover_port,
)
from so101_kinematics.motion import (
    PROFILES,
    Configuration,
    JointLimitError,
    PlanError,
    Trajectory,
    check_configuration,
    check_number,
    unit,
)

logger = logging.getLogger(__name__)

# --- Settings ---------------------------------------------------------------
DEFAULT_RATE_HZ = 100.0            # control loop rate [Hz]
MIN_RATE_HZ = 20.0                 # slower, one cycle's step at the speed cap exceeds 5 deg
MAX_RATE_HZ = 500.0                # a 6-motor cycle takes about 1.1 ms on the wire and host
MAX_JOINT_SPEED_DEG_S = 100.0      # speed cap of each arm joint [deg/s] (peak of the profile)
SPEED_CAP_LIMIT_DEG_S = 180.0      # the highest cap accepted: 2/3 of the STS3215's no-load
                                   # speed at 7.4 V (0.222 s/60 deg = 270 deg/s) [deg/s]
MAX_GRIPPER_SPEED_PCT_S = 100.0    # speed cap of the gripper [%/s]
RETURN_SPEED_DEG_S = 20.0          # "slowly": return after an abort [deg/s] (gripper [%/s])
RETURN_MIN_DURATION_S = 1.0        # the return after an abort never takes less [s]
TRACKING_TOLERANCE_DEG = 15.0      # measured vs commanded, arm joints [deg] ...
TRACKING_TOLERANCE_LIMIT_DEG = 45.0  # ... at most this [deg] ...
TRACKING_TIMEOUT_S = 0.3           # ... beyond it for this long [s] is a stall or a collision
READ_RETRIES = 1                   # a failed Present_Position read is retried in the cycle
OUTAGE_TOLERANCE_S = 1.0           # the arm may go unobserved this long: the plan pauses [s]
RECOVERY_TIMEOUT_S = 5.0           # after a longer outage, wait this long for the arm [s]
MAX_ADVANCE_S = 0.05               # the trajectory advances at most this much per cycle [s]
STATUS_EVERY = 10                  # read the servos' Status (error bits) every N cycles
SPIN_S = 0.0005                    # busy-wait this last part of each period [s]
IDLE_RESTART_S = 0.25              # a loop idle for longer starts a fresh deadline grid [s]
STATUS_BITS = {0x01: "input voltage out of range", 0x04: "overheated", 0x08: "overcurrent",
               0x20: "overloaded"}
"""Status register bits of the STS3215 that stop the motion, and what they mean."""


# --- Errors -----------------------------------------------------------------
# --- Speed cap ---------------------------------------------------------------
PEAK_SPEED_FACTOR = {"linear": 1.0, "minimum_jerk": 1.875}
"""Peak of d(fraction)/ds of each time scaling: 1 for linear; 30 s^2 (1 - s)^2 peaks at
s = 1/2 for minimum jerk: 15/8."""


def peak_speed_factor(profile: str) -> float:
    """Peak speed of a move over its mean speed, for a time-scaling profile (exact)."""
    return PEAK_SPEED_FACTOR[profile]


def speed_caps(max_joint_speed: float = MAX_JOINT_SPEED_DEG_S,
               max_gripper_speed: float = MAX_GRIPPER_SPEED_PCT_S) -> dict[str, float]:
    """Joint -> speed cap ([deg/s]; gripper [%/s])."""
    return {j: (max_gripper_speed if j == "gripper" else max_joint_speed) for j in JOINTS}


def tracking_tolerances(arm_tolerance: float = TRACKING_TOLERANCE_DEG) -> dict[str, float | None]:
    """Joint -> tracking tolerance [deg].

    The gripper is not checked: it squeezes the cube by design, and lerobot's
    configuration limits its torque and current instead.
    """
    return {j: (None if j == "gripper" else arm_tolerance) for j in JOINTS}


def capped_duration(start: Mapping[str, float], goal: Mapping[str, float], duration: float,
                    profile: str, max_speed: Mapping[str, float]) -> float:
    """The shortest duration >= ``duration`` [s] that keeps every joint under its speed cap.

    Args:
        start: configuration at the start ([deg], gripper [0, 100]).
        goal: configuration at the end.
        duration: the requested duration [s].
        profile: time scaling of the move ("minimum_jerk" or "linear").
        max_speed: joint -> cap ([deg/s]; gripper [%/s]).

    Example:
        >>> capped_duration({"shoulder_pan": 0.0}, {"shoulder_pan": 90.0}, 1.0, "linear",
        ...                 {"shoulder_pan": 45.0})
        2.0
    """
    factor = peak_speed_factor(profile)
    needed = max((abs(goal[j] - start[j]) * factor / max_speed[j] for j in goal), default=0.0)
    return max(float(duration), needed)


# --- Deadline scheduler ----------------------------------------------------------
class RateLoop:
    """Fixed-rate, deadline-scheduled loop: ``next_deadline += period``, sleep, spin the last bit.

    A late cycle is counted as an overrun and the loop runs on at once; when
    more than a whole period late, the missed deadlines are skipped (never
    replayed in a burst).

    Args:
        rate_hz: loop rate [Hz].
        clock: monotonic clock [s].
        sleep: sleep function [s].
        spin: busy-wait this last part of each wait [s].
    """

    def __init__(self, rate_hz: float, clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep, spin: float = SPIN_S):
        if not (isinstance(rate_hz, (int, float)) and 0 < rate_hz <= MAX_RATE_HZ):
            raise ValueError(f"rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate_hz!r}.")
        self.period = 1.0 / float(rate_hz)
        self.clock, self.sleep, self.spin = clock, sleep, spin
        self.deadline: float | None = None
        self.woke = 0.0  # when the last wait returned [s]
        self.cycles = self.overruns = self.skipped = 0

    def start(self) -> float:
        """Make now the current deadline; returns it [s]."""
        self.deadline = self.woke = self.clock()
        return self.deadline

    def resume(self) -> float:
        """The grid point a new segment starts from: the latest deadline not in the future.

        Continues the grid (skipping missed deadlines) when the loop was busy
        until now; starts afresh after an idle gap longer than ``IDLE_RESTART_S``.
        """
        if self.deadline is None:
            return self.start()
        behind = self.clock() - self.deadline
        if behind > IDLE_RESTART_S:
            return self.start()
        if behind >= self.period:
            missed = int(behind // self.period)
            self.skipped += missed
            self.deadline += missed * self.period
        return self.deadline

    def wait(self) -> float:
        """Wait for the next deadline and return it (the cycle's scheduled time [s])."""
        if self.deadline is None:
            self.start()
        self.deadline += self.period
        now = self.clock()
        late = now - self.deadline
        if late > 0.0:
            self.overruns += 1
            if late >= self.period:
                missed = int(late // self.period)
                self.skipped += missed
                self.deadline += missed * self.period
        else:
            remaining = -late
            if remaining > self.spin:
                self.sleep(remaining - self.spin)
            while self.clock() < self.deadline:
                pass
        self.cycles += 1
        self.woke = self.clock()
        return self.deadline


def loop_timing_stats(wake_times: list[float], rate_hz: float) -> dict[str, float]:
    """Period statistics of a loop from the times its cycles started [s].

    Returns:
        ``achieved_hz``, ``period_p50_ms``, ``period_p99_error_ms`` (99th percentile
        of |period - nominal|), ``period_max_error_ms`` and ``cycles``.
    """
    import numpy as np

    times = np.asarray(wake_times, dtype=float)
    if times.size < 3:
        raise ValueError("need at least 3 cycles for timing statistics")
    periods = np.diff(times)
    error = np.abs(periods - 1.0 / rate_hz)
    return {
        "rate_hz": float(rate_hz),
        "achieved_hz": float((times.size - 1) / (times[-1] - times[0])),
        "period_p50_ms": float(np.median(periods) * 1e3),
        "period_p99_error_ms": float(np.percentile(error, 99) * 1e3),
        "period_max_error_ms": float(error.max() * 1e3),
        "cycles": int(times.size),
    }


# --- The control loop ------------------------------------------------------------
class Cycle(NamedTuple):
    """One control cycle: scheduled and wake time since start [s], step, command, measurement."""

    t_s: float
    wall_s: float
    step: str
    command: Configuration
    measured: Configuration | None


@dataclass
class Segment:
    """A move or a hold as executed, on the session's timeline."""

    kind: str  # "move" or "hold"
    step: str
    t_start_s: float  # [s] since the session's first cycle was scheduled
    start: Configuration
    goal: Configuration
    duration: float  # [s], after the speed cap
    requested: float  # [s], as asked


_SESSIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class ArmSession:
    """A connected arm plus the state of its control loop.

    Created for a bus, it is found again by :func:`move_to_pose` and
    :func:`hold_position`, so the course's ``move_to_pose(bus, cfg, 2.0)`` works.

    Args:
        bus: a connected lerobot ``FeetechMotorsBus`` (calibration set).
        rate_hz: control loop rate [Hz], in [``MIN_RATE_HZ``, ``MAX_RATE_HZ``].
        profile: "minimum_jerk" (default, as the simulator) or "linear".
        max_speed: joint -> speed cap ([deg/s]; gripper [%/s]).
        tracking_tolerance: joint -> |measured - commanded| allowed [deg]
            (None: not checked; the gripper by default, as it squeezes the cube).
        tracking_timeout: how long a joint may stay beyond it [s].
        outage_tolerance: how long the arm may go unobserved (every read
            failing) before the motion stops [s]; meanwhile the plan pauses.
        on_cycle: called with (session, cycle) after each cycle (tests, monitors, the log).
        clock, sleep: time sources (tests).
    """

    def __init__(self, bus, *, rate_hz: float = DEFAULT_RATE_HZ, profile: str = "minimum_jerk",
                 max_speed: Mapping[str, float] | None = None,
                 tracking_tolerance: Mapping[str, float | None] | None = None,
                 tracking_timeout: float = TRACKING_TIMEOUT_S,
                 outage_tolerance: float = OUTAGE_TOLERANCE_S,
                 on_cycle: Callable[[ArmSession, Cycle], None] | None = None,
                 clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep):
        if profile not in PROFILES:
            raise PlanError(f"Unknown profile '{profile}'; use one of {', '.join(PROFILES)}.")
        check_rate(rate_hz)
        self.bus = bus
        self.limits = calibrated_limits(bus.calibration)
        self.loop = RateLoop(rate_hz, clock, sleep)
        self.profile = profile
        self.max_speed = dict(max_speed or speed_caps())
        if tracking_tolerance is None:
            tracking_tolerance = tracking_tolerances(TRACKING_TOLERANCE_DEG)
        self.tracking_tolerance = dict(tracking_tolerance)
        self.tracking_timeout = tracking_timeout
        self.outage_tolerance = outage_tolerance
        self.on_cycle = on_cycle
        self.cycles: list[Cycle] = []
        self.segments: list[Segment] = []
        self.stretched: list[str] = []
        self.command: Configuration | None = None  # last command sent
        self.step = ""
        self.stop_reason: str | None = None
        self.outages: list[tuple[float, float]] = []  # ridden through: (start, length) [s]
        self._t0: float | None = None
        self._beyond: dict[str, float] = {}
        self._unobserved_since: float | None = None
        self.known_faults: dict[str, int] = {}  # joint -> status bits already reported
        self.stale_bytes = 0  # late-reply bytes dropped before reads
        _SESSIONS[bus] = self

    # measurement and command
    def _read(self) -> Configuration:
        """Present_Position of every joint, retried within the call; raises what the bus raises."""
        raw = self.bus.sync_read("Present_Position", num_retry=READ_RETRIES)
        return {j: float(raw[j]) for j in JOINTS}

    def read_pose(self) -> Configuration:
        """Present_Position of every joint ([deg]; gripper [0, 100]); raises BusError, PortLost."""
        try:
            return self._read()
        except Exception as error:  # noqa: BLE001 - lerobot raises ConnectionError/RuntimeError
            if port_lost(self.bus):
                raise PortLost.during("reading the arm's position") from error
            raise BusError(f"Cannot read the arm's position: {error}") from error

    def _guard(self, command: Mapping[str, float]) -> Configuration:
        """Last line of defence: refuse a command outside the calibrated range."""
        out = {}
        for joint in JOINTS:
            lower, upper = self.limits[joint]
            value = command[joint]
            if not (lower - 1e-6 <= value <= upper + 1e-6):
                raise JointLimitError(
                    f"Command {joint} = {value:g} {unit(joint)} is outside the calibrated range "
                    f"[{lower:g}, {upper:g}] {unit(joint)}; nothing was sent.")
            out[joint] = min(upper, max(lower, value))
        return out

    @property
    def observed(self) -> bool:
        """Whether the last read of the arm succeeded."""
        return self._unobserved_since is None

    def _send(self, command: Configuration) -> None:
        try:
            self.bus.sync_write("Goal_Position", command)
        except Exception as error:  # noqa: BLE001 - a broadcast gets no reply: only the port fails
            if port_lost(self.bus):
                raise PortLost.during("sending Goal_Position") from error
            logger.warning("Goal_Position write failed: %s", error)

    def _cycle(self, command_at: Callable[[float], Mapping[str, float]]) -> float:
        """Wait for the next deadline, command, measure, check, log; returns the deadline [s]."""
        deadline = self.loop.wait()
        if self.stop_reason is not None:
            raise StopRequested(self.stop_reason)
        previous = self.command
        command = self._guard(command_at(deadline))
        self._send(command)
        self.command = command
        try:
            stale = discard_stale_input(self.bus)
            if stale:
                self.stale_bytes += stale
                logger.debug("dropped %d stale bytes (a late reply)", stale)
            measured = self._read()
        except Exception as error:  # noqa: BLE001
            measured = None
            if port_lost(self.bus):
                raise PortLost.during(f"'{self.step}'") from error
            recover_port(self.bus, settle=False)
            if self._unobserved_since is None:
                self._unobserved_since = deadline
                logger.warning("The arm does not answer (%s); pausing the plan, holding the last "
                               "goal.", error)
            unobserved = self.loop.clock() - self._unobserved_since
            if unobserved > self.outage_tolerance:
                raise BusError(f"The arm did not answer for {unobserved:.2f} s (more than the "
                               f"{self.outage_tolerance:g} s tolerated): {error}") from error
        if measured is not None:
            if self._unobserved_since is not None:
                length = deadline - self._unobserved_since
                self.outages.append((self._unobserved_since - self._t0, length))
                logger.warning("The arm answers again after %.2f s; resuming the plan.", length)
                self._unobserved_since = None
            if previous is not None:
                self._check_tracking(previous, measured, deadline)
            if len(self.cycles) % STATUS_EVERY == 0:
                self._check_status()
        cycle = Cycle(deadline - self._t0, self.loop.woke - self._t0, self.step, command, measured)
        self.cycles.append(cycle)
        if self.on_cycle is not None:
            self.on_cycle(self, cycle)
        return deadline

    def _check_status(self) -> None:
        """Stop on a new error bit in a servo's Status register (the gripper's overload excepted).

        A bit reported once is known: it does not stop the slow return that follows.
        """
        try:
            status = self.bus.sync_read("Status", normalize=False)
        except Exception:  # noqa: BLE001 - a missed status read is not a fault; the next one
            recover_port(self.bus, settle=False)
            return
        for joint, bits in status.items():
            bits = int(bits) & ~self.known_faults.get(joint, 0)
            if joint == "gripper":  # squeezing the cube is what its overload protection is for
                bits &= ~0x20
            faults = [text for bit, text in STATUS_BITS.items() if bits & bit]
            if faults:
                self.known_faults[joint] = self.known_faults.get(joint, 0) | bits
                raise ServoFault(f"The {joint} servo reports: {', '.join(faults)} (status "
                                 f"0x{int(bits):02x}). Fix: check the power supply (voltage), "
                                 "let the servo cool down, or free the arm from what it pushes "
                                 "against.")

    def _check_tracking(self, commanded: Configuration, measured: Configuration,
                        now: float) -> None:
        for joint, tolerance in self.tracking_tolerance.items():
            if tolerance is None:
                continue
            error = abs(measured[joint] - commanded[joint])
            if error <= tolerance:
                self._beyond.pop(joint, None)
                continue
            since = self._beyond.setdefault(joint, now)
            if now - since >= self.tracking_timeout:
                raise TrackingError(
                    f"{joint} does not follow its command: measured {measured[joint]:.1f} "
                    f"{unit(joint)}, commanded {commanded[joint]:.1f} {unit(joint)} (error "
                    f"{error:.1f} > tolerance {tolerance:g} {unit(joint)} for "
                    f"{now - since:.2f} s). Something blocks the arm (the table, an object, a "
                    "cable) or the servo is overloaded: clear the way and check the power supply; "
                    "--tracking-tolerance changes the tolerance.")

    # motion
    def _begin(self) -> float:
        """Start (or continue) the loop for a new segment; returns its start time [s]."""
        t_start = self.loop.resume()
        if self._t0 is None:
            self._t0 = t_start
        return t_start

    def _run(self, command_at: Callable[[float], Mapping[str, float]], duration: float,
             t_start: float) -> None:
        """Cycle until the segment's own clock reaches ``duration`` [s].

        The segment's clock advances by the time between cycles (at most
        ``MAX_ADVANCE_S``) only while the arm is observed: during an outage
        the last goal is repeated and the plan resumes where it paused.
        """
        elapsed, last = 0.0, t_start

        def at(deadline: float) -> Mapping[str, float]:
            nonlocal elapsed, last
            if self.observed:
                elapsed = min(duration, elapsed + min(deadline - last, MAX_ADVANCE_S))
            last = deadline
            return command_at(elapsed)

        while elapsed < duration - 1e-9:
            self._cycle(at)

    def move(self, cfg: Mapping[str, float], duration: float, step: str | None = None,
             max_speed: Mapping[str, float] | None = None) -> Segment:
        """Move from the last command (the measured pose at first) to ``cfg`` in ``duration`` [s].

        The duration is stretched (with a warning) if a joint would exceed its speed cap.

        Raises:
            JointLimitError: ``cfg`` is outside the calibrated range (nothing sent).
            TrackingError, BusError, ServoFault, StopRequested, PortLost: see the class.
        """
        goal = check_configuration(cfg, self.limits, "move_to_pose target (calibrated range)")
        if step is not None:
            self.step = step
        if self.command is None:
            self.command = self.read_pose()  # the first move ramps from where the arm is
        start = dict(self.command)
        requested = float(duration)
        caps = max_speed or self.max_speed
        duration = capped_duration(start, goal, requested, self.profile, caps)
        if duration > requested + 1e-9:
            fastest = max(goal, key=lambda j: abs(goal[j] - start[j]) / caps[j])
            distance = abs(goal[fastest] - start[fastest])
            message = (f"'{self.step}': {requested:.2f} s is too fast for the speed cap "
                       f"({fastest} moves {distance:.1f} {unit(fastest)}); "
                       f"stretched to {duration:.2f} s.")
            if max_speed is None:
                logger.warning(message)
                self.stretched.append(message)
        path = Trajectory(start, goal, duration, self.profile)
        t_start = self._begin()
        segment = Segment("move", self.step, t_start - self._t0, start, goal, duration, requested)
        self.segments.append(segment)
        self._run(path.at, duration, t_start)
        return segment

    def hold(self, duration: float, step: str | None = None) -> None:
        """Keep the last command for ``duration`` [s], still reading and checking every cycle."""
        if step is not None:
            self.step = step
        if self.command is None:
            self.command = self.read_pose()
        command = dict(self.command)
        t_start = self._begin()
        self.segments.append(Segment("hold", self.step, t_start - self._t0, command, command,
                                     float(duration), float(duration)))
        self._run(lambda elapsed: command, float(duration), t_start)

    def stop_here(self) -> Configuration | None:
        """Controlled stop: goal = present position (clamped to the calibration), torque stays on.

        Returns:
            The pose the arm stopped at, or None if it cannot be read (then
            every servo that hears us still holds its last goal by itself).
        """
        self._beyond.clear()
        self.loop.sleep(PORT_SETTLE_S)  # let late replies arrive, then drop them
        recover_port(self.bus, settle=False)
        try:
            pose = self._read()
        except Exception:  # noqa: BLE001 - unobserved: the servos hold their last goals
            return None
        goal = {j: min(self.limits[j][1], max(self.limits[j][0], pose[j])) for j in JOINTS}
        self._send(goal)
        self.command = goal
        return pose

    def wait_for_arm(self, timeout: float = RECOVERY_TIMEOUT_S) -> Configuration | None:
        """Poll the arm until every servo answers (then stop there), for up to ``timeout`` [s]."""
        give_up = self.loop.clock() + timeout
        while True:
            pose = self.stop_here()
            if pose is not None or self.loop.clock() >= give_up:
                return pose
            self.loop.sleep(0.1)

    def return_slowly(self, target: Mapping[str, float]) -> Segment:
        """Stop where the arm is, then go to ``target`` at the slow return speed."""
        if self.stop_here() is None:
            raise BusError("Cannot read the arm's position before the return.")
        slow = speed_caps(RETURN_SPEED_DEG_S, RETURN_SPEED_DEG_S)
        return self.move(target, RETURN_MIN_DURATION_S, step="abort_return", max_speed=slow)

    def timing(self) -> dict[str, float]:
        """Loop timing of the cycles so far (see :func:`loop_timing_stats`), plus overruns."""
        stats = loop_timing_stats([c.wall_s for c in self.cycles], 1.0 / self.loop.period)
        stats.update(overruns=self.loop.overruns, skipped=self.loop.skipped)
        return stats


def session_for(bus) -> ArmSession:
    """The :class:`ArmSession` of a bus (created with default settings the first time)."""
    if isinstance(bus, ArmSession):
        return bus
    session = _SESSIONS.get(bus)
    return session if session is not None else ArmSession(bus)


def move_to_pose(bus, cfg: Mapping[str, float], duration: float) -> None:
    """Move the arm to ``cfg`` ([deg], gripper [0, 100]) in ``duration`` [s], as in the simulator.

    Deadline-scheduled at the session's rate, Present_Position read each
    cycle; the first call ramps from the measured pose.

    Args:
        bus: a connected lerobot FeetechMotorsBus (or its :class:`ArmSession`).
        cfg: target configuration.
        duration: [s]; stretched if too fast for the speed cap.
    """
    session_for(bus).move(cfg, duration)


def hold_position(bus, duration: float) -> None:
    """Hold the last commanded pose for ``duration`` [s], reading and checking the arm each cycle.

    Args:
        bus: a connected lerobot FeetechMotorsBus (or its :class:`ArmSession`).
        duration: [s].
    """
    session_for(bus).hold(duration)


@contextmanager
def gc_frozen():
    """Collect garbage once, then freeze: no 0.2 s full collection in the middle of a motion.

    With lerobot (and PyTorch) imported, a full collection of the cyclic
    garbage collector walks about 250 000 objects: about 0.2 s on this
    machine, long enough to stall the arm mid-move. Frozen objects are
    skipped; reference counting still frees everything the loop creates.
    """
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


STOP_SIGNALS = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}
"""Every signal that asks a program to stop, and how the messages name it."""


@contextmanager
def stop_on_signals(session: ArmSession, freeze_at_once: bool = False):
    """Turn every stop signal (Ctrl-C, SIGTERM, SIGHUP) into a stop at the next cycle boundary.

    The first signal sets ``session.stop_reason`` (the loop raises
    StopRequested at its next cycle, never inside a bus transaction); a second
    one raises :class:`FreezeRequested` at once. With ``freeze_at_once`` (during
    the return after an abort) the first signal already freezes. Only in the
    main thread; the previous handlers are restored on exit.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        name = STOP_SIGNALS.get(signum, f"signal {signum}")
        if session.stop_reason is None and not freeze_at_once:
            session.stop_reason = name
            print(f"\nStopping ({name}): the arm returns slowly to its start. {name} again "
                  "freezes it where it is, torque on.", file=sys.stderr, flush=True)
        else:
            raise FreezeRequested(name)

    previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextmanager
def signals_as_interrupt():
    """SIGTERM and SIGHUP raise KeyboardInterrupt, as Ctrl-C does (before and after the motion)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise KeyboardInterrupt(STOP_SIGNALS.get(signum, str(signum)))

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def check_rate(rate_hz) -> float:
    """The control loop's rate [Hz], refused outside [MIN_RATE_HZ, MAX_RATE_HZ]."""
    return check_number(rate_hz, "--rate", MIN_RATE_HZ, MAX_RATE_HZ, "Hz")
