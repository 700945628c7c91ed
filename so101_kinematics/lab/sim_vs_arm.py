"""Simulator versus arm: a hardware run's log replayed in MuJoCo, for the write-up.

:func:`compare_run` reads a hardware log (``pick_place_hw.py --log``: the CSV
and its ``.run.json`` sidecar, see ``hw/log.py``), starts the simulated arm
at the run's measured starting pose and sends it the goals the servos got
(the plan as it ran: speed caps, pauses and a ``--velocity-ff`` lead included)
at the times they got them (the log's ``wall_s``, late cycles included),
and compares, per joint, the commanded, the measured and the simulated
angles. It also puts the cube where the measured angles put the object frame
during the pick and the place (FK of the measured pose at the end of those
steps) against where the plan puts it. :func:`draw_report` draws it all.
The trims the run applied (``--trims``, the log's ``trim_*`` columns) are
reported: the commanded and measured angles are the model's, the servos got
the commands plus the trims.

It reads any log the hardware script can write: a run stopped by Ctrl-C or
an abort before the pick or the place (that position is reported as not
reached), a partial log (a last row cut short, cycles whose read failed, a
log without its sidecar: the replay then starts at the first measured pose),
and a measured start outside the model's limits (as the arm may rest just
past one after a release: the replay starts at the nearest pose inside, with
a warning, as the hardware run itself does; its goals back to that start are
sent at the limit, with a note).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from so101_kinematics.errors import InputError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.hw.log import sidecar_path
from so101_kinematics.lab.log_ending import run_ending, stop_index
from so101_kinematics.lab.sag import describe_servo, logged_supply
from so101_kinematics.markers import png_metadata
from so101_kinematics.outputs import atomic_output
from so101_kinematics.planning.motion import Plan, Step
from so101_kinematics.planning.plans import pick_and_place_steps
from so101_kinematics.servo import COUNTS_PER_TURN, TARGET_RATE_MAX

__all__ = ["Comparison", "LogError", "compare_run", "draw_report", "logged_plan", "read_log",
           "replay"]

SETTLE_WINDOW_S = 0.2  # the pick/place pose: mean measured pose over the step's last [s]
MAX_SPEED_DEG_S = TARGET_RATE_MAX * 360.0 / COUNTS_PER_TURN  # [deg/s] the STS3215's fastest
MISREAD_MARGIN_DEG = 1.0  # [deg] beyond twice that speed's travel: no servo moved so (see below)
COLUMNS = ("t_s", "step", *(f"{kind}_{j}" for kind in ("cmd", "meas") for j in JOINTS))
"""The columns a replay needs (``hw/log.py``'s HEADER has them all)."""


class LogError(InputError):
    """A log that cannot be compared (missing, unreadable, or without its sidecar)."""


@dataclass
class Comparison:
    """The figures of :func:`compare_run` (the JSON report is :meth:`as_json`)."""

    t: np.ndarray
    commanded: dict[str, np.ndarray]
    measured: dict[str, np.ndarray]
    simulated: dict[str, np.ndarray]
    max_tracking_error_deg: dict[str, float]
    sim_vs_arm_rms_deg: dict[str, float]
    positions_mm: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    pick_position_error_mm: float = math.nan
    place_position_error_mm: float = math.nan
    trims_deg: dict[str, float] = field(default_factory=lambda: dict.fromkeys(JOINTS, 0.0))
    notes: list[str] = field(default_factory=list)  # what the log lacked, and what was done
    servo: str = ""  # the arm's servos as the log records them (hw/log.py), replayed so
    sag_deg: dict[str, dict[str, float]] = field(default_factory=dict)  # role -> joint -> [deg]
    sag_table_n: dict[str, float] = field(default_factory=dict)  # role -> the table's load [N]
    aborted: str | None = None  # how an aborted run ended (lab/log_ending.py); None: complete
    stopped_at: int | None = None  # the row of its stop: the figures end before it
    read_s: np.ndarray | None = None  # [s] when each cycle read the arm (the log's wall_s)

    def as_json(self) -> dict:
        """The report's numbers (gripper values are in [%], the rest in the keys' units).

        A position the run did not reach (stopped before its step) is null.
        """
        def number(value: float) -> float | None:
            return None if math.isnan(value) else value

        return {"max_tracking_error_deg": self.max_tracking_error_deg,
                "sim_vs_arm_rms_deg": self.sim_vs_arm_rms_deg,
                "servo": self.servo, "predicted_sag_deg": self.sag_deg,
                "sag_table_force_n": self.sag_table_n, "aborted": self.aborted,
                "pick_position_error_mm": number(self.pick_position_error_mm),
                "place_position_error_mm": number(self.place_position_error_mm),
                "positions_mm": self.positions_mm, "trims_deg": self.trims_deg,
                "notes": self.notes}

    def summary(self) -> str:
        """A few lines for the terminal."""
        lines = [f"warning: {note}" for note in self.notes]
        if self.aborted:
            lines.append(f"aborted: {self.aborted}")
        lines += [f"trims (added to every goal sent to the arm): {self.describe_trims()}",
                  "joint           max |cmd - arm|   rms |sim - arm|"]
        lines += [f"  {j:<14}{self.max_tracking_error_deg[j]:>10.2f}"
                  f"{self.sim_vs_arm_rms_deg[j]:>17.2f}" for j in JOINTS]
        for role in ("pick", "place"):
            p = self.positions_mm.get(role)
            if p is None:
                lines.append(f"{role}: not reached in this log (the run ended before its step)")
                continue
            lines.append(f"{role}: planned x, y, z = {_xyz(p['planned'])} mm, from the arm's "
                         f"angles {_xyz(p['measured'])} mm: "
                         f"{getattr(self, role + '_position_error_mm'):.1f} mm apart")
        if self.servo:
            lines.append(f"servo: {self.servo}")
        for role, sag in self.sag_deg.items():
            joints = ", ".join(f"{j} {v:.1f}" for j, v in sag.items() if abs(v) >= 0.05)
            table = self.sag_table_n.get(role, 0.0)
            lines.append(f"  without the feed-forward it sags at the {role}: {joints or 'none'} "
                         "deg (the simulator" + (f", the table carrying the arm with "
                                                 f"{table:.1f} N)" if table else ")"))
        return "\n".join(lines)

    def describe_trims(self) -> str:
        """The run's non-zero trims in one line, or "none"."""
        return ", ".join(f"{j} {v:+.1f} {'%' if j == 'gripper' else 'deg'}"
                         for j, v in self.trims_deg.items() if v) or "none"


def _xyz(v) -> str:
    return ", ".join(f"{c:.1f}" for c in v)


def read_log(path: str | Path) -> tuple[list[dict[str, str]], dict]:
    """The CSV rows and the sidecar of a hardware log (``{}`` when the sidecar is missing)."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            reader = csv.DictReader(handle)
            rows = list(reader)
            missing = [c for c in COLUMNS if c not in (reader.fieldnames or ())]
    except (OSError, ValueError, csv.Error) as error:
        raise LogError(f"so101 compare {path}: cannot read the log ({error}). Fix: give a CSV "
                       "written by pick_place_hw.py --log.") from None
    if missing:
        raise LogError(f"so101 compare {path}: not a log of pick_place_hw.py (no column "
                       f"{missing[0]!r}). Fix: give a CSV written by pick_place_hw.py --log.")
    try:
        info = json.loads(sidecar_path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        info = {}
    return rows, info if isinstance(info, dict) else {}


def usable_rows(rows: list[dict[str, str]]) -> tuple[list[dict[str, float | str]], int]:
    """The cycles a replay can use (parsed), and how many were cut short or unreadable.

    A cycle whose read failed (empty measured columns) is left out silently, as
    the run itself logged it; a row cut short (the last one after a kill) or
    with a non-number is counted.
    """
    usable, broken = [], 0
    for row in rows:
        if row.get(f"meas_{JOINTS[0]}") == "" and row.get("t_s"):
            continue
        try:
            parsed = {c: float(row[c]) for c in COLUMNS if c != "step"}
        except (TypeError, ValueError, KeyError):
            broken += 1
            continue
        try:  # the cycle's actual start: the command went out and the arm was read then
            parsed["wall_s"] = float(row.get("wall_s") or parsed["t_s"])
        except ValueError:
            parsed["wall_s"] = parsed["t_s"]
        for j in JOINTS:  # the velocity lead (--velocity-ff): the goal written was cmd + lead
            try:
                parsed[f"lead_{j}"] = float(row.get(f"lead_{j}") or 0.0)
            except ValueError:
                parsed[f"lead_{j}"] = 0.0
        if all(math.isfinite(v) for v in parsed.values()):
            usable.append({**parsed, "step": row["step"]})
        else:
            broken += 1
    return usable, broken


def misreads(rows: list[dict]) -> list[int]:
    """The rows whose arm joints jumped further than any servo moves: misread replies.

    A row is one when its measured arm joints jumped from both neighbours (or the only one,
    at an end) by more than twice the servo's top speed allows (seen on the virtual arm
    under load: every joint about -2900 deg for one cycle).
    """
    if len(rows) < 2:
        return []
    t = np.array([r["wall_s"] for r in rows])
    q = np.array([[r[f"meas_{j}"] for j in ARM_JOINTS] for r in rows])
    jump = np.abs(np.diff(q, axis=0)).max(axis=1)
    impossible = jump > 2.0 * MAX_SPEED_DEG_S * np.abs(np.diff(t)) + MISREAD_MARGIN_DEG
    before = np.concatenate([[impossible[0]], impossible])
    after = np.concatenate([impossible, [impossible[-1]]])
    return np.flatnonzero(before & after).tolist()


def start_inside_limits(start: dict[str, float], notes: list[str]) -> dict[str, float]:
    """``start`` moved into the model's limits; each move is a note (and a warning)."""
    from so101_kinematics.sim.scene import joint_limits, load_model

    limits = joint_limits(load_model())
    inside = {}
    for joint in JOINTS:
        low, high = limits[joint]
        inside[joint] = min(high, max(low, float(start[joint])))
        if inside[joint] != start[joint]:
            unit = "%" if joint == "gripper" else "deg"
            notes.append(f"the measured start has {joint} = {start[joint]:g} {unit}, "
                         f"{abs(start[joint] - inside[joint]):.2g} {unit} outside the model's "
                         f"[{low:g}, {high:g}] {unit}: the replay starts at {inside[joint]:g}")
    return inside


