"""The placement sheet: a PDF to print at 100 % that shows where the cubes go, at 1:1.

:func:`write_sheet` draws, in the robot's base frame (the FK's frame): a 1 cm
grid, the base frame's origin and its x/y axes, the shoulder_pan axis (the
vertical the arm turns about, ``PAN_AXIS_CM`` in front of the origin, from the
FK's ``g_w1``: not under the origin), the outline of the base's footprint (the bottom of the model's
base mesh, as MuJoCo places it), and the pick and place cubes' 26 mm
footprints at the FK positions of the plan's pick and place steps, turned by
the cube's yaw there (the grasp's jaw axis, as ``cartesian_plan`` defines
it), each labelled with its x, y [cm]. Every page carries a 10 cm scale bar
and the line that tells the student to check it with a ruler. When the area
does not fit one page it is tiled over several, overlapping by
``OVERLAP_CM``, with lettered alignment marks in the overlaps.

On the paper the robot's x axis points up the page (away from the student
standing at the bottom edge) and its y axis to the left, as seen from above.

A stacking plan (``so101_kinematics.planning.stacking``) draws each block's start and
the stack's spot instead. With the arm on a mount (``base_height``, the lab's
15 mm) the sheet lies on the table, that far below the base frame: the x, y
positions are the same, the header says how high the base frame is and where
the cubes' centres are (``-base_height`` + 13 mm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from so101_kinematics.constants import CUBE_SIZE
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, FIXED_TRANSFORMS
from so101_kinematics.markers import pdf_metadata
from so101_kinematics.outputs import atomic_output
from so101_kinematics.planning.motion import Plan
from so101_kinematics.planning.plans import pick_and_place_steps

__all__ = [
    "CUBE_COLOR", "ORIGIN_COLOR", "PAN_AXIS_COLOR", "PAPER_MM", "SCALE_BAR_COLOR",
    "write_sheet",
]

PAPER_MM = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}
"""Paper sizes, portrait (width, height) [mm]."""
MM_PER_INCH = 25.4
CUBE_EDGE_MM = CUBE_SIZE * 1000.0  # the course's cube [mm]
SCALE_BAR_MM = 100.0     # the scale bar to check with a ruler [mm]
MARGIN_MM = 10.0         # blank border of each page (printers do not print there) [mm]
HEADER_MM = 17.0         # title and instructions above the drawing [mm]
FOOTER_MM = 14.0         # the scale bar below the drawing [mm]
CONTENT_MARGIN_CM = 1.5  # drawn around the footprint and the cubes [cm]
OVERLAP_CM = 2.0         # tiles overlap this much; the alignment marks sit in the middle [cm]
FOOTPRINT_SLICE_M = 0.003  # the footprint: the base mesh's vertices this close to its bottom [m]
BASE_MESH = "base_so101_v2"
CUBE_COLOR = (0.85, 0.1, 0.1)
SCALE_BAR_COLOR = (0.0, 0.0, 0.55)
FOOTPRINT_COLOR = (0.1, 0.45, 0.1)
ORIGIN_COLOR = (0.55, 0.0, 0.55)
PAN_AXIS_COLOR = (0.0, 0.4, 0.6)
PAN_AXIS_CM = tuple(float(v) * 100.0 for v in FIXED_TRANSFORMS["w1"][0][:2])
"""Where the shoulder_pan axis meets the table, (x, y) [cm] in the base frame (g_w1's offset)."""
RULER_LINE = ("Print at 100 % (actual size, no 'fit to page'), then check with a ruler: the bar "
              "below must measure 10.0 cm and each cube square 2.6 cm.")


@dataclass(frozen=True)
class CubeMark:
    """A cube's footprint on the sheet: the plan's step, its FK centre [cm] and yaw [deg]."""

    role: str          # "pick" or "place"
    step: str
    x_cm: float
    y_cm: float
    yaw_deg: float

    @property
    def label(self) -> str:
        """The label printed beside the square."""
        return f"{self.role} ({self.step}): x = {self.x_cm:.1f} cm, y = {self.y_cm:.1f} cm"


@dataclass
class SheetInfo:
    """What :func:`write_sheet` drew."""

    path: Path
    paper: str
    orientation: str                  # "portrait" or "landscape"
    page_mm: tuple[float, float]      # (width, height) of each page [mm]
    tiles: tuple[int, int]            # (rows, columns)
    cubes: list[CubeMark] = field(default_factory=list)
    base_height: float = 0.0          # the table below the base frame [m]

    @property
    def pages(self) -> int:
        """The number of pages."""
        return self.tiles[0] * self.tiles[1]

    def summary(self) -> str:
        """What to tell the student."""
        lines = [f"Placement sheet: {self.path} ({self.pages} page(s), {self.paper} "
                 f"{self.orientation}). {RULER_LINE}"]
        if self.base_height:
            lines.append(f"  {mount_line(self.base_height)}")
        lines += [f"  {cube.label}" for cube in self.cubes]
        return "\n".join(lines)


def cube_marks(plan: Plan) -> list[CubeMark]:
    """The pick and place cubes of ``plan``: FK object-frame position and the grasp's yaw."""
    marks = []
    for role, step in zip(("pick", "place"), pick_and_place_steps(plan), strict=True):
        position, rotation = forward_kinematics({j: step.configuration[j] for j in ARM_JOINTS})
        yaw = math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))
        marks.append(CubeMark(role, step.name, float(position[0]) * 100.0,
                              float(position[1]) * 100.0, yaw))
    return marks


