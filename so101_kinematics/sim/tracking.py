"""How well the simulated arm follows a move, and how smoothly: assignment 9's comparison.

:class:`StepLog` stands where a viewer goes in ``move_to_pose`` / ``hold_position``
and records every physics step (commanded and measured joints, the measured
velocity and acceleration), passing the frames on to a real viewer if it wraps one.
:func:`run_week9` runs the course's week-9 test (the all-zero pose, the two block
targets, back; 2 s moves, 1 s holds) with one profile; :func:`metrics` turns a log
into the figures of ``test_trajectory_mujoco.py --json``; :func:`log_frame` into the
course's logging DataFrame (week 8: ``time``, ``target_<joint>``, ``actual_<joint>``).
The log also records where the arm pressed on the table (``sim/table_contact.py``):
:func:`table_contact` says how hard, where and when, as a jaw dragged over the table
makes the figures the impact's, not the profile's.
"""

from __future__ import annotations

import math

import numpy as np

from so101_kinematics.frames import JOINTS
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.markers import png_metadata
from so101_kinematics.planning import motion_metrics, trajectory_log
from so101_kinematics.planning.motion_metrics import METRIC_KEYS
from so101_kinematics.sim import stepping
from so101_kinematics.sim.scene import gripper_from_radians, joint_table, set_initial_pose
from so101_kinematics.sim.table_contact import arm_table_contacts

__all__ = [
    "HOLD_S", "MOVE_S", "SETTLE_S", "StepLog", "TARGETS", "log_frame", "metrics",
    "plot_tracking", "run_week9", "table_contact",
]

BLOCK_SIZE = 0.0285  # [m], the course's week-9 block (1.125 in)
TARGETS = ((0.25, 0.1, BLOCK_SIZE / 2), (0.25, -0.1, BLOCK_SIZE / 2))  # [m], the page's
MOVE_S = 2.0  # [s] per move, the page's
HOLD_S = 1.0  # [s] after each move, the page's
SETTLE_S = 1.0  # [s] held at the start before the log begins: the arm, placed at rest,
                # first sags onto its servos (not part of any move)
INITIAL = dict.fromkeys(JOINTS, 0.0)  # the page's all-zero start, gripper 0
ARM = JOINTS[:5]  # the figures are the arm's joints [deg]; the gripper is in [0, 100]


class StepLog:
    """A viewer stand-in that records each physics step (``sync_every_step``).

    Args:
        m: the model.
        d: the data.
        viewer: a viewer to pass frames on to (every ``VIEWER_SYNC_PERIOD``; every step to
            a video recorder, which asks for it with ``sync_every_step``), or None.
    """

    sync_every_step = True

    def __init__(self, m, d, viewer=None):
        self.m, self.d, self.viewer = m, d, viewer
        if viewer is not None:
            stepping._guard_passive_viewer(viewer)  # its exit waits for the render thread
        self.offscreen = viewer is None or getattr(viewer, "offscreen", False)
        self._every_step = getattr(viewer, "sync_every_step", False)  # a video recorder
        table = joint_table(m)
        self._acts = [act for _, _, act, *_ in table]
        self._qadr = [adr for _, adr, *_ in table]
        self._dofs = [int(m.joint(name).dofadr[0]) for name, *_ in table]
        self.rows: list[tuple] = []
        self.table: list[tuple] = []  # (time [s], TableContact) of each step the arm touched
        self.t0 = float(d.time)  # [s] the log's times count from here
        self._next_frame = -math.inf

    def is_running(self) -> bool:
        """False once a wrapped viewer's window is closed."""
        return self.viewer is None or self.viewer.is_running()

    def sync(self) -> None:
        """Record this step; pass the frame on to the wrapped viewer when one is due."""
        d = self.d
        self.rows.append((d.time, d.ctrl[self._acts].copy(), d.qpos[self._qadr].copy(),
                          d.qvel[self._dofs].copy(), d.qacc[self._dofs].copy()))
        touching = arm_table_contacts(self.m, d) if d.ncon else []
        if touching:
            self.table.append((d.time - self.t0, touching[0]))
        if self.viewer is not None and (self._every_step or d.time >= self._next_frame - 1e-9):
            self.viewer.sync()
            self._next_frame = d.time + stepping.VIEWER_SYNC_PERIOD

    def arrays(self) -> dict[str, np.ndarray]:
        """The log as arrays, one row per step.

        Returns:
            time [s] since the log began (n,); command, measured [deg, gripper 0-100]
            (n, 6); velocity [deg/s], acceleration [deg/s^2] (n, 6; the gripper in deg).
        """
        if not self.rows:
            empty = np.zeros((0, len(JOINTS)))
            return {"time": np.zeros(0), "command": empty, "measured": empty,
                    "velocity": empty, "acceleration": empty}
        time, ctrl, qpos, qvel, qacc = (np.array(column) for column in zip(*self.rows,
                                                                           strict=True))
        gripper = JOINTS.index("gripper")

        def user(angles):
            out = np.degrees(angles)
            out[:, gripper] = [gripper_from_radians(self.m, a) for a in angles[:, gripper]]
            return out

        return {"time": time - self.t0, "command": user(ctrl), "measured": user(qpos),
                "velocity": np.degrees(qvel), "acceleration": np.degrees(qacc)}


