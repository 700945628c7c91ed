"""The page's pose on the table from touched points: a 2-D rigid fit, its residual, its file.

A student marks points on the page (:func:`page_marks`: its corners, 10 mm in), touches
each with the pen's tip, the arm limp (``register_page.py``), and the tip's positions in
the base frame are fitted to the marks by a rotation about the vertical and a translation
(least squares, Kabsch's method in the plane, no scale: a printed page is the size it
says). The fit is the page's pose (``page.Page``'s ``centre`` and ``yaw``); its residual,
each point's distance from its mark after the fit, tells a bad touch from a good one.

Example (the default page, touched exactly)::

    >>> from so101_kinematics.drawing.page import page_to_base
    >>> marks = page_marks("a5")
    >>> fit = fit_page(marks, page_to_base(Page(), marks)[:, :2])
    >>> [round(v, 6) for v in (*fit.centre, fit.yaw)], fit.rms_mm < 1e-9
    ([0.2, 0.0, 0.0], True)
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from so101_kinematics.drawing.page import PAGES, Page
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import rigid_fit_2d

__all__ = [
    "MARK_INSET_MM", "MARK_NAMES", "MAX_RMS_MM", "PageFit", "check_fit", "fit_page",
    "page_marks", "read_page_pose", "read_touched_points",
]

MARK_INSET_MM = 10.0
"""The marks' distance from the page's edges [mm]: a cross a pen's tip can find."""
MARK_NAMES = ("bottom-left", "bottom-right", "top-right", "top-left")
"""The marks in the order they are touched (the page read the right way up)."""
MAX_RMS_MM = 2.0
"""The largest residual (RMS) [mm] of a fit that is used: the pen's tip on a cross, by eye,
with the servos' 0.3 mm steps, is within a millimetre."""


@dataclass(frozen=True)
class PageFit:
    """A page's pose fitted to touched points.

    Attributes:
        page: the page at the fitted pose.
        centre: its centre (x, y) [m] in the base frame.
        yaw: its turn about the vertical [deg] (``Page.yaw``).
        residuals_mm: each touched point's distance from its mark after the fit [mm].
        rms_mm: their root mean square [mm].
    """

    page: Page
    centre: tuple[float, float]
    yaw: float
    residuals_mm: tuple[float, ...]
    rms_mm: float

    def as_json(self) -> dict:
        """The page pose file's content (``read_page_pose`` reads it back)."""
        return {"page": self.page.name, "size_mm": list(self.page.size),
                "centre_m": [round(v, 6) for v in self.centre], "yaw_deg": round(self.yaw, 4),
                "residuals_mm": [round(r, 3) for r in self.residuals_mm],
                "rms_mm": round(self.rms_mm, 3)}


def page_marks(name: str, count: int = 4) -> np.ndarray:
    """The marks (count, 2) [mm] on the page, in touching order (``MARK_NAMES``).

    Example:
        >>> page_marks("a5", 3).tolist()
        [[-95.0, -64.0], [95.0, -64.0], [95.0, 64.0]]
    """
    if count not in (3, 4):
        raise PlanError(f"{count} marks: the page's pose is fitted to 3 or 4 touched points. "
                        "Fix: touch 3 or 4 marks.")
    width, height = PAGES[name]
    x, y = width / 2 - MARK_INSET_MM, height / 2 - MARK_INSET_MM
    return np.array([[-x, -y], [x, -y], [x, y], [-x, y]])[:count]


def fit_page(marks_mm: np.ndarray, touched_m: np.ndarray, name: str = "a5") -> PageFit:
    """The page's pose that takes its marks [mm] nearest the touched points [m], and the residual.

    Args:
        marks_mm: (n, 2) the marks in the page's frame [mm] (:func:`page_marks`).
        touched_m: (n, 2) where the tip touched each, (x, y) in the base frame [m].
        name: the page ("a5", "a4").
    """
    marks_mm = np.asarray(marks_mm, dtype=float).reshape(-1, 2)
    touched_m = np.asarray(touched_m, dtype=float).reshape(-1, 2)
    angle, centre, residuals = rigid_fit_2d(marks_mm / 1000.0, touched_m)
    # the page's x axis is the base's (sin yaw, -cos yaw): the rotation by yaw - 90 deg
    yaw = (math.degrees(angle) + 90.0 + 180.0) % 360.0 - 180.0
    page = Page(name, PAGES[name], (float(centre[0]), float(centre[1])), yaw)
    residuals = 1000.0 * residuals
    return PageFit(page, page.centre, yaw, tuple(float(r) for r in residuals),
                   float(np.sqrt((residuals ** 2).mean())))


