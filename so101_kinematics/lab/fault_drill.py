"""Fault drills: the hardware run against the virtual SO-101, one fault injected at one phase.

Each drill starts a fresh virtual arm, runs a short pick-and-place through
the real hardware path (lerobot's bus, :func:`so101_kinematics.hw.run.run_on_arm`, the
streamed CSV log), injects the fault at the first cycle of a phase, and
records how the run ended and how the arm was left. With ``sim_clock`` the drill runs on
the virtual arm's simulated clock (``virtual/sim_clock.py``): the control loop and the
physics take simulated time, only the bus's bytes and timeouts take wall time. The fault matrix in
docs/hardware_safety.md is :func:`main`'s output: ``python -m so101_kinematics.lab.fault_drill``.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from so101_kinematics.calibration import load_calibration
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.frames import JOINTS
from so101_kinematics.hw.log import CycleLog
from so101_kinematics.hw.run import RELEASE_HINT, MotionAborted, ending, run_on_arm
from so101_kinematics.paths import DOCS_DIR
from so101_kinematics.planning.motion import Plan, Step

__all__ = ["FAULTS", "PHASES", "run_drill"]

DOC_PATH = DOCS_DIR / "hardware_safety.md"
AT_START_DEG = 2.0  # "at the start": every arm joint within this of its starting angle [deg]

HOME = HOME_POSE  # the virtual arm powers up there

PHASES = {"approach": "approach", "grasp": "grasp", "carry (cube lifted)": "carry",
          "return": "return_to_start"}
"""Phase -> the drill plan's step during which the fault is injected."""

FAULTS = {
    "3 replies lost": "drop:shoulder_lift:3",
    "bus outage 0.5 s": "outage:500",
    "bus outage 2.5 s": "outage:2500",
    "replies 80 ms late (x3)": "latency:80:3",
    "elbow_flex overheats": "overheat:elbow_flex",
    "shoulder_pan stalls": "stall:shoulder_pan",
    "wrist_flex servo lost": "remove:wrist_flex",
    "USB cable pulled": "unplug",
    "SIGTERM": "SIGTERM",
    "SIGHUP twice": "SIGHUP,SIGHUP",
}
"""Fault label -> virtual-arm fault specification, or the signal(s) sent to this process."""


def drill_plan() -> Plan:
    """Four phases in about 5 s: approach, grasp (the jaws close), carry (pan 60 deg), return."""
    approach = dict(HOME, shoulder_lift=-60.0, elbow_flex=60.0, gripper=50.0)
    grasp = dict(approach, gripper=5.0)
    carry = dict(grasp, shoulder_pan=60.0, shoulder_lift=-70.0)
    return Plan([Step("approach", approach, 0.8, 0.1), Step("grasp", grasp, 0.5, 0.1),
                 Step("carry", carry, 1.0, 0.1)], return_duration=1.0)


@dataclass
class Drill:
    """How one drill ended."""

    fault: str
    phase: str
    completed: bool  # the plan ran to its end
    aborted: str | None
    at_start: bool  # every arm joint within AT_START_DEG of its start (MuJoCo's truth)
    torque_off: list[str]  # joints whose torque is off at the end
    goals_outside: int  # Goal_Position writes outside the calibrated range
    cycles: int
    log_rows: int
    last_line: str
    seconds: float  # [s] of wall time the drill took

    @property
    def outcome(self) -> str:
        """One cell of the fault matrix."""
        how = "completed" if self.completed else "stopped"
        if self.at_start and len(self.torque_off) == len(JOINTS):
            return f"{how}; back at the start, released"
        where = "at the start" if self.at_start else "away from the start"
        torqued = "torque on" if not self.torque_off else f"torque off on {self.torque_off}"
        return f"{how}; holding {where}, {torqued}"


def _injector(arm, fault: str, step: str):
    signals = [getattr(signal, name) for name in fault.split(",") if name.startswith("SIG")]

    def on_cycle(session, cycle):
        if cycle.step == step and not on_cycle.fired:
            on_cycle.fired = True
            if signals:
                os.kill(os.getpid(), signals[0])
            else:
                arm.inject(fault)
        elif len(signals) > 1 and cycle.step == "abort_return" and not on_cycle.second:
            on_cycle.second = True
            os.kill(os.getpid(), signals[1])

    on_cycle.fired = on_cycle.second = False
    return on_cycle


