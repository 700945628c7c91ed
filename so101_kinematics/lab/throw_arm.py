"""The throw on an arm through lerobot: the simulator's throw on the servos, the release read back.

The half of ``throw.py --port PORT`` that moves an arm (the virtual arm or a real one):

1. **preflight** (nothing moves): the servos' ``Present_Voltage`` read through the bus
   (:func:`read_supply`); the throw planned and rehearsed in the simulator at that supply
   (``throwing/throw_run.py``'s :func:`~so101_kinematics.throwing.throw_run.tune_throw`: the
   week-9 cubic swing, the release timed on the rehearsal, the gripper's opening delay
   measured there), so a release speed these servos cannot reach is refused in one line
   (``PlanError``) before the port is armed; the swing's commands checked against the
   calibrated range (``hw/preflight.py``);
2. **the run**: ``hw/run.py``'s ``run_on_arm`` (the course's register values written,
   gravity feed-forward, torque on in place, the fault policy): the approach to the
   wind-up, the settle, then the swing (:func:`_swing`), one command per 10 ms control cycle,
   the simulator's own (``ThrowRun.command``: the plan led by the servo's lag, the velocity
   feed-forward of the simulator's throw), the gripper told to open its delay before the
   release. The session's speed caps are raised for the swing's cycles alone (passed to
   each of its moves; the approach and every return keep the course's); a register the swing
   needs beyond the course's value (``Acceleration``, when the swing's peak acceleration is
   above the firmware's ramp: never in the throwing range at 12 V, :func:`swing_registers`)
   is written just before the swing and put back in a ``finally``, read back, before the
   ending, whatever ended the swing. Then the return to the start and the one ending
   (``hw/run.ending``, from the servos' read-back);
3. **the release read back** (:func:`measured_release`): every control cycle's
   ``Present_Position`` (timestamped) through the bus; the moment the moving jaw has opened
   ``throw_scene.RELEASE_OPENING_DEG`` beyond its hold (the simulator's release: the ball
   slips out there), interpolated between cycles; the joints there and their rates (central
   finite differences), the object frame's position (FK) and velocity (Jacobian); the ball's
   flight (``ball.flight``, drag) from that measured release to the cup's rim.

On an arm there is no simulated ball to compare with: ``model_error_m`` is the distance
between the landings the forward model predicts from the simulator's release (the same
commands on the model) and from the measured release (:data:`MODEL_ERROR_BASIS`).
"""

from __future__ import annotations

import logging
import math
import statistics
from collections.abc import Callable, Mapping
from typing import Any

import mujoco
import numpy as np

from so101_kinematics import servo
from so101_kinematics.errors import ConnectionFailed, PlanError
from so101_kinematics.frames import ARM_JOINTS, TOOL_SITE
from so101_kinematics.hw.bus import bus_errors, connect, disconnect, with_retries
from so101_kinematics.hw.control import RECOVERY_TIMEOUT_S
from so101_kinematics.hw.preflight import validate_plan_for_arm
from so101_kinematics.hw.run import MotionAborted, RunResult, run_on_arm
from so101_kinematics.hw.servo_settings import course_value, read_registers
from so101_kinematics.hw.timing import speed_caps
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.straight_line import CONTROL_DT
from so101_kinematics.sim.scene import gripper_to_radians
from so101_kinematics.throwing.ball import Ball, flight
from so101_kinematics.throwing.throw_plan import GRIPPER_HOLD, SWING_JOINTS, ThrowPlan
from so101_kinematics.throwing.throw_run import (
    OPEN,
    SETTLE_S,
    ThrowRun,
    TunedThrow,
    fly,
    tune_throw,
)
from so101_kinematics.throwing.throw_scene import (
    CUP_HEIGHT,
    CUP_INNER_DIAMETER,
    RELEASE_OPENING_DEG,
)

__all__ = [
    "FIRST_MOVE_DEG", "MODEL_ERROR_BASIS", "RAMP_DEG_S2", "WINDUP_S", "arm_report",
    "measure_opening_on_arm", "opening_line",
    "measured_release", "opening_times", "read_supply", "swing_registers", "throw_on_arm",
]

logger = logging.getLogger(__name__)

