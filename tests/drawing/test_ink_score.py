"""The ink scored against the strokes: distances, coverage, stray ink; the page as a PNG."""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.drawing.ink_score import (
    distances_to_strokes,
    ink_trace,
    save_drawing,
    score_ink,
)
from so101_kinematics.drawing.page import Page, page_to_base
from so101_kinematics.markers import png_ours

PAGE = Page()
TARGET = [np.column_stack([np.linspace(-30.0, 30.0, 121), np.zeros(121)])]  # a 60 mm line


def _ink(points_mm, t0=0.0, dt=0.004, force=0.3):
    """Touch rows (time, x, y, force) of a pen that went through ``points_mm`` on the page."""
    xyz = page_to_base(PAGE, np.asarray(points_mm), 0.0)
    times = t0 + dt * np.arange(len(xyz))
    return np.column_stack([times, xyz[:, 0], xyz[:, 1], np.full(len(xyz), force)])


def test_the_distance_to_a_polyline_by_hand():
    corner = [np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])]
    points = np.array([[5.0, -2.0], [13.0, 5.0], [14.0, 13.0], [-3.0, -4.0]])
    assert distances_to_strokes(points, corner) == pytest.approx([2.0, 3.0, 5.0, 5.0])


def test_ink_on_the_line_scores_zero_and_covers_it():
    ink = _ink(np.column_stack([np.linspace(-30.0, 30.0, 601), np.zeros(601)]))
    figures = score_ink(PAGE, TARGET, ink)
    assert figures["mean_mm"] == pytest.approx(0.0, abs=1e-6)
    assert figures["coverage_pct"] == 100.0 and figures["stray_mm"] == 0.0
    assert figures["ink_mm"] == pytest.approx(60.0, abs=0.1)


def test_ink_beside_half_the_line_scores_its_offset_and_covers_half():
    ink = _ink(np.column_stack([np.linspace(0.0, 30.0, 301), np.full(301, 0.8)]))
    figures = score_ink(PAGE, TARGET, ink)
    assert figures["mean_mm"] == pytest.approx(0.8, abs=1e-6)
    assert figures["worst_mm"] == pytest.approx(0.8, abs=1e-6)
    # the right half, and 0.6 mm left of its start (sqrt(1 - 0.8^2)): 62 of 121 points
    assert figures["coverage_pct"] == pytest.approx(100.0 * 62 / 121, abs=0.1)


def test_the_longest_stray_ink_is_measured_along_it():
    on_line = _ink(np.column_stack([np.linspace(-30.0, 30.0, 301), np.zeros(301)]))
    drag = _ink(np.column_stack([np.full(101, 10.0), np.linspace(3.0, 13.0, 101)]), t0=10.0)
    small = _ink(np.column_stack([np.linspace(-20.0, -16.0, 41), np.full(41, 5.0)]), t0=20.0)
    figures = score_ink(PAGE, TARGET, np.vstack([on_line, drag, small]))
    # the drag is 3 to 13 mm from the line: the part beyond 2 mm is all of it, 10 mm long
    assert figures["stray_mm"] == pytest.approx(10.0, abs=0.15)
    assert figures["worst_mm"] == pytest.approx(13.0, abs=1e-6)
    assert len(ink_trace(PAGE, np.vstack([on_line, drag, small]))) == 3  # three lines of ink


def test_no_ink_is_reported_as_none():
    figures = score_ink(PAGE, TARGET, np.zeros((0, 4)))
    assert figures["mean_mm"] is None and figures["coverage_pct"] == 0.0


def test_the_page_is_written_as_a_png_of_ours(tmp_path):
    out = save_drawing(tmp_path / "page.png", PAGE, TARGET, _ink(TARGET[0]), "a line")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png_ours(out)