def commands_inside_limits(commands: dict[str, np.ndarray],
                           notes: list[str]) -> dict[str, np.ndarray]:
    """``commands`` clipped to the model's limits; a joint clipped is a note (by how much).

    The hardware run returns to its measured start, which may lie just past a limit (the
    released arm slumps there): the replay sends that goal at the limit instead.
    """
    from so101_kinematics.sim.scene import joint_limits, load_model

    limits = joint_limits(load_model())
    inside = {}
    for joint, values in commands.items():
        low, high = limits[joint]
        inside[joint] = np.clip(values, low, high)
        beyond = float(np.max(np.abs(values - inside[joint]), initial=0.0))
        if beyond > 0.0:
            unit = "%" if joint == "gripper" else "deg"
            notes.append(f"goals past the model's limits (from and back to a slumped start): "
                         f"{joint} by up to {beyond:.2g} {unit} beyond [{low:g}, {high:g}] "
                         f"{unit}: replayed at the limit")
    return inside


def logged_plan(record: dict) -> Plan:
    """The plan a log's header recorded (``hw/log.py``), as it ran."""
    return Plan([Step(s["name"], s["configuration"], s["duration"], s["hold"])
                 for s in record["steps"]], record.get("return_to_start", True),
                record.get("return_duration", 2.0))