def stack_marks(stack) -> list[CubeMark]:
    """A stacking plan's blocks at their starts, then the stack's spot (turned as its bottom)."""
    marks = [CubeMark(f"block {i + 1}", "start", b.start[0] * 100.0, b.start[1] * 100.0,
                      b.start_yaw_deg) for i, b in enumerate(stack.blocks)]
    _, place = pick_and_place_steps(stack.plan)  # the top block's release: the stack's yaw
    _, rotation = forward_kinematics({j: place.configuration[j] for j in ARM_JOINTS})
    x, y, _ = stack.blocks[0].target
    marks.append(CubeMark("stack", f"{len(stack.blocks)} blocks", x * 100.0, y * 100.0,
                          math.degrees(math.atan2(rotation[1, 0], rotation[0, 0]))))
    return marks


def mount_line(base_height: float) -> str:
    """The header's line for an arm on a mount ``base_height`` [m] above the sheet."""
    return (f"The arm stands on a {base_height * 1e3:.0f} mm mount: its base frame is "
            f"{base_height * 100:.1f} cm above this sheet; a cube resting here has its centre "
            f"at z = {(CUBE_EDGE_MM / 2000.0 - base_height) * 100:.1f} cm in the base frame.")


def cube_corners_cm(cube: CubeMark) -> np.ndarray:
    """The square's four corners, (x, y) in the base frame [cm]."""
    half = CUBE_EDGE_MM / 20.0
    c, s = math.cos(math.radians(cube.yaw_deg)), math.sin(math.radians(cube.yaw_deg))
    local = np.array([[half, half], [-half, half], [-half, -half], [half, -half]])
    return np.array([cube.x_cm, cube.y_cm]) + local @ np.array([[c, s], [-s, c]])


