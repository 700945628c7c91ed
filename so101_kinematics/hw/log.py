"""The hardware run's log: a CSV written as the run goes, that survives any ending, and its plot.

:class:`CycleLog` appends one row per control cycle to a temporary file
beside the target, flushed at least every ``FLUSH_EVERY_S`` of run time, and
renames it over the target when closed, whatever ended the run (done, abort,
signal, exception). After a SIGKILL the temporary file (``.NAME.*.part.csv``
beside the target) still holds every cycle up to its last flush.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Iterable
from pathlib import Path

from so101_kinematics.frames import JOINTS
from so101_kinematics.hw.control import ArmSession
from so101_kinematics.hw.timing import Cycle
from so101_kinematics.inputs import unit
from so101_kinematics.markers import png_metadata
from so101_kinematics.outputs import (
    JSON_REPORT,
    OutputKind,
    atomic_output,
    csv_kind,
    forget_temporary,
    stamp,
    temporary_beside,
    write_text_atomic,
)
from so101_kinematics.planning.motion import Plan
from so101_kinematics.trims import Trims

__all__ = [
    "CycleLog", "HEADER", "LOG_KIND", "SIDECAR_KIND", "plan_record", "plot_log",
    "sidecar_path", "write_log_csv",
]

FLUSH_EVERY_S = 0.5  # the log reaches the disk at least this often [s of run time]
BEFORE_LEAD = (["t_s", "wall_s", "step"] + [f"cmd_{j}" for j in JOINTS]
               + [f"meas_{j}" for j in JOINTS] + [f"trim_{j}" for j in JOINTS])
HEADER = BEFORE_LEAD + [f"lead_{j}" for j in JOINTS]
"""CSV columns: scheduled and actual cycle start [s], step, commanded and measured joints,
each joint's trim (the course's offset_config: the servo got cmd + trim and read meas + trim;
cmd and meas are the model's angles), and each joint's velocity lead (``hw/lead.py``: the goal
led the plan by it; empty without --velocity-ff)."""
_KINDS = (csv_kind(HEADER, ""), csv_kind(BEFORE_LEAD, ""))
LOG_KIND = OutputKind("a CSV log of pick_place_hw.py (its header row)",
                      lambda path: any(kind.recognise(path) for kind in _KINDS),
                      replaceable=False)
"""How an existing log of ours is recognised (``outputs.check_output_path``); a log written
before the lead's columns too. It is never replaced without ``--overwrite``: it holds a
run that cannot be run again (the next run is refused, the message names a free name)."""
SIDECAR_KIND = OutputKind("the sidecar of a pick_place_hw.py log (its generator key)",
                          JSON_REPORT.recognise, replaceable=False)
"""A log's sidecar (:func:`sidecar_path`), kept as its log is."""


def sidecar_path(path: str | Path) -> Path:
    """The run's sidecar beside its CSV log: ``run.csv`` -> ``run.run.json``."""
    path = Path(path)
    return path.with_name(path.stem + ".run.json")


def plan_record(plan: Plan) -> dict:
    """``plan`` as a waypoint file's table (``plans.load_plan`` reads it back)."""
    return {"steps": [{"name": s.name, "configuration": dict(s.configuration),
                       "duration": s.duration, "hold": s.hold} for s in plan.steps],
            "return_to_start": plan.return_to_start, "return_duration": plan.return_duration}


def cycle_row(cycle: Cycle, trims: Trims | None = None) -> list[str]:
    """One CSV row; the measured columns are empty when the read failed."""
    measured = [f"{cycle.measured[j]:.4f}" if cycle.measured else "" for j in JOINTS]
    trims = trims or Trims()
    lead = [f"{cycle.lead.get(j, 0.0):.4f}" if cycle.lead else "" for j in JOINTS]
    return ([f"{cycle.t_s:.6f}", f"{cycle.wall_s:.6f}", cycle.step]
            + [f"{cycle.command[j]:.4f}" for j in JOINTS] + measured
            + [f"{trims.offsets[j]:g}" for j in JOINTS] + lead)


