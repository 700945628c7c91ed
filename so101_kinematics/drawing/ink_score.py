"""The ink scored against the target strokes, and the page drawn as an image (PNG).

The figures, all on the page in [mm]:

- ``mean_mm`` and ``worst_mm``: each ink point's distance to the nearest target stroke
  (a point-to-segment distance), over the ink's trace taken every ``TRACE_STEP_MM`` of the
  tip's way (a pen standing still writes one point, not one per physics step);
- ``coverage_pct``: the share of the target strokes (every ``strokes.DEFAULT_SPACING_MM``)
  that has ink within ``COVER_MM``;
- ``stray_mm``: the longest run of ink farther than ``STRAY_MM`` from every target stroke,
  along the ink (a pen dragged between strokes, a slip, a bounce's landing).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from so101_kinematics.drawing.page import Page, base_to_page
from so101_kinematics.drawing.strokes import resample
from so101_kinematics.markers import png_metadata
from so101_kinematics.outputs import atomic_output

__all__ = [
    "COVER_MM", "STRAY_MM", "TRACE_STEP_MM", "distances_to_strokes", "ink_trace",
    "save_drawing", "score_ink",
]

TRACE_STEP_MM = 0.1  # [mm]: the ink's trace keeps a point when the tip moved this far
COVER_MM = 1.0  # [mm]: a target point with ink this close is covered (the line's width)
STRAY_MM = 2.0  # [mm]: ink farther than this from every stroke is stray (twice the line's width)
GAP_S = 0.02  # [s]: touches further apart in time than this are two lines of ink
CHUNK = 1000  # points per block of the distance computation
CAPTION_MM = 16.0  # [mm of the page's scale]: the band under the page for the caption
MM_PER_INCH_SHOWN = 30.0  # the picture's scale: 100 px per 30 mm of page (A5: 700 px wide)


def distances_to_strokes(points: np.ndarray, strokes: Sequence[np.ndarray]) -> np.ndarray:
    """Each point's (n, 2) distance [mm] to the nearest segment of any stroke.

    Example:
        >>> distances_to_strokes(np.array([[5.0, 3.0], [-4.0, 0.0]]),
        ...                      [np.array([[0.0, 0.0], [10.0, 0.0]])]).tolist()
        [3.0, 4.0]
    """
    a = np.vstack([s[:-1] for s in strokes if len(s) > 1])
    b = np.vstack([s[1:] for s in strokes if len(s) > 1])
    ab = b - a
    length2 = np.maximum((ab * ab).sum(axis=1), 1e-18)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    out = np.empty(len(points))
    for start in range(0, len(points), CHUNK):
        p = points[start:start + CHUNK, None, :]
        t = np.clip(((p - a) * ab).sum(axis=2) / length2, 0.0, 1.0)
        nearest = a + t[..., None] * ab
        out[start:start + CHUNK] = np.sqrt(((p - nearest) ** 2).sum(axis=2)).min(axis=1)
    return out


def ink_trace(page: Page, ink: np.ndarray) -> list[np.ndarray]:
    """The ink's lines on the page: (n, 2) [mm] each, a point every ``TRACE_STEP_MM``.

    Args:
        page: the page the ink is on.
        ink: rows (time [s], x [m], y [m], force [N]) of the touches that left ink.
    """
    if len(ink) == 0:
        return []
    on_page = base_to_page(page, ink[:, 1:3])
    breaks = np.flatnonzero(np.diff(ink[:, 0]) > GAP_S) + 1
    lines = []
    for part in np.split(np.arange(len(ink)), breaks):
        kept = [on_page[part[0]]]
        for point in on_page[part[1:]]:
            if np.linalg.norm(point - kept[-1]) >= TRACE_STEP_MM:
                kept.append(point)
        if len(part) > 1 and np.linalg.norm(on_page[part[-1]] - kept[-1]) > 0.0:
            kept.append(on_page[part[-1]])  # the line's end, however close
        lines.append(np.array(kept))
    return lines


def _longest_stray(lines: list[np.ndarray], strokes: Sequence[np.ndarray]) -> float:
    longest = 0.0
    for line in lines:
        far = distances_to_strokes(line, strokes) > STRAY_MM
        run = 0.0
        for i in range(1, len(line)):
            if far[i] and far[i - 1]:
                run += float(np.linalg.norm(line[i] - line[i - 1]))
                longest = max(longest, run)
            else:
                run = 0.0
    return longest


def score_ink(page: Page, strokes: Sequence[np.ndarray], ink: np.ndarray) -> dict:
    """The ink's figures against the target strokes (see the module's docstring).

    Returns:
        ``mean_mm``, ``worst_mm``, ``coverage_pct``, ``stray_mm``, ``ink_mm`` (the ink's
        length), ``points`` (of the trace); the distances are None when there is no ink.
    """
    lines = ink_trace(page, ink)
    if not lines:
        return {"mean_mm": None, "worst_mm": None, "coverage_pct": 0.0, "stray_mm": 0.0,
                "ink_mm": 0.0, "points": 0}
    points = np.vstack(lines)
    distance = distances_to_strokes(points, strokes)
    targets = np.vstack([resample(s) for s in strokes])
    covered = distances_to_strokes(targets, lines if all(len(x) > 1 for x in lines)
                                   else [np.vstack([x, x]) for x in lines]) <= COVER_MM
    ink_mm = sum(float(np.linalg.norm(np.diff(x, axis=0), axis=1).sum()) for x in lines)
    return {"mean_mm": round(float(distance.mean()), 3),
            "worst_mm": round(float(distance.max()), 3),
            "coverage_pct": round(100.0 * float(covered.mean()), 1),
            "stray_mm": round(_longest_stray(lines, strokes), 2),
            "ink_mm": round(ink_mm, 1), "points": int(len(points))}


def save_drawing(path: str | Path, page: Page, strokes: Sequence[np.ndarray], ink: np.ndarray,
                 title: str, program: str = "draw.py") -> Path:
    """Write the page as a PNG: the target strokes faint, the ink over them, the figures.

    Args:
        path: the PNG (checked beforehand: ``outputs.check_output_path``).
        page: the page (its size is the picture's).
        strokes: the target strokes [mm].
        ink: the touches that left ink (:meth:`ink.InkRecorder.ink`).
        title: one or two lines under the page (the figures).
        program: the program named in the PNG's marker.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    width, height = page.size
    band = CAPTION_MM
    figure = Figure(figsize=(width / MM_PER_INCH_SHOWN, (height + band) / MM_PER_INCH_SHOWN),
                    dpi=100)
    axes = figure.add_axes((0.0, band / (height + band), 1.0, height / (height + band)))
    axes.set_xlim(-width / 2, width / 2)
    axes.set_ylim(-height / 2, height / 2)
    axes.set_aspect("equal")
    axes.axis("off")
    axes.add_patch(Rectangle((-width / 2, -height / 2), width, height, fill=False,
                             edgecolor="0.6", linewidth=1.0))
    for stroke in strokes:
        axes.plot(stroke[:, 0], stroke[:, 1], color=(1.0, 0.55, 0.55), linewidth=3.0,
                  solid_capstyle="round")
    for line in ink_trace(page, ink):
        axes.plot(line[:, 0], line[:, 1], color=(0.05, 0.1, 0.45), linewidth=1.0,
                  solid_capstyle="round")
    figure.text(0.5, 0.5 * band / (height + band), title, ha="center", va="center", fontsize=8)
    target = Path(path)
    with atomic_output(target) as temporary:
        figure.savefig(temporary, format="png", metadata=png_metadata(program))
    return target
