"""Plot the pen tip's reach on the table and on a vertical board (docs/final_project_reach.png).

Left, the table seen from above: the points of the paper's surface the tip reaches with the
pen upright (the default) and tilted 20 deg, with the A5 page at draw.py's default pose.
Right, the vertical board light_paint.py paints on (its plane, 0.26 m ahead of the base),
as the camera in front of the arm sees it: the points the tip (the light) reaches with the
holder leaning 60 deg (light_paint.py's) and 90 deg (a pen square to the board), with the
120 mm star's square. Each point is solved on its own (``drawing/pen.py``'s IK from the
course's first guess), within the joint limits.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))

from so101_kinematics.drawing.light_paint import BOARD_CENTRE, LIGHT_TILT_DEG  # noqa: E402
from so101_kinematics.drawing.page import PAGE_THICKNESS, PAGES, Page, page_to_base  # noqa: E402
from so101_kinematics.drawing.pen import PenPose, pen_configuration  # noqa: E402
from so101_kinematics.errors import OutputPathError, UnreachableError  # noqa: E402
from so101_kinematics.markers import png_metadata  # noqa: E402
from so101_kinematics.outputs import (  # noqa: E402
    PNG,
    add_overwrite_argument,
    atomic_output,
    check_output_path,
)

OUTPUT = REPO / "docs" / "final_project_reach.png"
GRID_STEP = 0.005  # [m]
TABLE_TILTS = (0.0, 20.0)  # [deg]: the pen upright (draw.py's default), tilted
BOARD_TILTS = (LIGHT_TILT_DEG, 90.0)  # [deg]: light_paint.py's lean, a pen square to the board
TABLE_X, TABLE_Y = (0.0, 0.42), (-0.32, 0.32)  # [m]: the table's region mapped
BOARD_Y, BOARD_Z = (-0.32, 0.32), (0.0, 0.42)  # [m]: the board's region mapped
STAR_MM = 120.0  # the light painting
TABLE_COLOURS = ((0.7, 0.85, 1.0), (0.35, 0.55, 0.9), (0.55, 0.7, 0.95))  # first, second, both
BOARD_COLOURS = ((1.0, 0.85, 0.6), (0.85, 0.5, 0.3), (0.95, 0.68, 0.45))


def reachable(points: np.ndarray, tilt: float) -> np.ndarray:
    """Whether the tip reaches each point (n, 3) [m] at ``tilt`` [deg]."""
    pose, out = PenPose(tilt), np.zeros(len(points), dtype=bool)
    for k, point in enumerate(points):
        try:
            pen_configuration(point, pose)
            out[k] = True
        except UnreachableError:
            pass
    return out


def _regions(axes, across, up, points, tilts, what: str, colours) -> None:
    """Fill where only the first tilt reaches, only the second, and both; one legend entry each."""
    from matplotlib.colors import ListedColormap

    first, second = (reachable(points, tilt).reshape(across.shape) for tilt in tilts)
    region = first * 1.0 + second * 2.0  # 0 neither, 1 the first only, 2 the second, 3 both
    axes.pcolormesh(across, up, region, cmap=ListedColormap(["white", *colours]), vmin=-0.5,
                    vmax=3.5, shading="nearest")
    labels = (f"{what} {tilts[0]:g} deg only", f"{what} {tilts[1]:g} deg only", "both")
    for colour, label in zip(colours, labels, strict=True):
        axes.plot([], [], color=colour, linewidth=8, label=label)


def _table(axes, step: float) -> None:
    xs, ys = np.arange(*TABLE_X, step), np.arange(*TABLE_Y, step)
    grid_x, grid_y = np.meshgrid(xs, ys, indexing="ij")
    points = np.column_stack([grid_x.ravel(), grid_y.ravel(),
                              np.full(grid_x.size, PAGE_THICKNESS)])
    extent = (-TABLE_Y[1], -TABLE_Y[0], TABLE_X[0], TABLE_X[1])  # the page's right: the base's -y
    _regions(axes, -grid_y, grid_x, points, TABLE_TILTS, "pen tilted", TABLE_COLOURS)
    page = Page("a5", PAGES["a5"])
    width, height = page.size
    corners = np.array([[-width, -height], [width, -height], [width, height], [-width, height],
                        [-width, -height]]) / 2
    outline = page_to_base(page, corners)
    axes.plot(-outline[:, 1], outline[:, 0], color="k", linewidth=1.5,
              label="A5 at draw.py's default pose")
    axes.plot([0], [0], "k+", markersize=10)
    axes.set(xlim=extent[:2], ylim=extent[2:], aspect="equal",
             xlabel="-y [m] (the page's right)", ylabel="x [m] (away from the arm)",
             title="A page on the table, from above")
    axes.legend(loc="lower right", fontsize=8)


def _board(axes, step: float) -> None:
    ys, zs = np.arange(*BOARD_Y, step), np.arange(*BOARD_Z, step)
    grid_y, grid_z = np.meshgrid(ys, zs, indexing="ij")
    points = np.column_stack([np.full(grid_y.size, BOARD_CENTRE[0]), grid_y.ravel(),
                              grid_z.ravel()])
    _regions(axes, grid_y, grid_z, points, BOARD_TILTS, "holder leaning", BOARD_COLOURS)
    half = STAR_MM / 2000.0
    cy, cz = BOARD_CENTRE[1], BOARD_CENTRE[2]
    axes.plot([cy - half, cy + half, cy + half, cy - half, cy - half],
              [cz - half, cz - half, cz + half, cz + half, cz - half], color="k", linewidth=1.5,
              label=f"the {STAR_MM:g} mm star's square")
    axes.axhline(0.0, color="0.4", linewidth=1.0)
    axes.set(xlim=BOARD_Y, ylim=BOARD_Z, aspect="equal", xlabel="y [m] (as the camera sees it)",
             ylabel="z [m] (above the table)",
             title=f"A vertical board {BOARD_CENTRE[0]:g} m ahead of the base")
    axes.legend(loc="upper right", fontsize=8)


def plot(output: Path, step: float) -> float:
    """Write the two maps to ``output``; returns the seconds taken."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    started = time.perf_counter()
    figure = Figure(figsize=(12.0, 5.2), dpi=100)
    table, board = figure.subplots(1, 2)
    _table(table, step)
    _board(board, step)
    figure.suptitle("Where the pen's tip reaches (each point's IK within the joint limits, "
                    f"a {1000 * step:g} mm grid)", fontsize=10)
    figure.tight_layout()
    with atomic_output(output) as temporary:
        figure.savefig(temporary, format="png", metadata=png_metadata("plot_drawing_reach.py"))
    return time.perf_counter() - started


def main() -> int:
    """Parse arguments and write the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=OUTPUT, help="PNG to write")
    parser.add_argument("--step", type=float, default=GRID_STEP, help="grid spacing [m]")
    add_overwrite_argument(parser)
    args = parser.parse_args()
    try:
        output = check_output_path(args.output, "--output", suffixes=(".png",), kind=PNG,
                                   overwrite=args.overwrite)
    except OutputPathError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    if not 0.0005 <= args.step <= 0.05:
        print(f"error: --step {args.step} m is outside [0.0005, 0.05] m. Fix: give e.g. "
              f"{GRID_STEP}.", file=sys.stderr)
        return 2
    seconds = plot(output, args.step)
    print(f"Wrote {output} in {seconds:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
