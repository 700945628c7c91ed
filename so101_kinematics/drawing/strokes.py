"""Strokes: metric polylines on a page, resampled evenly and ordered to shorten pen-up travel.

A stroke is one pen-down line: an (n, 2) array of points [mm] in the page's frame (origin
at the page's centre, x to the page's right, y up the page). A drawing is a list of
strokes, drawn in order; between two strokes the pen is up. Everything here is numpy on
plain arrays: the text (``glyphs.py``), the SVG pictures (``svg_paths.py``) and the shapes
(``glyphs.py``) all end as such a list, and :func:`prepare` makes it ready to draw.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from so101_kinematics.errors import PlanError

__all__ = [
    "DEFAULT_SPACING_MM", "MIN_STROKE_MM", "bounds", "fit_to_height", "ink_length",
    "order_strokes", "pen_up_travel", "prepare", "resample", "stroke_length",
]

DEFAULT_SPACING_MM = 0.5
"""Resampling step along a stroke [mm]: well under the pen's line (about 0.5-1 mm wide) and
the servo's resolution at the page (0.088 deg at 0.25 m is 0.4 mm)."""

MIN_STROKE_MM = 0.5
"""A stroke shorter than this [mm] is a dot; it is kept only if the drawing asks for dots."""


def stroke_length(stroke: np.ndarray) -> float:
    """The length [mm] of a polyline.

    Example:
        >>> stroke_length(np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 10.0]]))
        11.0
    """
    points = np.asarray(stroke, dtype=float)
    if len(points) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def ink_length(strokes: Sequence[np.ndarray]) -> float:
    """The total length [mm] of the strokes (the pen-down path)."""
    return sum(stroke_length(s) for s in strokes)


def resample(stroke: np.ndarray, spacing: float = DEFAULT_SPACING_MM) -> np.ndarray:
    """The polyline with points every ``spacing`` [mm] along it, its corners and ends kept.

    Each segment is cut into ``ceil(length / spacing)`` equal parts, so no step is longer
    than ``spacing`` and every corner of the original is a point of the result (a letter's
    corner stays sharp). Repeated points are dropped.

    Example:
        >>> resample(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0]]), 1.0).tolist()
        [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0]]
    """
    if not spacing > 0.0:
        raise PlanError(f"resampling spacing {spacing} mm is not positive. Fix: give e.g. 0.5.")
    points = np.asarray(stroke, dtype=float).reshape(-1, 2)
    out = [points[0]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        length = float(np.linalg.norm(b - a))
        if length < 1e-9:
            continue
        parts = max(1, math.ceil(length / spacing - 1e-9))
        fractions = np.arange(1, parts + 1)[:, None] / parts
        out.extend(a + fractions * (b - a))
    return np.array(out)


def bounds(strokes: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest (x, y) [mm] of all the strokes' points."""
    every = np.vstack([np.asarray(s, dtype=float).reshape(-1, 2) for s in strokes])
    return every.min(axis=0), every.max(axis=0)


def fit_to_height(strokes: Sequence[np.ndarray], height: float,
                  reference: tuple[float, float] | None = None) -> list[np.ndarray]:
    """The strokes scaled to ``height`` [mm] and centred on the page's origin.

    Args:
        strokes: polylines in any unit, y up.
        height: the wanted height [mm] of ``reference`` (or of the drawing's bounds).
        reference: (bottom, top) in the strokes' units whose distance becomes ``height``
            (a font's descender and cap lines); None: the drawing's own bounds.

    Returns:
        New arrays [mm], the drawing's bounding box centred on (0, 0).
    """
    low, high = bounds(strokes)
    bottom, top = reference if reference is not None else (low[1], high[1])
    if not top - bottom > 0.0:
        raise PlanError("the drawing has no height (every point on one line). Fix: draw "
                        "something with some height, or give --shape or --text.")
    scale = height / (top - bottom)
    centre = 0.5 * (low + high)
    return [(np.asarray(s, dtype=float) - centre) * scale for s in strokes]


def _end_cost(point: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    return np.linalg.norm(candidates - point, axis=1)


def order_strokes(strokes: Sequence[np.ndarray],
                  start: Sequence[float] = (0.0, 0.0)) -> list[np.ndarray]:
    """The strokes in the order (and direction) that keeps the pen-up travel short.

    Greedy nearest neighbour: from ``start``, the next stroke is the one with an end
    nearest the pen, drawn from that end (a stroke may be reversed: a line is the same
    line either way). Not the shortest tour (that is the travelling salesman's problem),
    but within a small factor of it on letters, and never longer than the given order's
    travel when that order is itself nearest-first.

    Example:
        >>> far, near = np.array([[10.0, 0.0], [11.0, 0.0]]), np.array([[2.0, 0.0], [1.0, 0.0]])
        >>> [s.tolist() for s in order_strokes([far, near])]
        [[[1.0, 0.0], [2.0, 0.0]], [[10.0, 0.0], [11.0, 0.0]]]
    """
    left = [np.asarray(s, dtype=float) for s in strokes]
    here = np.asarray(start, dtype=float)
    out = []
    while left:
        firsts = np.array([s[0] for s in left])
        lasts = np.array([s[-1] for s in left])
        to_first, to_last = _end_cost(here, firsts), _end_cost(here, lasts)
        i_first, i_last = int(np.argmin(to_first)), int(np.argmin(to_last))
        if to_last[i_last] < to_first[i_first]:
            chosen = left.pop(i_last)[::-1].copy()
        else:
            chosen = left.pop(i_first)
        out.append(chosen)
        here = chosen[-1]
    return out


def pen_up_travel(strokes: Sequence[np.ndarray], start: Sequence[float] = (0.0, 0.0)) -> float:
    """The pen-up distance [mm]: from ``start`` to the first stroke and between strokes."""
    here, total = np.asarray(start, dtype=float), 0.0
    for stroke in strokes:
        total += float(np.linalg.norm(stroke[0] - here))
        here = stroke[-1]
    return total


def prepare(strokes: Sequence[np.ndarray], spacing: float = DEFAULT_SPACING_MM,
            start: Sequence[float] = (0.0, 0.0)) -> list[np.ndarray]:
    """Strokes ready to draw: dots dropped, ordered from ``start``, resampled at ``spacing``.

    Raises:
        PlanError: nothing left to draw (every stroke shorter than ``MIN_STROKE_MM``).
    """
    kept = [np.asarray(s, dtype=float) for s in strokes if stroke_length(s) >= MIN_STROKE_MM]
    if not kept:
        raise PlanError(f"nothing to draw: every stroke is shorter than {MIN_STROKE_MM:g} mm. "
                        "Fix: draw it larger (--height-mm).")
    return [resample(s, spacing) for s in order_strokes(kept, start)]
