"""The page on the table: page millimetres to the base frame, and the reach's refusal."""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.drawing.page import (
    PAGES,
    Page,
    base_to_page,
    check_reach,
    outside_reach,
    page_to_base,
)
from so101_kinematics.drawing.pen import PenPose
from so101_kinematics.errors import PlanError


def test_iso_sizes_laid_landscape():
    assert PAGES["a5"] == (210.0, 148.0) and PAGES["a4"] == (297.0, 210.0)  # ISO 216


def test_a_turned_page_maps_its_corners_by_hand():
    page = Page(centre=(0.25, 0.05), yaw=90.0)  # its up now the base's +y, its right +x
    corner = page_to_base(page, np.array([[100.0, 20.0]]), 0.001)[0]
    assert corner == pytest.approx([0.25 + 0.100, 0.05 + 0.020, 0.001])
    assert base_to_page(page, corner[None, :2]) == pytest.approx(np.array([[100.0, 20.0]]))


def test_a_drawing_in_front_of_the_arm_is_in_reach():
    line = np.column_stack([np.linspace(-60.0, 60.0, 241), np.zeros(241)])
    check_reach(Page(), [line], PenPose())  # no error


def test_strokes_out_of_reach_are_named_with_how_far_and_the_fix():
    near = np.column_stack([np.zeros(21), np.linspace(-5.0, 5.0, 21)])
    far = near + [0.0, 400.0]  # 0.6 m from the base: beyond any reach
    with pytest.raises(PlanError, match=r"1 of 2 strokes \(number 2\) fall outside.*Fix:"):
        check_reach(Page(), [near, far], PenPose())


def test_the_distance_outside_grows_with_the_stroke_moved_out():
    """A stroke moved 10 mm further out is 10 mm further outside (a hand calculation)."""
    dash = np.column_stack([np.zeros(5), np.linspace(160.0, 162.0, 5)])
    page = Page(centre=(0.2, 0.0))
    first = outside_reach(page, [dash], PenPose())[0]
    second = outside_reach(page, [dash + [0.0, 10.0]], PenPose())[0]
    assert first > 0.0
    assert second - first == pytest.approx(10.0, abs=0.5)