WINDUP_S = 3.0
"""The move from where the arm stands to the wind-up, and the return [s] (the course's speed
cap may stretch it)."""
AFTER_S = 0.3
"""The follow-through is held this long [s], still read, before the return."""
SAMPLE = "throw~"  # the swing's steps: throw~0000, ...
FIT_S = 0.06
"""The read-backs within this of the release [s] (13 at 100 Hz) are fitted for the joints'
angles and rates there: long enough to average the encoder's count, short against the
0.5-0.6 s swing, so a cubic follows it."""
FIRST_MOVE_DEG = 1.0
"""The jaw has started to open once its read-back is this far from its hold [deg]: twice the
STS3215's 0.088 deg count and the read-back's jitter at rest (about 0.2 deg on the virtual
arm's faithful servo), small against the 10 deg the ball needs."""
RAMP_DEG_S2 = servo.LEROBOT.acceleration * servo.ACCELERATION_UNIT * 360.0 / servo.COUNTS_PER_TURN
"""The firmware's acceleration ramp at the course's Acceleration (254 x 100 counts/s^2 [MEM],
2232 deg/s^2): a swing whose commands accelerate faster needs the register raised."""
MODEL_ERROR_BASIS = (
    "horizontal distance [m] at the cup's rim height between the forward model's (ball.py's "
    "flight, drag) landing from the planned release (the simulator's throw of the same "
    "commands: its ball's position and velocity when the jaw had opened 10 deg) and from the "
    "release measured on the arm (Present_Position read back every control cycle; the object "
    "frame by FK and Jacobian, its rates by finite differences, at the moment the jaw had "
    "opened 10 deg). On an arm no ball is observed: this is the release's error carried to "
    "the landing, not the model's against a real landing.")


def arm_report(port: str, volts: float, seed: int | None, ball: Ball, trials: list) -> dict:
    """``throw.py --port``'s JSON report of ``trials`` (each :func:`throw_on_arm`'s)."""
    return {"hits": sum(t["in_cup"] for t in trials), "throws": len(trials), "port": port,
            "supply_v": round(volts, 2), "seed": seed, "model_error_basis": MODEL_ERROR_BASIS,
            "ball": ball.report(),
            "trials": trials}


def opening_line(port: str, opening: Mapping[str, Any]) -> str:
    """``throw.py --measure-opening``'s line: :func:`measure_opening_on_arm`'s figures."""
    moved, free = opening["moved_s"], opening["free_s"]
    return (f"Opening delay at rest on {port} ({opening['supply_v']:g} V, {opening['samples']} "
            f"read-backs): the jaw moved {FIRST_MOVE_DEG:g} deg after "
            + ("-" if moved is None else f"{moved:.3f} s")
            + f", opened {RELEASE_OPENING_DEG:g} deg (the ball free) after "
            + ("-" if free is None else f"{free:.3f} s")
            + f"; the simulator's {opening['simulator_s']:.3f} s (use: --opening-delay "
            + ("S" if free is None else f"{free:.3f}") + ")")


def read_supply(port: str, calibration: Mapping[str, Any], robot_id: str | None = None) -> float:
    """The servos' supply [V]: the median ``Present_Voltage`` read through the bus (nothing moves).

    Raises:
        ConnectionFailed, CalibrationError, LerobotMissing: as ``hw/bus.connect`` (one line).
        ConnectionFailed: no servo reported its voltage.
    """
    bus = connect(port, calibration, robot_id=robot_id)
    try:
        values = read_registers(bus, ("Present_Voltage",)).get("Present_Voltage", {})
    finally:
        disconnect(bus)
    volts = [v / 10.0 for v in values.values() if v > 0]  # 0.1 V a unit [MEM]
    if not volts:
        raise ConnectionFailed(f"No servo on {port} reported its Present_Voltage: the throw's "
                               "speed cannot be checked against the supply (nothing moved). "
                               "Fix: check the arm's power supply and cables, then run again.")
    return statistics.median(volts)


def _swing_commands(m: mujoco.MjModel, ball: Ball, throw: TunedThrow) -> list[dict[str, float]]:
    """The swing's commands, one per control cycle: the simulator's ``ThrowRun.command``."""
    run = ThrowRun(m, ball, throw.plan, open_at=throw.open_at)
    cycles = math.ceil(throw.plan.duration / CONTROL_DT)
    return [run.command(run.start + k * CONTROL_DT) for k in range(1, cycles + 1)]