class CycleLog:
    """A CSV log written while the arm moves; use as the session's ``on_cycle`` hook.

    The CSV stays plain (one header row, one row per cycle). What a replay
    needs (``run_info``: the plan, the measured starting pose, the rate, the
    calibration, the servos, the velocity feed-forward: on or off, its lags, cap
    and largest leads; ``aborted``: why the run stopped, null when complete) goes
    to a JSON sidecar beside it (:func:`sidecar_path`), written atomically when the
    log is closed.

    Args:
        path: the CSV to produce (checked beforehand: ``outputs.check_output_path``).
        run_info: the sidecar's content (add ``start_pose`` once measured); None: no sidecar.
    """

    def __init__(self, path: str | Path, run_info: dict | None = None):
        self.path = Path(path)
        self.run_info = run_info
        self.temporary = temporary_beside(self.path)
        self._handle = self.temporary.open("w", newline="", encoding="utf-8")
        self._writer = csv.writer(self._handle)
        self._writer.writerow(HEADER)
        self._handle.flush()
        self._flushed_at = 0.0
        self.rows = 0
        self._lead = None  # the session's velocity lead (hw/lead.py), recorded at the close

    def __call__(self, session: ArmSession, cycle: Cycle) -> None:
        """Append ``cycle``; flush once ``FLUSH_EVERY_S`` of run time passed since the last."""
        feedforward = getattr(session, "feedforward", None)
        if self.run_info is not None and feedforward is not None and "servo" not in self.run_info:
            # what the replay needs to simulate this arm: its supply, P, the feed-forward
            self.run_info["servo"] = {"gravity_ff": feedforward.enabled,
                                      "supply_v": feedforward.volts,
                                      "p": feedforward.settings["shoulder_lift"].p}
        if self._lead is None:
            self._lead = getattr(session, "velocity_lead", None)
        self._writer.writerow(cycle_row(cycle, session.trims))
        self.rows += 1
        if cycle.wall_s - self._flushed_at >= FLUSH_EVERY_S:
            self._handle.flush()
            self._flushed_at = cycle.wall_s

    def discard(self) -> None:
        """Close and delete the temporary file: the target is left as it was."""
        if not self._handle.closed:
            self._handle.close()
        self.temporary.unlink(missing_ok=True)
        forget_temporary(self.temporary)

    def close(self) -> Path:
        """Flush, close and rename over the target (idempotent); returns the target."""
        if not self._handle.closed:
            self._handle.flush()
            os.fsync(self._handle.fileno())
            self._handle.close()
            os.replace(self.temporary, self.path)
            forget_temporary(self.temporary)
            if self.run_info is not None:
                if self._lead is not None:
                    self.run_info["velocity_ff"] = self._lead.record()
                info = stamp(self.run_info, "pick_place_hw.py --log")
                write_text_atomic(sidecar_path(self.path), json.dumps(info, indent=1))
        return self.path


def write_log_csv(cycles: Iterable[Cycle], path: str | Path, trims: Trims | None = None) -> Path:
    """Write ``cycles`` (run with ``trims``) as a CSV at once (complete, or not at all)."""
    with atomic_output(path) as temporary, temporary.open("w", newline="",
                                                          encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(HEADER)
        writer.writerows(cycle_row(c, trims) for c in cycles)
    return Path(path)


def plot_log(cycles: list[Cycle], path: str | Path,
             title: str = "SO-101: commanded vs measured") -> Path:
    """PNG with one panel per joint: commanded and measured against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [c.t_s for c in cycles]
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    measured = [c for c in cycles if c.measured]
    for ax, joint in zip(axes.flat, JOINTS, strict=True):
        ax.plot(t, [c.command[joint] for c in cycles], label="commanded", lw=1.5)
        ax.plot([c.t_s for c in measured], [c.measured[joint] for c in measured],
                label="measured", lw=1.0, ls="--")
        worst = max((abs(c.command[joint] - c.measured[joint]) for c in measured), default=0.0)
        ax.set_title(f"{joint}  (max |commanded - measured| = {worst:.2f} {unit(joint)})",
                     fontsize=10)
        ax.set_ylabel("[%]" if joint == "gripper" else "[deg]")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes.flat[0].legend(loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    with atomic_output(path) as temporary:
        fig.savefig(temporary, dpi=100, format="png",
                    metadata=png_metadata("pick_place_hw.py --plot"))
    plt.close(fig)
    return Path(path)
