"""The page on the table: its size and pose, page millimetres to the base frame, the reach.

The page's frame: origin at its centre, x to the page's right, y up the page, in [mm].
Laid on the table in front of the arm at its default pose, the page's up is the base's
+x (away from the arm) and its right the base's -y: a reader standing behind the arm,
looking where it looks, reads it; the overhead camera (``model/table.xml``) sees it so.
The pose turns it by ``yaw`` about the vertical and puts its centre at (x, y).

:func:`check_reach` is the refusal: which strokes fall outside what the pen can reach at
the chosen tilt, by how much, and the fix.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from so101_kinematics.drawing.pen import PenPose, pen_configuration
from so101_kinematics.errors import PlanError, UnreachableError

__all__ = [
    "PAGES", "PAGE_THICKNESS", "Page", "base_to_page", "check_reach", "outside_reach",
    "page_to_base",
]

PAGES = {"a5": (210.0, 148.0), "a4": (297.0, 210.0)}
"""ISO 216 sizes [mm] (A5 148 x 210, A4 210 x 297), laid landscape: (width, height), the
long side across the arm's front, where its reach is widest."""

PAGE_THICKNESS = 0.0005
"""The paper's top above the table [m]: a few sheets, or one on a thin board."""

REACH_STEP_MM = 2.0  # the reach check tests the strokes' points this far apart [mm]
REACH_ANCHOR = (0.2, 0.0)  # [m]: a point the pen reaches at any tilt in range (its middle)
BISECTIONS = 12  # halvings of the way from a reachable point to one outside: 0.1 mm or less


@dataclass(frozen=True)
class Page:
    """A page on the table.

    Attributes:
        name: "a5" or "a4" (or "custom").
        size: (width, height) [mm].
        centre: its centre (x, y) [m] in the base frame.
        yaw: its turn about the vertical [deg] (0: its up is the base's +x).
    """

    name: str = "a5"
    size: tuple[float, float] = PAGES["a5"]
    centre: tuple[float, float] = (0.2, 0.0)
    yaw: float = 0.0

    def axes(self) -> tuple[np.ndarray, np.ndarray]:
        """The page's x (right) and y (up) axes in the base frame, unit (2,) vectors."""
        c, s = math.cos(math.radians(self.yaw)), math.sin(math.radians(self.yaw))
        return np.array([s, -c]), np.array([c, s])


def page_to_base(page: Page, points_mm: np.ndarray, z: float = PAGE_THICKNESS) -> np.ndarray:
    """Page points (n, 2) [mm] to base-frame points (n, 3) [m] at height ``z`` [m].

    Example (an A5 page at (0.2, 0) m: its up is the base's +x, its right the base's -y)::

        >>> page_to_base(Page(), np.array([[10.0, 20.0]]), 0.0).round(4).tolist()
        [[0.22, -0.01, 0.0]]
    """
    ex, ey = page.axes()
    points = np.asarray(points_mm, dtype=float).reshape(-1, 2) / 1000.0
    xy = np.asarray(page.centre) + points[:, :1] * ex + points[:, 1:] * ey
    return np.column_stack([xy, np.full(len(xy), z)])


def base_to_page(page: Page, xy: np.ndarray) -> np.ndarray:
    """Base-frame (x, y) points (n, 2) [m] to page points (n, 2) [mm]."""
    ex, ey = page.axes()
    rel = np.asarray(xy, dtype=float).reshape(-1, 2) - np.asarray(page.centre)
    return np.column_stack([rel @ ex, rel @ ey]) * 1000.0


def _reachable(tip: np.ndarray, pose: PenPose, initial) -> dict | None:
    try:
        return pen_configuration(tip, pose, initial)
    except UnreachableError:
        return None


def _beyond(tip: np.ndarray, anchor: np.ndarray, pose: PenPose) -> float:
    """How far [m] ``tip`` lies beyond the reach, along the way from a reachable ``anchor``."""
    inside, outside = anchor, tip
    for _ in range(BISECTIONS):
        middle = 0.5 * (inside + outside)
        if _reachable(middle, pose, None) is not None:
            inside = middle
        else:
            outside = middle
    return float(np.linalg.norm(tip - inside))


def outside_reach(page: Page, strokes: Sequence[np.ndarray], pose: PenPose,
                  z: float = PAGE_THICKNESS) -> dict[int, float]:
    """Stroke index -> how far [mm] its farthest point is outside the pen's reach.

    Each stroke's points are tested every ``REACH_STEP_MM`` (and its ends); the distance
    is measured along the way from the drawing's first point in reach (or, when none is,
    from ``REACH_ANCHOR``) to the point outside.
    """
    anchor, beyond = None, {}
    tested = []
    for index, stroke in enumerate(strokes):
        step = max(1, int(REACH_STEP_MM / 0.5))
        chosen = np.vstack([stroke[::step], stroke[-1:]])
        tested.append((index, page_to_base(page, chosen, z)))
    misses = []
    for index, tips in tested:
        initial = None
        for tip in tips:
            found = _reachable(tip, pose, initial)
            if found is None:
                misses.append((index, tip))
            elif anchor is None:
                anchor = tip
            initial = found
    if misses and anchor is None:  # nothing of the drawing in reach: from the reach's middle
        anchor = np.array([*REACH_ANCHOR, z])
    for index, tip in misses:
        beyond[index] = max(beyond.get(index, 0.0), 1000.0 * _beyond(tip, anchor, pose))
    return beyond


def check_reach(page: Page, strokes: Sequence[np.ndarray], pose: PenPose,
                z: float = PAGE_THICKNESS) -> None:
    """Refuse, in one line, a drawing whose strokes the pen cannot reach.

    Raises:
        PlanError: naming the strokes (1-based, in drawing order) outside the reach, the
            farthest distance and the fix.
    """
    beyond = outside_reach(page, strokes, pose, z)
    if not beyond:
        return
    names = ", ".join(str(i + 1) for i in sorted(beyond)[:12]) + (
        ", ..." if len(beyond) > 12 else "")
    worst = max(beyond.values())
    raise PlanError(
        f"{len(beyond)} of {len(strokes)} strokes (number {names}) fall outside the arm's "
        f"reach with the pen at a {math.degrees(pose.tilt):g} deg tilt, by up to "
        f"{worst:.0f} mm (page centre at ({page.centre[0]:.3f}, {page.centre[1]:.3f}) m). "
        f"Fix: move the page (--page-at X Y) so that these strokes come {worst:.0f} mm or more "
        "towards the arm's middle reach (0.2, 0) m, draw smaller (--height-mm), or tilt the "
        "pen (--tilt-deg 20).")