def swing_registers(plan: ThrowPlan, dt: float = CONTROL_DT) -> dict[str, int]:
    """The registers the swing needs beyond the course's values, on its swinging joints.

    ``Acceleration`` 0 (no ramp [MEM]) when the planned swing (the cubic, sampled every
    ``dt``) accelerates faster than :data:`RAMP_DEG_S2`; none otherwise. The cubic's peak is
    ``6 SWING_DEG / T^2``: 0.86 deg/s^2 x 1000 for a cup 0.4 m away, 1.76 x 1000 at the
    range's 0.8 m end at 12 V, under the course's ramp, which is also the rehearsal's (the
    simulator's servo model has it): the course's register stays.
    """
    steps = math.ceil(plan.duration / dt)
    angles = np.array([[plan.configuration(k * dt / plan.duration)[j] for j in SWING_JOINTS]
                       for k in range(steps + 1)])
    if len(angles) < 3:
        return {}
    peak = float(np.abs(np.diff(angles, 2, axis=0)).max()) / dt ** 2
    return {"Acceleration": 0} if peak > RAMP_DEG_S2 else {}


def _restore(session, raised: Mapping[str, Mapping[str, int]]) -> dict[str, bool]:
    """Write the course's values back where ``raised`` put others: register -> read back so.

    Tried until read back, for up to ``RECOVERY_TIMEOUT_S`` (the fault policy's wait for a
    silent arm: a bus outage mid-swing loses the writes and the reads until it ends).
    """
    restored = {}
    for register, joints in raised.items():
        values = {j: course_value(register, j) for j in joints}
        give_up = session.loop.clock() + RECOVERY_TIMEOUT_S
        while True:
            try:
                session.bus.sync_write(register, values, normalize=False)
            except Exception as error:  # noqa: BLE001 - read back below, said in the log
                logger.warning("Writing %s back failed: %s", register, error)
            read = read_registers(session.bus, (register,)).get(register, {})
            restored[register] = all(read.get(j) == v for j, v in values.items())
            if restored[register] or session.loop.clock() >= give_up:
                break
            session.loop.sleep(0.1)
        (logger.info if restored[register] else logger.error)(
            "%s %s to the course's %s on %s (read back).", register,
            "put back" if restored[register] else "could NOT be put back",
            "/".join(sorted({str(v) for v in values.values()})), ", ".join(values))
    return restored


def _swing(commands: list[dict[str, float]], caps: Mapping[str, float],
           registers: Mapping[str, int], restored: dict[str, bool]) -> Callable:
    """The run's closed loop after the approach: the swing, its registers put back always."""
    def swing(session) -> None:
        raised: dict[str, dict[str, int]] = {}
        try:
            for register, value in registers.items():
                raised[register] = dict.fromkeys(SWING_JOINTS, value)
                with bus_errors(f"raising {register} for the swing"):
                    with_retries(lambda b, r=register: b.sync_write(r, raised[r],
                                                                    normalize=False),
                                 session.bus)
                logger.info("%s %d on %s for the swing.", register, value,
                            ", ".join(SWING_JOINTS))
            # one command a cycle, chosen by the clock: a late or skipped cycle (a busy host)
            # skips commands instead of slowing the swing, whose release is timed
            started, k = session.loop.clock(), 0
            while k < len(commands):
                session.move(commands[k], CONTROL_DT, step=f"{SAMPLE}{k:04d}", max_speed=caps,
                             profile="linear")
                k = max(k + 1, round((session.loop.clock() - started) / CONTROL_DT))
            session.hold(AFTER_S, step="follow_through")
        finally:  # every ending of the swing: a fault, a stop signal, done
            restored.update(_restore(session, raised))
    return swing


def _swing_caps(commands: list[Mapping[str, float]], start: Mapping[str, float],
                limits: Mapping[str, float]) -> dict[str, float]:
    """The speed caps of the swing's moves: its fastest cycle, within the servos' top speed.

    Raises:
        PlanError: a swinging joint commanded faster than its servo turns (nothing moved).
    """
    rows = [start, *commands]
    caps = speed_caps()
    for joint in caps:
        steps = zip(rows, rows[1:], strict=False)
        fastest = max(abs(b[joint] - a[joint]) for a, b in steps) / CONTROL_DT
        top = math.degrees(limits.get(joint, math.inf))
        if joint in SWING_JOINTS and fastest > top:
            raise PlanError(f"the swing commands {joint} at {fastest:.0f} deg/s, above its "
                            f"servo's {top:.0f} deg/s (nothing moved). Fix: a nearer cup.")
        caps[joint] = max(caps[joint], 1.01 * fastest)  # raised for the swing only
    return caps


