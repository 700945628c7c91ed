"""The deadline-scheduled control loop of the real arm.

The motion side of the hardware backend of the shared motion code
(``motion.py``), on a lerobot bus opened with ``hw/bus.py``:
  - the speed cap and the deadline scheduler are ``hw/timing.py``'s, the stop
    signals and the frozen garbage collector ``hw/signals.py``'s;
  - the control loop (:class:`ArmSession`) behind ``pick_place_hw.py`` and the
    course's helpers (``so101_utils.py``, ``hw/course_helpers.py``), with every stop
    signal (Ctrl-C, SIGTERM, SIGHUP) turned into a stop at a cycle boundary
    (:func:`stop_on_signals`) and the garbage collector frozen during motion
    (:func:`gc_frozen`).

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

import logging
import time
from collections.abc import Callable, Mapping

from so101_kinematics.calibration import calibrated_limits
from so101_kinematics.clearance import check_path
from so101_kinematics.errors import BusError, PortLost, StopRequested
from so101_kinematics.frames import JOINTS
from so101_kinematics.gravity import Feedforward
from so101_kinematics.hw.bus import (
    PORT_SETTLE_S,
    discard_stale_input,
    port_lost,
    read_pose,
    recover_port,
)
from so101_kinematics.hw.cycle_checks import check_status, check_torque, check_tracking
from so101_kinematics.hw.feedforward import tracking_allowance
from so101_kinematics.hw.goals import goal_for, guard, send_goal
from so101_kinematics.hw.grip import held_grip
from so101_kinematics.hw.lead import VelocityLead
from so101_kinematics.hw.misreads import ReadingCheck
from so101_kinematics.hw.timing import (
    DEFAULT_RATE_HZ,
    SPIN_S,
    TRACKING_TOLERANCE_DEG,
    Cycle,
    RateLoop,
    Segment,
    capped_duration,
    check_profile,
    check_rate,
    loop_timing_stats,
    speed_caps,
    stretch_warning,
    tracking_tolerances,
)
from so101_kinematics.inputs import Configuration, check_configuration
from so101_kinematics.planning.motion import Trajectory
from so101_kinematics.trims import Trims, as_trims

__all__ = [
    "ArmSession", "OUTAGE_TOLERANCE_S", "READ_RETRIES", "RECOVERY_TIMEOUT_S",
    "RETURN_MIN_DURATION_S", "RETURN_SPEED_DEG_S", "STATUS_EVERY", "TRACKING_TIMEOUT_S",
    "TRACKING_TOLERANCE_LIMIT_DEG",
]

logger = logging.getLogger(__name__)

# --- Settings ---------------------------------------------------------------
RETURN_SPEED_DEG_S = 20.0          # "slowly": return after an abort [deg/s] (gripper [%/s])
RETURN_MIN_DURATION_S = 1.0        # the return after an abort never takes less [s]
TRACKING_TOLERANCE_LIMIT_DEG = 45.0  # ... at most this [deg] ...
TRACKING_TIMEOUT_S = 0.3           # ... beyond it for this long [s] is a stall or a collision
READ_RETRIES = 1                   # a failed Present_Position read is retried in the cycle
OUTAGE_TOLERANCE_S = 1.0           # the arm may go unobserved this long: the plan pauses [s]
RECOVERY_TIMEOUT_S = 5.0           # after a longer outage, wait this long for the arm [s]
MAX_ADVANCE_S = 0.05               # the trajectory advances at most this much per cycle [s]
STATUS_EVERY = 10                  # read the servos' Status and Torque_Enable every N cycles


# --- The control loop ------------------------------------------------------------
class ArmSession:
    """A connected arm plus the state of its control loop.

    The course's ``move_to_pose(bus, cfg, duration)`` and ``hold_position(bus,
    duration)`` on the real arm are ``so101_utils.py``'s (``hw/course_helpers.py``):
    this loop with the fault policy's endings around each call.

    Args:
        bus: a connected lerobot ``FeetechMotorsBus`` (calibration set).
        rate_hz: control loop rate [Hz], in [``MIN_RATE_HZ``, ``MAX_RATE_HZ``].
        profile: "minimum_jerk" (default, as the simulator), "cubic", "quintic" or "linear".
        max_speed: joint -> speed cap ([deg/s]; gripper [%/s]).
        tracking_tolerance: joint -> |measured - commanded| allowed [deg]
            (None: not checked; the gripper by default, as it squeezes the cube).
        tracking_timeout: how long a joint may stay beyond it [s].
        outage_tolerance: how long the arm may go unobserved (every read
            failing) before the motion stops [s]; meanwhile the plan pauses.
        on_cycle: called with (session, cycle) after each cycle (tests, monitors, the log).
        clock, sleep: time sources (tests; the virtual arm's simulated clock).
        spin: the last part of each wait busy-waited [s] (0 on a simulated clock).
        trims: per-joint offsets (the course's offset_config; ``so101_kinematics.trims``),
            added to every goal written and taken off every position read, here only.
        feedforward: the gravity feed-forward (``hw/feedforward.py``), or None: its
            offsets are added to every goal written (within the calibrated range), so the
            sagging arm rests at the command; positions read are the arm's own.
        base_height: the table is this far below the base frame [m]: every move's path
            is checked against it before it starts (``clearance.check_path``), and may come
            as low as ``rest_pose`` (where the arm stood: the return to it), no lower.
        velocity_lead: the velocity feed-forward (``hw/lead.py``), or None: each goal of a
            move leads the plan by lag x planned velocity, bounded; the checks judge the plan.
    """

    def __init__(self, bus, *, rate_hz: float = DEFAULT_RATE_HZ, profile: str = "minimum_jerk",
                 max_speed: Mapping[str, float] | None = None,
                 tracking_tolerance: Mapping[str, float | None] | None = None,
                 tracking_timeout: float = TRACKING_TIMEOUT_S,
                 outage_tolerance: float = OUTAGE_TOLERANCE_S,
                 on_cycle: Callable[[ArmSession, Cycle], None] | None = None,
                 clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep, trims: Trims | None = None,
                 feedforward: Feedforward | None = None, base_height: float = 0.0,
                 velocity_lead: VelocityLead | None = None, spin: float = SPIN_S):
        check_profile(profile)
        check_rate(rate_hz)
        self.bus = bus
        self.trims = as_trims(trims)  # commands and readings here are the model's angles
        self.feedforward = feedforward
        self.limits = self.trims.limits(calibrated_limits(bus.calibration))
        self.readings = ReadingCheck(self.limits)  # a misread is a failed read
        self.loop = RateLoop(rate_hz, clock, sleep, spin)
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
        self.rest_pose: Configuration | None = None  # where the arm stood before the first move
        self.step = ""
        self.stop_reason: str | None = None
        self.outages: list[tuple[float, float]] = []  # ridden through: (start, length) [s]
        self._t0: float | None = None
        self._beyond: dict[str, float] = {}
        self._unobserved_since: float | None = None
        self.plan_lag_s = 0.0  # [s] the plan ran behind the wall clock (outages, host stalls)
        self.known_faults: dict[str, int] = {}  # joint -> status bits already reported
        self._status_seen: dict[str, int] = {}  # joint -> bits of the last status read
        self._limp_seen: set[str] = set()  # joints whose last Torque_Enable read was 0
        self.stale_bytes = 0  # late-reply bytes dropped before reads
        self.base_height = base_height
        self.velocity_lead = velocity_lead
        self._led: Configuration | None = None  # this cycle's led goal (None: the plan's)

    # measurement and command
    def _read(self) -> Configuration:
        """Present_Position less trims, retried in the call; raises as the bus, or Misread."""
        started = self.loop.clock()
        pose = self.trims.from_wire(read_pose(self.bus, READ_RETRIES))
        return self.readings(pose, self.loop.clock(), started)

    def read_pose(self) -> Configuration:
        """Present_Position of every joint ([deg]; gripper [0, 100]); raises BusError, PortLost."""
        try:
            return self._read()
        except Exception as error:  # noqa: BLE001 - lerobot raises ConnectionError/RuntimeError
            if port_lost(self.bus):
                raise PortLost.during("reading the arm's position") from error
            raise BusError(f"Cannot read the arm's position: {error}") from error

    def _guard(self, command: Mapping[str, float]) -> Configuration:
        """Last line of defence: refuse a command outside the calibrated range (``hw/goals.py``)."""
        return guard(command, self.limits)

    @property
    def observed(self) -> bool:
        """Whether the last read of the arm succeeded."""
        return self._unobserved_since is None

    def goal_for(self, command: Mapping[str, float]) -> Configuration:
        """The goal written for ``command``: plus the gravity feed-forward, in the range."""
        return goal_for(command, self.feedforward, self.limits, self._led)

    def _send(self, command: Configuration) -> None:
        send_goal(self.bus, self.trims, self.goal_for(command))

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
                raise PortLost.during("a control cycle") from error
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
                check_tracking(previous, measured, deadline,
                               tracking_allowance(self.feedforward, self.tracking_tolerance,
                                                  previous, command, self.loop.period),
                               self.tracking_timeout, self._beyond)
            if len(self.cycles) % STATUS_EVERY == 0:
                check_status(self.bus, self.known_faults, self._status_seen)
                check_torque(self.bus, self._limp_seen)
        cycle = Cycle(deadline - self._t0, self.loop.woke - self._t0, self.step, command, measured,
                      self._led and {j: self._led[j] - command[j] for j in command})
        self.cycles.append(cycle)
        if self.on_cycle is not None:
            self.on_cycle(self, cycle)
        return deadline

    # motion
    def _begin(self) -> float:
        """Start (or continue) the loop for a new segment; returns its start time [s]."""
        t_start = self.loop.resume()
        if self._t0 is None:
            self._t0 = t_start
        return t_start

    def _run(self, command_at: Callable[[float], Mapping[str, float]], duration: float,
             t_start: float, lead_at: Callable[[float, Configuration], Configuration] | None = None
             ) -> None:
        """Cycle until the segment's own clock reaches ``duration`` [s].

        The segment's clock advances by the time between cycles (at most
        ``MAX_ADVANCE_S``) only while the arm is observed: during an outage
        the last goal is repeated and the plan resumes where it paused. While the arm
        is observed, ``lead_at(elapsed, planned)`` is the goal written (the velocity lead).
        """
        elapsed, last = 0.0, t_start

        def at(deadline: float) -> Mapping[str, float]:
            nonlocal elapsed, last
            step = deadline - last
            if self.observed:
                elapsed = min(duration, elapsed + min(step, MAX_ADVANCE_S))
            self.plan_lag_s += step if not self.observed else max(0.0, step - MAX_ADVANCE_S)
            last = deadline
            planned = command_at(elapsed)
            self._led = lead_at(elapsed, planned) if lead_at and self.observed else None
            return planned

        try:
            while elapsed < duration - 1e-9:
                self._cycle(at)
        finally:
            self._led = None

    def move(self, cfg: Mapping[str, float], duration: float, step: str | None = None,
             max_speed: Mapping[str, float] | None = None, profile: str | None = None,
             velocity_ff: bool | None = None) -> Segment:
        """Move from the last command (the measured pose at first) to ``cfg`` in ``duration`` [s].

        The duration is stretched (with a warning) if a joint would exceed its speed cap;
        ``profile`` (default the session's) is this move's time scaling; ``velocity_ff``
        leads its goals by the servo's lag (default: as the session's ``velocity_lead``).

        Raises:
            JointLimitError: ``cfg`` is outside the calibrated range (nothing sent).
            ClearanceError: the path goes into the table (nothing sent).
            TrackingError, BusError, ServoFault, StopRequested, PortLost: see the class.
        """
        goal = check_configuration(cfg, self.limits, "move_to_pose target (calibrated range)")
        if step is not None:
            self.step = step
        if self.command is None:
            self.command = self.read_pose()  # the first move ramps from where the arm is
            self.rest_pose = self.rest_pose or dict(self.command)
        start = dict(self.command)
        check_path([start, goal], [self.step or "move_to_pose"], base_height=self.base_height,
                   rest=self.rest_pose)
        requested = float(duration)
        caps = max_speed or self.max_speed
        profile = check_profile(profile or self.profile)
        duration = capped_duration(start, goal, requested, profile, caps)
        if duration > requested + 1e-9:
            message = stretch_warning(self.step, start, goal, requested, duration, caps)
            if max_speed is None:
                logger.warning(message)
                self.stretched.append(message)
        path = Trajectory(start, goal, duration, profile)
        if velocity_ff and self.velocity_lead is None:  # asked for: from the servos read
            self.velocity_lead = VelocityLead.for_feedforward(self.feedforward, enabled=False)
        lead = self.velocity_lead and self.velocity_lead.along(path, velocity_ff)
        t_start = self._begin()
        segment = Segment("move", self.step, t_start - self._t0, start, goal, duration, requested)
        self.segments.append(segment)
        self._run(path.at, duration, t_start, lead)
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

        A gripper holding something (``hw/grip.py``: still, wider than its command) keeps its
        command: its present width as the goal would end the squeeze, and the cube would slip
        out of the stopped jaws (on the 12 V arm it fell 10 cm and landed upside down).

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
            pose = None
        if pose is not None:
            goal = {j: min(self.limits[j][1], max(self.limits[j][0], pose[j])) for j in JOINTS}
            if self.command is not None and held_grip(self) is not None:
                goal["gripper"] = self.command["gripper"]  # the squeeze goes on
            self._led = None  # the stop's goal is where the arm is: nothing leads it
            self._send(goal)
            self.command = goal
        self._record("stop", pose)
        return pose

    def _record(self, step: str, measured: Configuration | None) -> None:
        """A cycle outside the rate loop (a stop, a poll while the arm is silent): logged too."""
        if self._t0 is None or self.command is None:
            return  # nothing commanded yet: no run to log
        now = self.loop.clock() - self._t0
        cycle = Cycle(now, now, step, dict(self.command), measured)
        self.cycles.append(cycle)
        if self.on_cycle is not None:
            self.on_cycle(self, cycle)

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
        stats.update(overruns=self.loop.overruns, skipped=self.loop.skipped,
                     plan_lag_s=self.plan_lag_s)
        return stats