def check_fit(fit: PageFit, marks_mm: np.ndarray, touched_m: np.ndarray,
              max_rms_mm: float = MAX_RMS_MM) -> None:
    """Refuse, in one line, a fit whose residual is too large, with its likely cause.

    When another order of the same touches fits within ``max_rms_mm``, they were touched in
    the wrong order (the message gives the order that fits); otherwise the page moved, or a
    touch missed its mark.

    Raises:
        PlanError: the RMS, the worst point, the cause and the fix.
    """
    if fit.rms_mm <= max_rms_mm:
        return
    worst = int(np.argmax(fit.residuals_mm))
    touched_m = np.asarray(touched_m, dtype=float).reshape(-1, 2)
    count = len(touched_m)
    for order in itertools.permutations(range(count)):
        if list(order) == list(range(count)):
            continue
        other = fit_page(marks_mm, touched_m[list(order)], fit.page.name)
        if other.rms_mm <= max_rms_mm:
            touched = ", ".join(f"{MARK_NAMES[i]} as touch {order[i] + 1}" for i in range(count)
                                if order[i] != i)
            raise PlanError(
                f"the touched points do not fit the page: RMS residual {fit.rms_mm:.1f} mm > "
                f"{max_rms_mm:g} mm (point {worst + 1}: {fit.residuals_mm[worst]:.1f} mm); "
                f"likely touched in the wrong order: they fit ({other.rms_mm:.1f} mm) with the "
                f"{touched}. Fix: touch the marks in the order "
                f"{', '.join(MARK_NAMES[:count])} (the page read the right way up).")
    raise PlanError(
        f"the touched points do not fit the page: RMS residual {fit.rms_mm:.1f} mm > "
        f"{max_rms_mm:g} mm (point {worst + 1}, {MARK_NAMES[worst]}: "
        f"{fit.residuals_mm[worst]:.1f} mm); likely the page moved between touches, a touch "
        "missed its mark, or the page is not the size given. Fix: tape the page down and "
        "touch every mark again (--page if it is another size).")


def read_touched_points(path: str | Path) -> np.ndarray:
    """Touched points (n, 2) [m] from a JSON file: ``{"points_m": [[x, y], ...]}``.

    Raises:
        PlanError: a file that is missing, not JSON, or without 3 or 4 (x, y) points.
    """
    text = _read(path, "--points")
    try:
        points = np.asarray(json.loads(text)["points_m"], dtype=float)
    except (ValueError, KeyError, TypeError):
        points = np.empty((0,))
    if points.ndim != 2 or points.shape[1] != 2 or len(points) not in (3, 4) or not np.all(
            np.isfinite(points)):
        raise PlanError(f"--points {path}: not 3 or 4 touched points. Fix: a JSON file "
                        '{"points_m": [[x, y], ...]} with the tip\'s base-frame (x, y) [m] at '
                        f"the marks, in the order {', '.join(MARK_NAMES)}.")
    return points


def read_page_pose(path: str | Path) -> Page:
    """The page a page pose file (``register_page.py --out``) describes.

    Raises:
        PlanError: a file that is missing or not a page pose.
    """
    text = _read(path, "--page-pose")
    try:
        data = json.loads(text)
        centre = tuple(float(v) for v in data["centre_m"])
        yaw, name = float(data["yaw_deg"]), str(data["page"])
        if name not in PAGES or len(centre) != 2 or not all(map(math.isfinite, (*centre, yaw))):
            raise ValueError(name)
    except (ValueError, KeyError, TypeError):
        raise PlanError(f"--page-pose {path}: not a page pose file. Fix: give the file "
                        "register_page.py --out wrote.") from None
    return Page(name, PAGES[name], centre, yaw)


def _read(path: str | Path, option: str) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise PlanError(f"{option} {path}: cannot be read ({error.__class__.__name__}). Fix: "
                        "give an existing file.") from None