def opening_times(samples: list[tuple[float, Mapping[str, float]]], open_at: float,
                  m: mujoco.MjModel) -> tuple[float | None, float | None, float]:
    """When the jaw started to open and when it had opened enough for the ball [s].

    Args:
        samples: (time [s], read-back configuration) per control cycle, in order.
        open_at: when the open command was written [s, the samples' clock].
        m: a model of the arm (the gripper's range: [0, 100] -> rad).

    Returns:
        ``(moved, free, hold)``: the first crossing of ``FIRST_MOVE_DEG`` and of
        ``RELEASE_OPENING_DEG`` beyond the hold (linear between samples; None if never),
        and the hold [deg] (the median read-back before ``open_at``).
    """
    t = np.array([s for s, _ in samples])
    jaw = np.degrees([gripper_to_radians(m, c["gripper"]) for _, c in samples])
    before = jaw[t <= open_at + 1e-9]
    hold = float(np.median(before[-10:])) if len(before) else float(jaw[0])

    def crossing(beyond: float) -> float | None:
        after = np.flatnonzero((t > open_at + 1e-9) & (jaw - hold >= beyond))
        if not len(after):
            return None
        k = int(after[0])
        if k == 0:
            return float(t[0])
        a, b = jaw[k - 1] - hold, jaw[k] - hold
        share = 1.0 if b == a else (beyond - a) / (b - a)
        return float(t[k - 1] + min(1.0, max(0.0, share)) * (t[k] - t[k - 1]))

    return crossing(FIRST_MOVE_DEG), crossing(RELEASE_OPENING_DEG), hold


def measured_release(m: mujoco.MjModel, samples: list[tuple[float, Mapping[str, float]]],
                     at: float) -> tuple[np.ndarray, np.ndarray]:
    """The object frame's position [m] and velocity [m/s] at time ``at`` from read-back samples.

    Each arm joint's read-back within ``FIT_S`` of ``at`` is fitted by a cubic in time (least
    squares; the swing is a cubic move), whose value and slope at ``at`` are the joint's angle
    and rate: finite differences of neighbouring read-backs would carry the encoder's count
    (0.088 deg) over 20 ms into the rate, 4.4 deg/s, 3 % of the swing's. Position by the FK,
    velocity by the site's Jacobian (MuJoCo's) times the rates.
    """
    t = np.array([s for s, _ in samples])
    q = np.radians([[c[j] for j in ARM_JOINTS] for _, c in samples])
    near = np.abs(t - at) <= FIT_S
    if near.sum() < 5:
        raise PlanError(f"only {int(near.sum())} read-backs within {FIT_S:g} s of the release: "
                        "too few to fit the joints' motion there.")
    d = mujoco.MjData(m)
    dofs, qdot = [], []
    for k, joint in enumerate(ARM_JOINTS):
        fit = np.polyfit(t[near] - at, q[near, k], 3)
        d.qpos[m.joint(joint).qposadr[0]] = fit[-1]
        qdot.append(fit[-2])
        dofs.append(m.joint(joint).dofadr[0])
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    jac = np.zeros((3, m.nv))
    site = m.site(TOOL_SITE).id
    mujoco.mj_jacSite(m, d, jac, None, site)
    return d.site_xpos[site].copy(), jac[:, dofs] @ np.array(qdot)


def _landing(point, velocity, ball: Ball) -> np.ndarray:
    """The forward model's landing (x, y) [m] at the cup's rim height."""
    return flight(point, velocity, ball, CUP_HEIGHT)[0, :2]


def _rounded(values, digits: int = 4) -> list[float]:
    return [round(float(v), digits) for v in values]