@lru_cache(maxsize=1)
def base_footprint_cm() -> tuple[tuple[float, float], ...]:
    """The outline of the base on the table: convex hull of the base mesh's bottom, (x, y) [cm].

    From the model as MuJoCo compiles it (the mesh placed by its geom's pose in
    the base body, which sits at the world origin = the FK's base frame).
    """
    import mujoco

    from so101_kinematics.sim.scene import load_model

    m = load_model()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    mesh = m.mesh(BASE_MESH).id
    geom = next(g for g in range(m.ngeom) if m.geom_dataid[g] == mesh
                and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    start, count = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
    world = d.geom_xpos[geom] + m.mesh_vert[start:start + count] @ d.geom_xmat[geom].reshape(3, 3).T
    bottom = world[world[:, 2] <= world[:, 2].min() + FOOTPRINT_SLICE_M]
    return tuple((float(x) * 100.0, float(y) * 100.0) for x, y in convex_hull(bottom[:, :2]))


def convex_hull(points: np.ndarray) -> list[tuple[float, float]]:
    """Convex hull of 2-D points, counter-clockwise (Andrew's monotone chain).

    Example:
        >>> convex_hull(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]))
        [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    """
    pts = sorted({(float(x), float(y)) for x, y in points})

    def half(sequence):
        chain: list[tuple[float, float]] = []
        for p in sequence:
            while len(chain) >= 2 and ((chain[-1][0] - chain[-2][0]) * (p[1] - chain[-2][1])
                                       - (chain[-1][1] - chain[-2][1]) * (p[0] - chain[-2][0])
                                       ) <= 0:
                chain.pop()
            chain.append(p)
        return chain[:-1]

    return half(pts) + half(reversed(pts))


# --- paper coordinates: u = -y (to the right), v = x (up the page), in cm ---------------------
def to_paper(xy_cm) -> np.ndarray:
    """Base-frame (x, y) [cm] -> sheet (u, v) [cm]: x up the page, y to the left."""
    xy = np.asarray(xy_cm, dtype=float)
    return np.stack([-xy[..., 1], xy[..., 0]], axis=-1)


def _window_mm(page: tuple[float, float]) -> tuple[float, float]:
    return page[0] - 2 * MARGIN_MM, page[1] - 2 * MARGIN_MM - HEADER_MM - FOOTER_MM


def _tiling(low: float, high: float, size: float) -> tuple[int, list[float]]:
    """How many windows of ``size`` [cm] overlapping by OVERLAP_CM cover [low, high]; starts."""
    step = size - OVERLAP_CM
    n = max(1, math.ceil((high - low - size) / step - 1e-9) + 1)
    covered = size + (n - 1) * step
    first = low - (covered - (high - low)) / 2.0
    return n, [first + i * step for i in range(n)]


def layout(cubes: list[CubeMark], paper: str):
    """Orientation, page size [mm] and the tiles' window origins (u0, v0) [cm] per row/column."""
    points = [to_paper(base_footprint_cm())] + [to_paper(cube_corners_cm(c)) for c in cubes]
    points.append(to_paper([[0.0, 0.0], [6.0, 0.0], [0.0, 6.0]]))  # origin and the axes' arrows
    allpts = np.concatenate(points)
    low = allpts.min(axis=0) - CONTENT_MARGIN_CM
    high = allpts.max(axis=0) + CONTENT_MARGIN_CM
    low[1] -= 1.5  # room for the labels below the cubes
    width, height = PAPER_MM[paper]
    best = None
    for orientation, page in (("portrait", (width, height)), ("landscape", (height, width))):
        w, h = (v / 10.0 for v in _window_mm(page))
        cols, us = _tiling(low[0], high[0], w)
        rows, vs = _tiling(low[1], high[1], h)
        if best is None or rows * cols < best[2][0] * best[2][1]:
            best = (orientation, page, (rows, cols), us, vs[::-1])  # first row at the top
    return best


def alignment_marks(us: list[float], vs: list[float], size: tuple[float, float]):
    """Lettered marks (name, u, v) [cm] in the middle of each overlap between two tiles."""
    w, h = size
    marks = []
    for i in range(1, len(us)):  # between columns i-1 and i
        u = us[i] + OVERLAP_CM / 2.0
        for v0 in vs:
            marks += [(u, v0 + 0.25 * h), (u, v0 + 0.75 * h)]
    for i in range(1, len(vs)):  # between rows i-1 (above) and i (below)
        v = vs[i] + h - OVERLAP_CM / 2.0
        for u0 in us:
            marks += [(u0 + 0.25 * w, v), (u0 + 0.75 * w, v)]
    return [(_letters(k), u, v) for k, (u, v) in enumerate(marks)]


def _letters(k: int) -> str:
    return (_letters(k // 26 - 1) if k >= 26 else "") + chr(ord("A") + k % 26)


def write_sheet(plan: Plan, path: str | Path, paper: str = "a4",
                source: str = "the course's plan", *, stack=None,
                base_height: float = 0.0) -> SheetInfo:
    """Write the placement sheet of ``plan`` as a PDF (checked path; written atomically).

    Args:
        plan: the plan whose pick and place steps place the cubes.
        path: the PDF to write (``outputs.check_output_path`` it first).
        paper: "a4" or "letter".
        source: where the plan came from, printed in the title.
        stack: a ``so101_kinematics.planning.stacking.StackPlan``: draw its blocks' starts and
            the stack's spot (its ``plan`` is then the plan).
        base_height: the table (the sheet) below the base frame [m] (the lab's mount).

    Returns:
        What was drawn (pages, tiles, the cubes' positions).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    cubes = stack_marks(stack) if stack is not None else cube_marks(plan)
    if stack is not None:
        source = f"stacking {len(stack.blocks)} blocks"
    orientation, page, (rows, cols), us, vs = layout(cubes, paper)
    window = tuple(v / 10.0 for v in _window_mm(page))
    marks = alignment_marks(us, vs, window)
    with atomic_output(path) as temporary, PdfPages(
            temporary, metadata=pdf_metadata("so101 sheet")) as pdf:
        for r, v0 in enumerate(vs):
            for c, u0 in enumerate(us):
                fig = _page(page, (u0, v0), window, cubes, marks, source,
                            (r * cols + c + 1, rows * cols, r + 1, c + 1), base_height)
                pdf.savefig(fig)
                plt.close(fig)
    return SheetInfo(Path(path), paper, orientation, page, (rows, cols), cubes, base_height)


def _label_inside(fig, ax, u: float, v: float, text: str) -> None:
    """A cube's label centred under it at (u, v) [cm], moved just enough to stay in the window.

    Text is not clipped to the drawing: a label hanging out of the window would
    print over the header or the footer, or off the paper.
    """
    label = ax.text(u, v, text, ha="center", va="top", fontsize=7, color=CUBE_COLOR, zorder=4)
    box = label.get_window_extent(fig.canvas.get_renderer()).transformed(
        ax.transData.inverted())
    (left, bottom), (right, top) = box.get_points()
    (u_low, u_high), (v_low, v_high) = ax.get_xlim(), ax.get_ylim()
    pad = 0.1  # [cm]
    du = max(0.0, u_low + pad - left) - max(0.0, right - (u_high - pad))
    dv = max(0.0, v_low + pad - bottom) - max(0.0, top - (v_high - pad))
    label.set_position((u + du, v + dv))


def _page(page, origin, window, cubes, marks, source, numbering, base_height=0.0):
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon, Rectangle

    width, height = page
    fig = plt.figure(figsize=(width / MM_PER_INCH, height / MM_PER_INCH))
    box = [MARGIN_MM / width, (MARGIN_MM + FOOTER_MM) / height,
           window[0] * 10.0 / width, window[1] * 10.0 / height]
    ax = fig.add_axes(box)
    (u0, v0), (w, h) = origin, window
    ax.set_xlim(u0, u0 + w)
    ax.set_ylim(v0, v0 + h)
    ax.set_axis_off()
    ax.add_patch(Rectangle((u0, v0), w, h, fill=False, lw=0.8, color="0.3"))
    for u in range(math.ceil(u0), math.floor(u0 + w) + 1):
        ax.axvline(u, lw=0.9 if u % 5 == 0 else 0.3, color="0.55" if u % 5 == 0 else "0.8")
        if u % 5 == 0:
            ax.text(u + 0.1, v0 + h - 0.15, f"y = {-u}", fontsize=6, va="top", color="0.4")
    for v in range(math.ceil(v0), math.floor(v0 + h) + 1):
        ax.axhline(v, lw=0.9 if v % 5 == 0 else 0.3, color="0.55" if v % 5 == 0 else "0.8")
        if v % 5 == 0:
            ax.text(u0 + 0.1, v + 0.1, f"x = {v}", fontsize=6, color="0.4")
    # the base frame: origin and axes (x up the page, y to the left)
    ax.annotate("", xy=(0, 5), xytext=(0, 0), arrowprops={"arrowstyle": "-|>", "lw": 1.5})
    ax.annotate("", xy=(-5, 0), xytext=(0, 0), arrowprops={"arrowstyle": "-|>", "lw": 1.5})
    ax.text(0.25, 5.0, "x", fontsize=11, weight="bold", va="top")
    ax.text(-5.0, 0.25, "y", fontsize=11, weight="bold")
    ax.add_patch(Circle((0.0, 0.0), 0.15, color=ORIGIN_COLOR, lw=0, zorder=4))
    ax.text(0.25, -0.6, "base frame origin", fontsize=6, color=ORIGIN_COLOR)
    pan = to_paper(PAN_AXIS_CM)
    ax.add_patch(Circle(pan, 0.12, color=PAN_AXIS_COLOR, lw=0, zorder=4))
    ax.text(pan[0] + 0.25, pan[1] - 0.05, f"shoulder_pan axis: {PAN_AXIS_CM[0] * 10:.1f} mm "
            "in front of\nthe origin (not the origin)", fontsize=6, va="top",
            color=PAN_AXIS_COLOR)
    ax.add_patch(Polygon(to_paper(base_footprint_cm()), closed=True, fill=False, lw=1.6,
                         color=FOOTPRINT_COLOR, ls="--"))
    ax.text(*to_paper(base_footprint_cm()).min(axis=0) + [0.0, -0.5], "robot base: align its "
            "footprint here", fontsize=6, color=FOOTPRINT_COLOR)
    for cube in cubes:
        corners = to_paper(cube_corners_cm(cube))
        ax.add_patch(Polygon(corners, closed=True, facecolor=(1.0, 0.85, 0.85),
                             edgecolor=CUBE_COLOR, lw=0.8, zorder=3))
        centre = to_paper([cube.x_cm, cube.y_cm])
        ax.plot(*centre, "+", color=CUBE_COLOR, ms=6, zorder=4)
        if u0 <= centre[0] <= u0 + w and v0 <= centre[1] <= v0 + h:  # its label on its page
            _label_inside(fig, ax, centre[0], corners[:, 1].min() - 0.4, cube.label)
    for name, u, v in marks:
        if u0 <= u <= u0 + w and v0 <= v <= v0 + h:
            ax.add_patch(Circle((u, v), 0.4, fill=False, lw=0.8, zorder=5))
            ax.plot([u - 0.6, u + 0.6], [v, v], color="black", lw=0.8, zorder=5)
            ax.plot([u, u], [v - 0.6, v + 0.6], color="black", lw=0.8, zorder=5)
            ax.text(u + 0.5, v + 0.45, name, fontsize=8, weight="bold", zorder=5)
    number, total, row, col = numbering
    top = 1.0 - MARGIN_MM / height
    title = f"SO-101 placement sheet: {source}"
    if total > 1:
        title += (f"    page {number} of {total} (row {row}, column {col}); tape the pages "
                  "together with the lettered marks on top of each other")
    fig.text(MARGIN_MM / width, top, title, fontsize=8, va="top", weight="bold")
    fig.text(MARGIN_MM / width, top - 5.0 / height, RULER_LINE, fontsize=7, va="top")
    fig.text(MARGIN_MM / width, top - 9.5 / height, "Base frame: x up the page, y to the left; "
             "1 cm grid, every 5th line darker. Put each cube on its square, edges on the "
             "lines." + (f" {mount_line(base_height)}" if base_height else ""), fontsize=7,
             va="top")
    bar = Rectangle((MARGIN_MM / width, (MARGIN_MM + 3.0) / height), SCALE_BAR_MM / width,
                    2.5 / height, transform=fig.transFigure, color=SCALE_BAR_COLOR, lw=0)
    fig.patches.append(bar)
    fig.text((MARGIN_MM + SCALE_BAR_MM + 3.0) / width, (MARGIN_MM + 3.0) / height,
             "10 cm: check with a ruler", fontsize=7)
    return fig
