"""Strokes: resampled evenly with their corners kept, ordered to shorten the pen-up travel."""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.drawing.strokes import (
    bounds,
    fit_to_height,
    order_strokes,
    pen_up_travel,
    prepare,
    resample,
    stroke_length,
)
from so101_kinematics.errors import PlanError


def test_resampling_keeps_every_corner_and_no_step_is_longer_than_the_spacing():
    letter_l = np.array([[0.0, 10.0], [0.0, 0.0], [7.0, 0.0]])  # 10 mm down, 7 mm across
    points = resample(letter_l, 0.5)
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert steps.max() <= 0.5 + 1e-12
    assert len(points) == 1 + 20 + 14  # 10 / 0.5 and 7 / 0.5 steps, by hand
    for corner in letter_l:
        assert np.min(np.linalg.norm(points - corner, axis=1)) < 1e-12
    assert stroke_length(points) == pytest.approx(17.0)


def test_resampling_refuses_a_spacing_that_is_not_positive():
    with pytest.raises(PlanError, match="Fix:"):
        resample(np.array([[0.0, 0.0], [1.0, 0.0]]), 0.0)


def test_ordering_shortens_the_pen_up_travel_and_may_reverse_a_stroke():
    # three horizontal dashes along x, given out of order and one backwards
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[30.0, 0.0], [20.0, 0.0]])  # drawn from its far end as given
    c = np.array([[40.0, 0.0], [50.0, 0.0]])
    given = [c, a, b]
    ordered = order_strokes(given)
    assert [s[0, 0] for s in ordered] == [0.0, 20.0, 40.0]  # b reversed: from 20 to 30
    # by hand: 0 to the first stroke, then 10 -> 20 and 30 -> 40
    assert pen_up_travel(ordered) == pytest.approx(20.0)
    assert pen_up_travel(given) == pytest.approx(40.0 + 40.0 + 30.0)


def test_fit_to_height_scales_the_reference_lines_to_the_height_and_centres_the_drawing():
    square = [np.array([[1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [1.0, 3.0], [1.0, 1.0]])]
    fitted = fit_to_height(square, 30.0)
    low, high = bounds(fitted)
    assert low.tolist() == pytest.approx([-15.0, -15.0])
    assert high.tolist() == pytest.approx([15.0, 15.0])
    # a reference twice the drawing's own height: the drawing comes out half as high
    half = fit_to_height(square, 30.0, reference=(0.0, 4.0))
    assert (bounds(half)[1] - bounds(half)[0]).tolist() == pytest.approx([15.0, 15.0])


def test_prepare_drops_dots_and_refuses_a_drawing_of_dots_only():
    dot = np.array([[0.0, 0.0], [0.1, 0.0]])
    line = np.array([[5.0, 0.0], [9.0, 0.0]])
    ready = prepare([dot, line])
    assert len(ready) == 1 and stroke_length(ready[0]) == pytest.approx(4.0)
    with pytest.raises(PlanError, match="nothing to draw"):
        prepare([dot])