def replay(t: np.ndarray, commands: dict[str, np.ndarray], start: dict[str, float],
           servo: dict | None = None):
    """Simulated joints at each time of ``t``, the commands sent as the arm got them.

    ``servo``: the log's record of the arm's servos (``gravity_ff``, ``supply_v``, ``p``;
    ``hw/log.py``); a log without it comes from a run before the feed-forward existed.
    """
    import mujoco

    from so101_kinematics.sim import actuation
    from so101_kinematics.sim.scene import (
        get_configuration,
        load_model,
        send_position_command,
        set_initial_pose,
    )

    m = load_model()
    servo = servo or {}
    actuation.use_servo(m, volts=logged_supply(servo),
                        p=int(servo.get("p", 16)), feedforward=bool(servo.get("gravity_ff")))
    d = mujoco.MjData(m)
    set_initial_pose(d, start)
    d.time = float(t[0])
    out = {j: np.empty(len(t)) for j in JOINTS}
    for k, now in enumerate(t):
        steps = round((now - d.time) / m.opt.timestep)
        if steps > 0:
            actuation.step(m, d, steps)
        for j, value in get_configuration(m, d).items():
            out[j][k] = value
        send_position_command(d, {j: float(commands[j][k]) for j in JOINTS})
    return out


def compare_run(path: str | Path) -> Comparison:
    """Replay the hardware log ``path`` in the simulator and compare (see the module)."""
    raw, info = read_log(path)
    rows, broken = usable_rows(raw)
    if not rows:
        raise LogError(f"so101 compare {path}: the log has no cycle with a measured pose (the run "
                       "was refused before it moved?). Fix: give the log of a run that moved.")
    notes = []
    if broken:
        notes.append(f"{broken} row(s) cut short or unreadable were left out (a partial log)")
    wrong = misreads(rows)
    if wrong:
        notes.append(f"{len(wrong)} reading(s) that no servo could move to in time were left out "
                     f"(misread replies), the first at t = {rows[wrong[0]]['t_s']:.2f} s")
        rows = [r for k, r in enumerate(rows) if k not in frozenset(wrong)]
    if not isinstance(info.get("start_pose"), dict):
        notes.append(f"no sidecar {sidecar_path(path).name} with the starting pose: the replay "
                     "starts at the first measured pose, on the default servo (the "
                     "feed-forward on, as pick_place_hw.py runs by default)")
        info["start_pose"] = {j: rows[0][f"meas_{j}"] for j in JOINTS}
        info.setdefault("servo", {"gravity_ff": True})
    start = start_inside_limits(info["start_pose"], notes)
    t = np.array([r["t_s"] for r in rows])
    read_s = np.array([r["wall_s"] for r in rows])
    commanded = {j: np.array([r[f"cmd_{j}"] for r in rows]) for j in JOINTS}
    measured = {j: np.array([r[f"meas_{j}"] for r in rows]) for j in JOINTS}
    # The simulator gets what the servos got, when they got it: the goal as written (the
    # plan plus the velocity lead of a --velocity-ff run) at the cycle's actual start.
    written = {j: commanded[j] + np.array([r[f"lead_{j}"] for r in rows]) for j in JOINTS}
    led = any(np.any(written[j] != commanded[j]) for j in JOINTS)
    simulated = replay(read_s, commands_inside_limits(written, notes), start, info.get("servo"))
    result = Comparison(
        t, commanded, measured, simulated,
        {j: float(np.max(np.abs(commanded[j] - measured[j]))) for j in JOINTS},
        {j: float(np.sqrt(np.mean((simulated[j] - measured[j]) ** 2))) for j in JOINTS})
    result.notes = notes
    try:
        result.trims_deg = {j: float(raw[0].get(f"trim_{j}") or 0.0) for j in JOINTS}
    except (TypeError, ValueError):
        result.notes.append("the trims of the first row are unreadable: taken as none")
    result.read_s = read_s
    steps = np.array([r["step"] for r in rows])
    try:
        roles = pick_and_place_steps(logged_plan(info["plan"]))
    except Exception:  # noqa: BLE001 - no sidecar, or a plan without its pick and place
        roles = ()
        result.notes.append("no plan in the sidecar with a pick and a place: their positions "
                            "are not compared")
    for role, step in zip(("pick", "place"), roles, strict=False):
        planned = _position_mm(step.configuration)
        inside = np.flatnonzero(steps == step.name)
        if inside.size == 0:
            continue
        last = inside[t[inside] >= t[inside[-1]] - SETTLE_WINDOW_S]
        pose = {j: float(np.mean(measured[j][last])) for j in ARM_JOINTS}
        seen = _position_mm(pose)
        result.positions_mm[role] = {"planned": planned.tolist(), "measured": seen.tolist()}
        setattr(result, f"{role}_position_error_mm", float(np.linalg.norm(seen - planned)))
    describe_servo(result, info.get("servo"), roles)
    names = [str(r.get("step", "")) for r in rows]
    result.aborted = run_ending(names, [r["t_s"] for r in rows], info)
    result.stopped_at = stop_index(names) if result.aborted else None
    if led:
        result.servo += "; goals led by the velocity feed-forward (replayed as written)"
    return result


