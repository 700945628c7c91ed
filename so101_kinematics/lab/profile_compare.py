"""Profiles compared from real runs: tracking and smoothness, the arm beside the simulator.

For the write-up of assignment 9 ("tracking performance, smoothness of motion", cubic
against linear, in simulation and on hardware): a student runs the arm once per
profile with a log (``pick_place_hw.py --profile cubic --log cubic.csv``) and gives the
logs to ``so101 compare``. Each log is replayed in the simulator
(``lab/sim_vs_arm.py``: the run's own commands, which are its profile's samples, from its
measured start, on its servo settings), and :func:`compare_profiles` puts, per log,
the arm's figures and the replay's side by side (``motion_metrics.metrics`` on the
arm's five joints, the gripper left out: it is in [%]).

The simulated angles are rounded to whole encoder counts before the figures are
taken, as the arm's are read, so both rows go through the same quantiser and the same
derivative filter (``motion_metrics``): what differs between them is the motion.

What students hand in: a log whose sidecar has no profile (or no sidecar) is taken as
``DEFAULT_PROFILE``, pick_place_hw.py's default since its first version, and says so;
two logs of one profile are listed each on its own row, not averaged (their spread is
the run-to-run variation, which the write-up can quote); logs of different plans are
compared with the table saying so (plan A, B, ...); the same file given twice counts once.
An aborted run (``lab/log_ending.py``) is marked aborted in the table and the JSON, its
figures end at its stop (the slow return left out), and it is never counted in a
profile's run-to-run variation.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.lab.sim_vs_arm import Comparison, compare_run, read_log
from so101_kinematics.markers import png_metadata
from so101_kinematics.outputs import atomic_output
from so101_kinematics.planning import motion_metrics
from so101_kinematics.planning.profiles import PROFILES

__all__ = ["DEFAULT_PROFILE", "compare_profiles", "draw_profiles"]

DEFAULT_PROFILE = "minimum_jerk"  # pick_place_hw.py --profile's default, unchanged since 17420a9
UNKNOWN_PLAN = "?"


@dataclass
class ProfileRun:
    """One log's figures: the arm's and its replay's (:data:`motion_metrics.METRIC_KEYS`)."""

    log: Path
    profile: str
    profile_recorded: bool  # False: the log did not say; DEFAULT_PROFILE assumed
    plan: str  # "A", "B", ... (same letter, same plan), or UNKNOWN_PLAN
    duration_s: float  # [s] the logged run, first to last cycle (the speed cap stretches it)
    arm: dict[str, float]
    sim: dict[str, float]
    comparison: Comparison

    def as_json(self) -> dict:
        """The run's row (the replay's full arrays are left out)."""
        return {"log": str(self.log), "profile_recorded": self.profile_recorded,
                "plan": self.plan, "duration_s": round(self.duration_s, 3),
                "aborted": self.comparison.aborted, "arm": self.arm, "sim": self.sim}


@dataclass
class ProfileComparison:
    """The logs' figures (:func:`compare_profiles`); :meth:`table` and :meth:`as_json`."""

    runs: list[ProfileRun]
    notes: list[str] = field(default_factory=list)

    @property
    def plans_differ(self) -> bool:
        """True when two logs ran different plans (or a log's plan is unknown)."""
        return len({run.plan for run in self.runs}) > 1

    def as_json(self) -> dict:
        """``profiles``: name -> a list of runs (one per log, in the order given)."""
        profiles: dict[str, list[dict]] = {}
        for run in self.runs:
            profiles.setdefault(run.profile, []).append(run.as_json())
        return {"profiles": profiles, "plans_differ": self.plans_differ,
                "derivatives": describe_derivatives(), "notes": self.notes}

    def table(self) -> str:
        """The comparison as text: a row for the arm and one for the simulator, per log."""
        width = max(len(run.log.name) for run in self.runs)
        lines = [f"note: {note}" for note in self.notes]
        lines.append("Profiles, arm joints (tracking: measured - commanded over the whole run; "
                     "peaks of the measured motion):")
        lines.append(f"{'log':<{width}}  {'profile':<13}{'plan':<5}{'run [s]':>8}  "
                     f"{'':<4}{'RMS / max [deg]':>17}{'speed':>9}{'accel':>9}{'jerk':>9}")
        for run in self.runs:
            for source in ("arm", "sim"):
                f = getattr(run, source)
                head = (f"{run.log.name:<{width}}  {run.profile:<13}{run.plan:<5}"
                        f"{run.duration_s:>8.1f}" if source == "arm" else " " * (width + 28))
                mark = "  ABORTED" if run.comparison.aborted and source == "arm" else ""
                lines.append(f"{head}  {source:<4}{f['tracking_rms_deg']:>9.2f} / "
                             f"{f['tracking_max_deg']:<5.2f}{f['peak_velocity_deg_s']:>9.0f}"
                             f"{f['peak_acceleration_deg_s2']:>9.0f}"
                             f"{f['peak_jerk_deg_s3']:>9.0f}{mark}")
        lines.append("(peaks: speed [deg/s], accel [deg/s^2], jerk [deg/s^3]; "
                     f"{describe_derivatives()})")
        if self.plans_differ:
            lines.append("the plans differ (column plan): their figures are not like for like")
        return "\n".join(lines)


def describe_derivatives() -> str:
    """How the peaks were taken, in one line."""
    return (f"derivatives of a cubic fitted over {motion_metrics.DERIVATIVE_WINDOW_S:g} s "
            f"windows, as the encoder counts ({motion_metrics.ENCODER_COUNT_DEG:.3f} deg) make "
            "plain differences noise; the simulated angles rounded to counts like the arm's")


