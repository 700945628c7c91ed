"""An SVG picture's paths as strokes: lines, Bezier curves and arcs sampled into polylines.

``svgpathtools`` (PyPI) reads the file's ``<path>`` elements and turns its circles, ellipses,
lines, polylines, polygons and rectangles into paths too; each continuous subpath becomes
one stroke, its straight segments kept as they are and its curves sampled every
``CURVE_STEP`` of their length (in the file's units, before the drawing is scaled). SVG's
y axis points down the picture: the strokes come out y up, as the page's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from so101_kinematics.errors import PlanError

__all__ = ["CURVE_POINTS_MIN", "svg_strokes"]

CURVE_POINTS_MIN = 8
"""Points along a curved segment at the least (a small arc still looks round)."""

CURVE_STEP = 1.0 / 200.0  # of the picture's height: a curve's sampling step


def _segment_points(segment, step: float) -> np.ndarray:
    """Points (complex) along one segment of a path, its start left out."""
    from svgpathtools import Line

    if isinstance(segment, Line):
        return np.array([segment.end])
    length = segment.length(error=1e-4)
    count = max(CURVE_POINTS_MIN, int(np.ceil(length / step)))
    return np.array([segment.point(t) for t in np.linspace(0.0, 1.0, count + 1)[1:]])


def _read(path: Path):
    from svgpathtools import svg2paths

    try:
        paths, _ = svg2paths(str(path))
    except FileNotFoundError:
        raise PlanError(f"--svg {path}: no such file. Fix: give the path of an SVG file.") from None
    except Exception as error:  # a malformed file: the parser's own words, one line
        text = " ".join(str(error).split())[:200]
        raise PlanError(f"--svg {path}: not a readable SVG ({type(error).__name__}: {text}). "
                        "Fix: save it again as plain SVG (Inkscape: Save As, Plain SVG).") \
            from None
    return paths


def svg_strokes(path: str | Path) -> list[np.ndarray]:
    """The picture's continuous subpaths as polylines (y up, the file's units).

    Args:
        path: an SVG file.

    Returns:
        One (n, 2) array per continuous subpath.

    Raises:
        PlanError: the file is missing or unreadable, or it has no path with any length (a
            picture of text or an embedded image has nothing a pen can follow).
    """
    path = Path(path)
    subpaths = [sub for p in _read(path) for sub in p.continuous_subpaths()
                if len(sub) and sub.length(error=1e-4) > 0.0]
    if not subpaths:
        raise PlanError(f"--svg {path}: the picture has no path, line or shape with any length "
                        "(text and embedded images are not drawn). Fix: in Inkscape, Path > "
                        "Object to Path, then save again.")
    ys = [pt.imag for sub in subpaths for seg in sub for pt in (seg.start, seg.end)]
    height = max(max(ys) - min(ys), max(abs(seg.start) for sub in subpaths for seg in sub), 1e-9)
    step = height * CURVE_STEP
    strokes = []
    for sub in subpaths:
        points = np.concatenate([[sub[0].start], *[_segment_points(s, step) for s in sub]])
        strokes.append(np.column_stack([points.real, -points.imag]))
    return strokes