def _read_back(m: mujoco.MjModel, ball: Ball, throw: TunedThrow, simulated: dict,
               result: RunResult, swing_start: float | None) -> dict:
    """The trial's figures from the run's read-back (JSON-ready)."""
    samples = [(c.wall_s, c.measured) for c in result.cycles
               if c.measured is not None and (c.step.startswith(SAMPLE)
                                              or c.step in ("settle", "follow_through"))]
    target = np.asarray(throw.plan.target)
    planned_p, planned_v = (np.asarray(simulated[k]) for k in ("release_point",
                                                                 "release_velocity"))
    planned_landing = _landing(planned_p, planned_v, ball)
    trial = {"cup": _rounded(target), "cup_distance_m": round(float(np.hypot(*target)), 4),
             "pan_deg": round(throw.plan.pan_deg, 2),
             "swing_rate_rad_s": round(throw.plan.rate, 3),
             "opening_delay_s": round(throw.delay, 4),
             "planned_release_point": _rounded(planned_p),
             "planned_release_velocity": _rounded(planned_v),
             "planned_landing": _rounded(planned_landing),
             "simulator_in_cup": simulated["in_cup"], "in_cup": False, "model_error_m": None,
             "model_error_basis": MODEL_ERROR_BASIS, "samples": len(samples)}
    if swing_start is None or len(samples) < 3:
        return {**trial, "failure": "the swing did not run (no read-back)"}
    open_at = swing_start + throw.open_at
    moved, free, hold = opening_times(samples, open_at, m)
    trial.update(open_command_s=round(throw.open_at, 4), jaw_hold_deg=round(hold, 2),
                 jaw_moved_s=None if moved is None else round(moved - swing_start, 4),
                 measured_opening_delay_s=None if free is None else round(free - open_at, 4))
    if free is None:
        return {**trial, "failure": f"the jaw never opened {RELEASE_OPENING_DEG:g} deg (read "
                                    "back): the ball was not let go"}
    point, velocity = measured_release(m, samples, free)
    landing = _landing(point, velocity, ball)
    radial = float(np.hypot(*(landing - target)))
    return {**trial, "release_s": round(free - swing_start, 4),
            "release_point": _rounded(point), "release_velocity": _rounded(velocity),
            "release_speed_m_s": round(float(np.linalg.norm(velocity)), 3),
            "release_elevation_deg": round(math.degrees(math.atan2(
                velocity[2], np.hypot(*velocity[:2]))), 2),
            "predicted_landing": _rounded(landing),
            "predicted_miss_m": round(radial, 4),
            # the ball's whole body through the mouth: its centre within the inner radius
            # less its own radius at the rim's height
            "in_cup": bool(radial <= CUP_INNER_DIAMETER / 2.0 - ball.radius),
            "model_error_m": round(float(np.hypot(*(landing - planned_landing))), 5)}


def _swing_start(result: RunResult) -> float | None:
    """When the swing's first command was written [s, the cycles' clock], minus one cycle."""
    for c in result.cycles:
        if c.step.startswith(SAMPLE):
            return c.wall_s - CONTROL_DT
    return None


def _windup_plan(windup: Mapping[str, float]) -> Plan:
    """The run's plan before its closed loop: to the wind-up, settle there; the return after."""
    return Plan([Step("wind_up", windup, WINDUP_S, 0.0), Step("settle", windup, 0.0, SETTLE_S)],
                return_to_start=True, return_duration=WINDUP_S)


def throw_on_arm(port: str, calibration: Mapping[str, Any], m: mujoco.MjModel, ball: Ball,
                 target, *, volts: float | None = None, opening_delay: float | None = None,
                 registers: Mapping[str, int] | None = None,
                 **run_options) -> tuple[dict, RunResult]:
    """Throw ``ball`` at a cup at ``target`` (x, y) [m] with the arm at ``port``: trial, run.

    Args:
        port: the arm's serial port.
        calibration: its lerobot calibration.
        m: the throwing model (``throw_scene.build_throw_model``) at the arm's supply.
        ball: the ball in the jaws.
        target: the cup's (x, y) [m].
        volts: the servos' supply [V] (default: read through the bus, :func:`read_supply`).
        opening_delay: the arm's opening delay at rest [s] (``--opening-delay``, measured
            with :func:`measure_opening_on_arm`): the gripper is told to open earlier by its
            excess over the simulator's (default: the simulator's, none).
        registers: registers raised on the swinging joints for the swing (default: what
            :func:`swing_registers` says the swing needs).
        **run_options: ``run_on_arm``'s (``confirm``, ``time_source``, ...).

    Returns:
        The trial (``in_cup``, ``model_error_m``, ``predicted_landing``, the measured and the
        planned release, ``registers_restored``, ``aborted``, ...) and ``run_on_arm``'s result,
        completed or aborted (its ending is the run's last line).

    Raises:
        PlanError, ConnectionFailed, CalibrationError: refused before anything moved (one line).
    """
    if volts is None:
        volts = read_supply(port, calibration, run_options.get("robot_id"))
    variant = servo.default_variant(volts)
    throw = tune_throw(m, ball, target, volts, variant)
    delay_offset = 0.0 if opening_delay is None else opening_delay - throw.resting_delay
    # the open command on the control cycle's grid (the arm writes goals once a cycle), the
    # nearest to the simulator's time less the arm's extra delay; the simulator flies the same
    written = CONTROL_DT * round((throw.open_at - delay_offset) / CONTROL_DT)
    throw = TunedThrow(throw.planned_speed, throw.plan, throw.limits, throw.release_at,
                       throw.resting_delay + delay_offset, throw.release_at - written,
                       throw.aimed)
    simulated = fly(m, ball, throw)
    if "release_point" not in simulated:
        raise PlanError(f"the simulator's throw at {tuple(target)} let no ball go ("
                        f"{simulated.get('failure')}; nothing moved). Fix: a cup in range.")
    windup = {**throw.plan.configuration(0.0), "gripper": GRIPPER_HOLD}
    commands = _swing_commands(m, ball, throw)
    caps = _swing_caps(commands, windup, throw.limits)
    chosen = swing_registers(throw.plan) if registers is None else dict(registers)
    plan = _windup_plan(windup)
    # the swing's commands checked before the port is armed (the approach's are run_on_arm's)
    validate_plan_for_arm(Plan([Step(f"{SAMPLE}{k:04d}", c, CONTROL_DT, 0.0)
                                for k, c in enumerate(commands)], return_to_start=False),
                          calibration, "the calibration", run_options.get("trims"))
    restored: dict[str, bool] = {}
    options = {"profile": "minimum_jerk", "gravity_ff": True, **run_options}
    try:
        result = run_on_arm(port, calibration, plan, then=_swing(commands, caps, chosen, restored),
                            **options)
    except MotionAborted as error:  # ended by the fault policy: reported all the same
        result = error.result
    trial = _read_back(m, ball, throw, simulated, result, _swing_start(result))
    trial.update(supply_v=round(volts, 2), variant=variant,
                 swing_caps_deg_s={j: round(v, 1) for j, v in caps.items() if j in SWING_JOINTS},
                 registers_raised=chosen, registers_restored=restored,
                 # a busy host's late cycles: the swing skips commands to stay on time
                 loop_skipped=result.timing.get("skipped"),
                 aborted=None if result.aborted is None else str(result.aborted))
    return trial, result