def _position_mm(cfg) -> np.ndarray:
    return forward_kinematics({j: cfg[j] for j in ARM_JOINTS})[0] * 1000.0


def draw_report(result: Comparison, path: str | Path, title: str = "") -> Path:
    """PNG: per joint, commanded / measured / simulated over time and the differences."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 3, figsize=(15, 11), sharex=True,
                             gridspec_kw={"height_ratios": [2, 1, 2, 1]})
    for k, joint in enumerate(JOINTS):
        top, bottom = axes[2 * (k // 3), k % 3], axes[2 * (k // 3) + 1, k % 3]
        unit = "%" if joint == "gripper" else "deg"
        top.plot(result.t, result.commanded[joint], lw=1.4, label="commanded")
        top.plot(result.t, result.measured[joint], lw=1.0, ls="--", label="measured (arm)")
        top.plot(result.t, result.simulated[joint], lw=1.0, ls=":", label="simulated")
        top.set_title(f"{joint} [{unit}]", fontsize=10)
        bottom.plot(result.t, result.measured[joint] - result.commanded[joint], lw=0.9,
                    label="arm - commanded")
        bottom.plot(result.t, result.measured[joint] - result.simulated[joint], lw=0.9,
                    label=f"arm - sim (rms {result.sim_vs_arm_rms_deg[joint]:.2f})")
        bottom.legend(fontsize=7, loc="upper right")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    text = []
    for role in ("pick", "place"):
        if role in result.positions_mm:
            p = result.positions_mm[role]
            text.append(f"{role}: planned ({_xyz(p['planned'])}) mm, from the measured angles "
                        f"({_xyz(p['measured'])}) mm, "
                        f"{getattr(result, role + '_position_error_mm'):.1f} mm apart")
    text.append(f"trims (added to every goal): {result.describe_trims()}")
    if result.aborted:
        text.insert(0, f"ABORTED: {result.aborted}")
    fig.suptitle((title + "\n" if title else "") + "\n".join(text), fontsize=10)
    fig.tight_layout()
    with atomic_output(path) as temporary:
        fig.savefig(temporary, dpi=90, format="png",
                    metadata=png_metadata("so101 compare --report"))
    plt.close(fig)
    return Path(path)