def week9_configurations() -> list[dict[str, float]]:
    """The page's sequence: the first block target, the second, back to all-zero ([deg])."""
    first, second = (get_inverse_kinematics(list(p)) for p in TARGETS)
    return [first, second, dict(INITIAL)]


def run_week9(m, d, viewer=None, profile: str = "cubic", velocity: bool | None = None,
              move_s: float = MOVE_S, hold_s: float = HOLD_S) -> StepLog:
    """The course's week-9 test with one profile, from the all-zero pose at rest; its log.

    The arm is placed at the all-zero pose and held ``SETTLE_S`` before the log
    begins, so the figures are the moves' (not the first sag onto the servos).

    Args:
        m: the model.
        d: the data (the arm is placed at the start).
        viewer: as for ``move_to_pose`` (None: headless).
        profile: a name in ``profiles.PROFILES``.
        velocity: feed the velocity forward (a velocity model; None: when it has one).
        move_s: [s] per move.
        hold_s: [s] held after each move.
    """
    set_initial_pose(d, INITIAL)
    stepping.hold_position(m, d, viewer, SETTLE_S, raise_if_closed=True)
    log = StepLog(m, d, viewer)
    for cfg in week9_configurations():
        stepping.move_to_pose(m, d, log, cfg, move_s, profile=profile, velocity=velocity,
                              raise_if_closed=True)
        stepping.hold_position(m, d, log, hold_s, raise_if_closed=True)
    return log


def metrics(log: StepLog) -> dict[str, float]:
    """Tracking and smoothness of the arm's joints over a log (:data:`METRIC_KEYS`).

    ``motion_metrics.metrics`` on the arm's joints, with the physics' own velocity and
    acceleration (the jerk: the acceleration's change per step).
    """
    a = log.arrays()
    arm = [JOINTS.index(j) for j in ARM]
    if len(a["time"]) < 2:
        return dict.fromkeys(METRIC_KEYS, 0.0)
    exact = motion_metrics.step_derivatives(a["time"], a["velocity"][:, arm],
                                            a["acceleration"][:, arm])
    return motion_metrics.metrics(a["time"], a["command"][:, arm], a["measured"][:, arm], exact)


def table_contact(log: StepLog, move_s: float = MOVE_S,
                  hold_s: float = HOLD_S) -> dict | None:
    """Where the arm pressed on the table in a :func:`run_week9` log (None: it never did).

    Returns:
        ``force_n`` (the largest normal force [N]), ``body``, ``geom`` and ``t_s`` (when
        it was largest, since the log began), ``where`` (that moment in the page's
        sequence), ``steps`` (how many physics steps touched).
    """
    if not log.table:
        return None
    t, contact = max(log.table, key=lambda entry: entry[1].force_n)
    k = min(int(t // (move_s + hold_s)), 2)
    target = ("the first block", "the second block", "the all-zero pose")[k]
    doing = "moving to" if t - k * (move_s + hold_s) < move_s else "holding at"
    return {"force_n": round(contact.force_n, 2), "body": contact.body,
            "geom": contact.geom, "t_s": round(t, 3), "where": f"{doing} {target}",
            "steps": len(log.table)}


def log_frame(log: StepLog):
    """The course's logging DataFrame (``trajectory_log.logging_frame``), a row per physics step.

    Raises:
        ImportError: one line naming the extra, when pandas is not installed.
    """
    a = log.arrays()
    rows = [dict(zip(JOINTS, row, strict=True)) for row in a["command"].tolist()]
    measured = [dict(zip(JOINTS, row, strict=True)) for row in a["measured"].tolist()]
    return trajectory_log.logging_frame(a["time"].tolist(), rows, measured)


def plot_tracking(logs: dict[str, StepLog], path, title: str = "") -> None:
    """Commanded (solid) vs measured (dashed) per arm joint, one panel per profile, to ``path``.

    Args:
        logs: profile name -> its log.
        path: the image file (the caller checked it; any format matplotlib writes).
        title: the figure's title.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(logs), 1, figsize=(10, 2.8 * len(logs)), sharex=True,
                             squeeze=False)
    for ax, (name, log) in zip(axes[:, 0], logs.items(), strict=True):
        a = log.arrays()
        for k, joint in enumerate(ARM):
            i = JOINTS.index(joint)
            colour = f"C{k}"
            ax.plot(a["time"], a["command"][:, i], color=colour, label=f"target {joint}")
            ax.plot(a["time"], a["measured"][:, i], color=colour, linestyle="--",
                    label=f"actual {joint}")
        rms = metrics(log)["tracking_rms_deg"]
        ax.set_title(f"{name}: tracking error RMS {rms:.2f} deg", fontsize=10)
        ax.set_ylabel("joint [deg]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata=png_metadata("test_trajectory_mujoco.py --plot"))
    plt.close(fig)
