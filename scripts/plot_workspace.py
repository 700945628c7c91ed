"""Plot where on the table the SO-101 can pick a cube with a top-down grasp (docs/workspace.png).

It also outlines the top-down reach at the course's four stacking heights (the
centres of its 1st to 4th block, assignment 8), on the table (solid) and with
the lab's 15 mm mount (dashed: the same heights above the table, 15 mm lower in
the base frame).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))

import so101_inverse_kinematics as ik  # noqa: E402
from so101_forward_kinematics import get_forward_kinematics  # noqa: E402
from so101_kinematics.constants import CUBE_HALF_SIZE  # noqa: E402
from so101_kinematics.errors import OutputPathError  # noqa: E402
from so101_kinematics.ik.geometry import PAN_AXIS_POINT  # noqa: E402
from so101_kinematics.ik.solver import sample_top_down_targets  # noqa: E402
from so101_kinematics.markers import png_metadata  # noqa: E402
from so101_kinematics.outputs import PNG, add_overwrite_argument, check_output_path  # noqa: E402
from so101_kinematics.planning.plans import FINAL_CONFIGURATION, STARTING_CONFIGURATION  # noqa: E402
from so101_kinematics.planning.stacking import (  # noqa: E402
    COURSE_BLOCK_HEIGHTS,
    LAB_BASE_HEIGHT,
    min_target_height,
)

OUTPUT = REPO / "docs" / "workspace.png"
HEIGHT = CUBE_HALF_SIZE   # cube centre above the table [m]
GRID_STEP = 0.005            # spacing of the IK grid [m]
X_RANGE = (-0.12, 0.38)      # table area plotted [m]
Y_RANGE = (-0.33, 0.33)      # [m]
FK_DRAWS = 400_000           # random configurations drawn for the FK samples
SLAB = 0.002                 # FK samples kept within this of HEIGHT [m]
SEED = 0
LEVEL_STEP = 0.01            # spacing of the IK grids of the stacking heights [m]
LEVEL_COLORS = ("darkorange", "tab:cyan", "magenta", "tab:brown")

log = logging.getLogger("plot_workspace")


def reachable_grid(step: float, yaw_deg: float | None, height: float = HEIGHT,
                   base_height: float = 0.0):
    """IK over a grid at ``height`` [m] (a table ``base_height`` below): (xs, ys, reachable)."""
    xs = np.arange(X_RANGE[0], X_RANGE[1] + 1e-9, step)
    ys = np.arange(Y_RANGE[0], Y_RANGE[1] + 1e-9, step)
    reachable = np.zeros((len(ys), len(xs)), dtype=bool)
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            try:
                ik.get_inverse_kinematics((x, y, height), approach="down", yaw_deg=yaw_deg,
                                          min_height=min_target_height(base_height))
            except ik.UnreachableError:
                continue
            reachable[j, i] = True
    return xs, ys, reachable


def fk_samples(draws: int):
    """Top-down grasps from the batch FK near the cube height, each checked with the IK.

    Returns:
        (positions (n, 3) [m], number that the IK solved).
    """
    _, positions, yaws = sample_top_down_targets(draws, seed=SEED)
    near = np.abs(positions[:, 2] - HEIGHT) <= SLAB
    positions, yaws = positions[near], yaws[near]
    solved = 0
    for position, yaw in zip(positions, yaws, strict=True):
        try:
            ik.get_inverse_kinematics(position, approach="down", yaw_deg=float(yaw))
        except ik.UnreachableError as error:
            log.warning("FK sample %s not solved: %s", position.round(4), error)
            continue
        solved += 1
    return positions, solved


def plot(output: Path, step: float, draws: int) -> None:
    """Compute the grids and samples and write the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    started = time.perf_counter()
    xs, ys, any_yaw = reachable_grid(step, None)
    _, _, yaw_zero = reachable_grid(step, 0.0)
    log.info("IK grid %d x %d: %d points reachable with some yaw, %d with yaw 0 (%.1f s)",
             len(xs), len(ys), any_yaw.sum(), yaw_zero.sum(), time.perf_counter() - started)
    positions, solved = fk_samples(draws)
    log.info("FK samples within %.0f mm of z = %.3f m: %d, solved by the IK: %d",
             SLAB * 1e3, HEIGHT, len(positions), solved)

    fig, ax = plt.subplots(figsize=(7.5, 9.0), dpi=120)
    extent = (xs[0] - step / 2, xs[-1] + step / 2, ys[0] - step / 2, ys[-1] + step / 2)
    ax.imshow(any_yaw, origin="lower", extent=extent, interpolation="nearest",
              cmap=ListedColormap(["#f4f4f4", "#9fd89f"]), vmin=0, vmax=1)
    ax.contour(xs, ys, yaw_zero.astype(float), levels=[0.5], colors="tab:blue", linewidths=1.2)
    ax.scatter(positions[:, 0], positions[:, 1], s=0.5, c="black", alpha=0.35, linewidths=0)
    level_handles = []
    for k, (z, color) in enumerate(zip(COURSE_BLOCK_HEIGHTS, LEVEL_COLORS, strict=True)):
        counts = []
        for base, style in ((0.0, "-"), (LAB_BASE_HEIGHT, "--")):
            lx, ly, level = reachable_grid(LEVEL_STEP, None, z - base, base)
            counts.append(int(level.sum()))
            if level.any():
                ax.contour(lx, ly, level.astype(float), levels=[0.5], colors=color,
                           linewidths=1.0, linestyles=style)
        log.info("block %d, z = %.3f m: %d grid points reachable on the table, %d on the mount",
                 k + 1, z, *counts)
        empty = "" if any(counts) else ": none (wrist_flex limit)"
        level_handles.append(plt.Line2D([], [], color=color, label=f"block {k + 1} centre, "
                                        f"z = {z * 1e3:.0f} mm above the table{empty}"))
    base = PAN_AXIS_POINT  # the shoulder_pan axis
    ax.plot(base[0], base[1], marker="+", color="k", markersize=14, mew=2)
    ax.annotate("shoulder_pan axis", (base[0], base[1]), textcoords="offset points",
                xytext=(8, -14), fontsize=8)
    for label, cfg, color in (("start (assignment)", STARTING_CONFIGURATION, "tab:red"),
                              ("final (assignment)", FINAL_CONFIGURATION, "tab:purple")):
        position, _ = get_forward_kinematics(cfg)
        ax.plot(position[0], position[1], "s", color=color, markersize=7, mfc="none", mew=2)
        ax.annotate(f"{label}\n({position[0]:.3f}, {position[1]:.3f})", position[:2],
                    textcoords="offset points", xytext=(10, 4), fontsize=8, color=color)
    ax.set_xlabel("x [m] (base frame)")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.grid(True, linewidth=0.3, alpha=0.5)
    ax.set_title("SO-101: where a cube can be picked from above\n"
                 f"cube centre z = {HEIGHT * 1e3:.0f} mm, top-down approach, "
                 "joint limits respected\noutlines: the course's stacking heights "
                 "(assignment 8), top-down",
                 fontsize=10)
    ax.legend(handles=[
        Patch(color="#9fd89f", label="reachable, wrist_roll free (IK grid)"),
        plt.Line2D([], [], color="tab:blue", label="reachable with yaw 0 (cube faces along x, y)"),
        plt.Line2D([], [], ls="", marker=".", color="black",
                   label=f"batch-FK samples within {SLAB * 1e3:.0f} mm (all solved by IK)"),
        *level_handles,
        plt.Line2D([], [], color="0.3", ls="--", label=f"the same on the lab's "
                   f"{LAB_BASE_HEIGHT * 1e3:.0f} mm mount"),
    ], loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=2, fontsize=7, framealpha=0.9)
    fig.tight_layout()
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, metadata=png_metadata("scripts/plot_workspace.py"))
    plt.close(fig)
    print(f"wrote {output}")


def main() -> int:
    """Parse arguments and write the figure."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--output", type=Path, default=OUTPUT, help="PNG to write")
    parser.add_argument("--step", type=float, default=GRID_STEP, help="IK grid spacing [m]")
    parser.add_argument("--draws", type=int, default=FK_DRAWS, help="random configurations for FK")
    add_overwrite_argument(parser)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:  # before the minutes of IK, not after
        output = check_output_path(args.output, "--output", suffixes=(".png",), kind=PNG,
                                   overwrite=args.overwrite)
    except OutputPathError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    plot(output, args.step, args.draws)
    return 0


if __name__ == "__main__":
    sys.exit(main())