def run_figures(comparison: Comparison) -> tuple[dict[str, float], dict[str, float]]:
    """The arm's and the replay's figures over a compared log (the arm's joints).

    Both are differentiated on the times the arm was read (the log's ``wall_s``: a late
    cycle read it late), which is when the replay sampled the simulator too. An aborted
    run's figures end before its stop (the stop and the slow return are not the profile).
    """
    n = comparison.stopped_at or len(comparison.t)
    commanded = np.column_stack([comparison.commanded[j][:n] for j in ARM_JOINTS])
    measured = np.column_stack([comparison.measured[j][:n] for j in ARM_JOINTS])
    simulated = motion_metrics.to_encoder_counts(
        np.column_stack([comparison.simulated[j][:n] for j in ARM_JOINTS]))
    read = (comparison.t if comparison.read_s is None else comparison.read_s)[:n]
    return (motion_metrics.metrics(read, commanded, measured),
            motion_metrics.metrics(read, commanded, simulated))


def _profile(info: dict, name: str, notes: list[str]) -> tuple[str, bool]:
    profile = info.get("profile")
    if not isinstance(profile, str) or not profile:
        notes.append(f"{name}: no profile recorded (a log without its sidecar, or an older "
                     f"one): assumed {DEFAULT_PROFILE}, pick_place_hw.py's default")
        return DEFAULT_PROFILE, False
    if profile not in PROFILES:
        notes.append(f"{name}: profile {profile!r} is not one of {', '.join(PROFILES)}: "
                     "shown as recorded")
    return profile, True


def compare_profiles(paths: list[str | Path]) -> ProfileComparison:
    """Replay each log and take the arm's and the simulator's figures (see the module).

    Every log is read before any is replayed, so a missing or unreadable one is
    refused at once (``LogError``, one line with a Fix).
    """
    unique: list[Path] = []
    notes: list[str] = []
    for path in map(Path, paths):
        if any(path.resolve() == seen.resolve() for seen in unique):
            notes.append(f"{path} was given more than once: compared once")
        else:
            unique.append(path)
    sidecars = [read_log(path)[1] for path in unique]
    plans: list[str] = []  # canonical JSON of each distinct plan, its index -> letter
    runs = []
    for path, info in zip(unique, sidecars, strict=True):
        profile, recorded = _profile(info, path.name, notes)
        if isinstance(info.get("plan"), dict):
            key = json.dumps(info["plan"], sort_keys=True)
            if key not in plans:
                plans.append(key)
            plan = chr(ord("A") + plans.index(key))
        else:
            plan = UNKNOWN_PLAN
            notes.append(f"{path.name}: no plan in its sidecar: whether it ran the same plan "
                         "as the others is unknown (plan ?)")
        comparison = compare_run(path)
        notes.extend(f"{path.name}: {note}" for note in comparison.notes)
        arm, sim = run_figures(comparison)
        runs.append(ProfileRun(path, profile, recorded, plan,
                               float(comparison.t[-1] - comparison.t[0]), arm, sim, comparison))
    for run in runs:
        if run.comparison.aborted:
            until = ("" if run.comparison.stopped_at is None else
                     f"; its figures end at the stop, t = "
                     f"{run.comparison.t[run.comparison.stopped_at]:.2f} s")
            notes.append(f"{run.log.name}: ABORTED ({run.comparison.aborted}): not a complete "
                         f"run, never counted in the run-to-run variation{until}")
    for profile in dict.fromkeys(run.profile for run in runs):
        same = [run.log.name for run in runs
                if run.profile == profile and not run.comparison.aborted]
        if len(same) > 1:
            notes.append(f"{profile}: {len(same)} logs ({', '.join(same)}), each on its own "
                         "row, not averaged (their spread is the run-to-run variation)")
    return ProfileComparison(runs, notes)


def draw_profiles(result: ProfileComparison, path: str | Path, title: str = "") -> Path:
    """PNG: per log, the tracking error and the measured acceleration over time, arm and sim.

    Each curve is the largest magnitude over the arm's joints at each sample [deg],
    [deg/s^2] (the acceleration as the table takes it).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(14, 5))
    for k, run in enumerate(result.runs):
        c = run.comparison
        commanded = np.column_stack([c.commanded[j] for j in ARM_JOINTS])
        label = f"{run.log.name} ({run.profile}{', ABORTED' if c.aborted else ''})"
        read = c.t if c.read_s is None else c.read_s
        for source, values, times, style in (
                ("arm", np.column_stack([c.measured[j] for j in ARM_JOINTS]), read, "-"),
                ("sim", motion_metrics.to_encoder_counts(
                    np.column_stack([c.simulated[j] for j in ARM_JOINTS])), c.t, ":")):
            t = c.t - c.t[0]
            _, acceleration, _ = motion_metrics.fitted_derivatives(times, values)
            axes[0].plot(t, np.abs(values - commanded).max(axis=1), style, color=f"C{k}",
                         lw=1.0, label=f"{label} {source}")
            axes[1].plot(t, np.abs(acceleration).max(axis=1), style, color=f"C{k}", lw=1.0,
                         label=f"{label} {source}")
    axes[0].set_title("tracking error, largest over the arm's joints [deg]", fontsize=10)
    axes[1].set_title("measured acceleration, largest over the arm's joints [deg/s^2]",
                      fontsize=10)
    for ax in axes:
        ax.set_xlabel("time since the log's first cycle [s]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle((title + "\n" if title else "") + describe_derivatives(), fontsize=9)
    fig.tight_layout()
    with atomic_output(path) as temporary:
        fig.savefig(temporary, dpi=90, format="png",
                    metadata=png_metadata("profile comparison --report"))
    plt.close(fig)
    return Path(path)
