"""Draw docs/sag.png: where the FK puts the arm, and where the STS3215 at P = 16 holds it.

Side view (the arm's vertical plane) at the all-zero pose and at the course's pick
configuration: the commanded pose (the FK), the simulated arm at rest without the
gravity feed-forward, and with it. Each pose is the simulator's, settled for 3 s on
the default servo (the course's C018 on 12 V). Run: ``python scripts/plot_sag.py`` (about 5 s).
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from so101_kinematics.frames import JOINTS, TOOL_SITE  # noqa: E402
from so101_kinematics.markers import png_metadata  # noqa: E402
from so101_kinematics.planning.plans import STARTING_CONFIGURATION  # noqa: E402
from so101_kinematics.sim import actuation  # noqa: E402
from so101_kinematics.sim.scene import load_model, set_initial_pose  # noqa: E402

OUT = Path(__file__).resolve().parent.parent / "docs" / "sag.png"
BODIES = ("shoulder", "upper_arm", "lower_arm", "wrist", "gripper")
POSES = {"all-zero pose": dict.fromkeys(JOINTS, 0.0) | {"gripper": 50.0},
         "the course's pick": dict(STARTING_CONFIGURATION)}
SETTLE_S = 3.0  # [s]


def chain(m, d) -> np.ndarray:
    """The joints' and the object frame's positions [mm] in the arm's plane: (radial, up)."""
    points = [d.body(b).xpos.copy() for b in BODIES] + [d.site(TOOL_SITE).xpos.copy()]
    pan = math.atan2(points[-1][1], points[-1][0])
    axis = np.array([math.cos(pan), math.sin(pan), 0.0])
    return np.array([[p @ axis * 1000, p[2] * 1000] for p in points])


def pose_of(cfg, servo: dict | None) -> np.ndarray:
    """The chain of ``cfg`` commanded (``servo`` None: the FK) or settled on that servo."""
    m = load_model()
    d = mujoco.MjData(m)
    if servo is not None:
        actuation.use_servo(m, **servo)
    set_initial_pose(d, cfg)
    if servo is not None:
        actuation.step(m, d, round(SETTLE_S / m.opt.timestep))
    mujoco.mj_kinematics(m, d)
    return chain(m, d)


def main() -> None:
    """Write the figure."""
    fig, axes = plt.subplots(1, len(POSES), figsize=(10, 4.2))
    for ax, (title, cfg) in zip(axes, POSES.items(), strict=True):
        target = pose_of(cfg, None)
        sagged = pose_of(cfg, {"feedforward": False})
        fixed = pose_of(cfg, {"feedforward": True})
        for points, style, label in ((target, "k--", "FK (commanded)"),
                                     (sagged, "r-", "STS3215 C018, P = 16, 12 V"),
                                     (fixed, "g-", "... with gravity feed-forward")):
            ax.plot(points[:, 0], points[:, 1], style, marker="o", markersize=3, label=label)
        miss = np.linalg.norm(sagged[-1] - target[-1])
        left = np.linalg.norm(fixed[-1] - target[-1])
        ax.set_title(f"{title}\nobject frame {miss:.0f} mm off; {left:.1f} mm with the "
                     "feed-forward", fontsize=10)
        ax.set_xlabel("along the arm [mm]")
        ax.set_ylabel("height [mm]")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT, dpi=110, metadata=png_metadata("scripts/plot_sag.py"))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