def measure_opening_on_arm(port: str, calibration: Mapping[str, Any], m: mujoco.MjModel,
                           ball: Ball, target=(0.4, 0.0), **run_options) -> tuple[dict, RunResult]:
    """The gripper's opening delay at rest on the arm at ``port`` (the documented procedure).

    The arm goes to the throw's wind-up (a cup at ``target``), settles holding
    ``GRIPPER_HOLD``, the gripper is told to open fully (one ``Goal_Position`` write), its
    ``Present_Position`` is read every control cycle for a second, and the arm returns.

    Returns:
        ``{"moved_s", "free_s", "hold_deg", "simulator_s", ...}``: from the open command
        until the jaw read back ``FIRST_MOVE_DEG`` from its hold, and
        ``RELEASE_OPENING_DEG`` (the ball free: the simulator's opening delay, given beside
        as ``simulator_s``); and the run's result.
    """
    volts = run_options.pop("volts", None) or read_supply(port, calibration,
                                                          run_options.get("robot_id"))
    throw = tune_throw(m, ball, target, volts, servo.default_variant(volts))
    windup = {**throw.plan.configuration(0.0), "gripper": GRIPPER_HOLD}
    opened = {**windup, "gripper": OPEN}
    caps = {**speed_caps(), "gripper": 1.01 * (OPEN - GRIPPER_HOLD) / CONTROL_DT}

    def open_and_watch(session) -> None:
        session.move(opened, CONTROL_DT, step=f"{SAMPLE}open", max_speed=caps, profile="linear")
        session.hold(1.0, step="follow_through")

    plan = _windup_plan(windup)
    try:
        result = run_on_arm(port, calibration, plan, then=open_and_watch,
                            **{"gravity_ff": True, **run_options})
    except MotionAborted as error:
        result = error.result
    samples = [(c.wall_s, c.measured) for c in result.cycles if c.measured is not None
               and (c.step.startswith(SAMPLE) or c.step in ("settle", "follow_through"))]
    start = _swing_start(result)
    report = {"moved_s": None, "free_s": None, "hold_deg": None,
              "simulator_s": round(throw.resting_delay, 4), "supply_v": round(volts, 2),
              "samples": len(samples),
              "aborted": None if result.aborted is None else str(result.aborted)}
    if start is not None and len(samples) >= 3:
        # the open command is written at the first cycle of its step: the swing's start + 1
        written = start + CONTROL_DT
        moved, free, hold = opening_times(samples, written, m)
        report.update(moved_s=None if moved is None else round(moved - written, 4),
                      free_s=None if free is None else round(free - written, 4),
                      hold_deg=round(hold, 2))
    return report, result