def run_drill(fault: str, phase: str, folder: str | Path | None = None,
              velocity_ff: bool = False, profile: str = "minimum_jerk",
              sim_clock: bool = False) -> Drill:
    """Run the drill plan on a fresh virtual arm with ``fault`` injected at ``phase``.

    Args:
        fault: a label of :data:`FAULTS`.
        phase: a label of :data:`PHASES`.
        folder: where the CSV log goes (default: a temporary folder).
        velocity_ff: run with the velocity lead (``--velocity-ff``, ``hw/lead.py``).
        profile: the moves' time scaling (``--profile``).
        sim_clock: run the arm and the control loop on the virtual arm's simulated clock
            (default: the wall clock).
    """
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    calibration = load_calibration(DEFAULT_CALIBRATION_PATH)
    folder = Path(folder or tempfile.mkdtemp(prefix="so101-drill-"))
    log_path = folder / f"{fault}-{phase}.csv".replace(" ", "_")
    started = time.perf_counter()
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, sim_clock=sim_clock) as arm:
        sleep = time.sleep if arm.clock is None else arm.clock.sleep
        start = arm.joint_positions()
        inject = _injector(arm, FAULTS[fault], PHASES[phase])
        log = CycleLog(log_path)

        def on_cycle(session, cycle):
            log(session, cycle)
            inject(session, cycle)

        try:
            result = run_on_arm(arm.port, calibration, drill_plan(), on_cycle=on_cycle,
                                velocity_ff=velocity_ff, profile=profile, time_source=arm.clock)
        except MotionAborted as error:
            result = error.result
        finally:
            log.close()
        sleep(0.3)  # a held arm must still be where it was; a released one may settle
        final, torque = result.final_pose or arm.joint_positions(), arm.torque_enabled()
        goals = arm.goal_log()
    by_id = {cal.id: cal for cal in calibration.values()}
    outside = sum(not by_id[servo].range_min <= ticks <= by_id[servo].range_max
                  for _, servo, ticks in goals)
    at_start = all(abs(final[j] - start[j]) <= AT_START_DEG for j in JOINTS if j != "gripper")
    release = RELEASE_HINT.format(port="PORT", arm="--id ARM")
    return Drill(fault, phase, result.aborted is None, result.aborted, at_start,
                 [j for j, on in torque.items() if not on], outside, len(result.cycles),
                 len(log_path.read_text().splitlines()) - 1, ending(result, release),
                 time.perf_counter() - started)


def matrix_markdown(drills: list[Drill]) -> str:
    """The fault matrix as a Markdown table, fault x phase."""
    phases = list(PHASES)
    rows = ["| fault | " + " | ".join(phases) + " |", "|---" * (len(phases) + 1) + "|"]
    for fault in FAULTS:
        cells = {d.phase: d.outcome for d in drills if d.fault == fault}
        rows.append(f"| {fault} (`{FAULTS[fault]}`) | "
                    + " | ".join(cells.get(p, "") for p in phases) + " |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    """Run every drill and print (or write, with --write) the fault matrix."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help=f"update {DOC_PATH.name}'s table")
    parser.add_argument("--sim-clock", action="store_true",
                        help="run the drills on the virtual arm's simulated clock")
    args = parser.parse_args(argv)
    drills = []
    for fault in FAULTS:
        for phase in PHASES:
            drill = run_drill(fault, phase, sim_clock=args.sim_clock)
            print(f"{fault:>26} @ {phase:<20} {drill.outcome} ({drill.seconds:.1f} s)",
                  file=sys.stderr, flush=True)
            drills.append(drill)
    table = matrix_markdown(drills)
    print(table)
    if args.write:
        from so101_kinematics.outputs import write_text_atomic

        text = DOC_PATH.read_text(encoding="utf-8")
        begin, end = "<!-- fault matrix: begin -->", "<!-- fault matrix: end -->"
        head, rest = text.split(begin)
        _, tail = rest.split(end)
        write_text_atomic(DOC_PATH, f"{head}{begin}\n{table}\n{end}{tail}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
