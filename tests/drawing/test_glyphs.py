"""Text in a Hershey stroke font and the simple shapes, as strokes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from so101_kinematics.drawing.glyphs import cap_height, shape_strokes, text_strokes
from so101_kinematics.drawing.strokes import bounds, fit_to_height
from so101_kinematics.errors import PlanError

# The Roman simplex's lines (Hershey's font format, as the hershey-fonts package documents
# its render options): cap line -12, base line 9, descenders' bottom line 16, y down.
CAP, BASE, BOTTOM = -12.0, 9.0, 16.0


def test_a_capital_is_three_quarters_of_the_line_height():
    assert cap_height(30.0) == pytest.approx(30.0 * (BASE - CAP) / (BOTTOM - CAP))  # 22.5 mm


def test_the_letter_e_is_four_strokes_standing_on_the_base_line():
    strokes, (bottom, top) = text_strokes("E")
    assert len(strokes) == 4  # the stem and three arms, one pen stroke each
    assert (bottom, top) == (-BOTTOM, -CAP)
    low, high = bounds(strokes)
    assert (low[1], high[1]) == (-BASE, -CAP)  # from the base line up to the cap line


def test_ece_4560_at_30_mm_is_22_5_mm_capitals_on_one_line():
    raw, lines = text_strokes("ECE 4560")
    strokes = fit_to_height(raw, 30.0, lines)
    low, high = bounds(strokes)
    assert high[1] - low[1] == pytest.approx(22.5)  # no descender: cap line to base line
    assert 150.0 < high[0] - low[0] < 200.0  # eight glyphs about 20 units wide, at 30/28


@pytest.mark.parametrize("text", ["", "   "])
def test_an_empty_text_is_refused_with_the_fix(text):
    with pytest.raises(PlanError, match=r"--text is empty.*Fix:"):
        text_strokes(text)


def test_an_unknown_glyph_is_named():
    with pytest.raises(PlanError, match=r"no glyph for 'é'.*Fix:"):
        text_strokes("café")


def test_the_star_has_five_points_on_a_circle_in_one_closed_stroke():
    (star,) = shape_strokes("star")
    assert len(star) == 6 and np.allclose(star[0], star[-1])
    radii = np.linalg.norm(star[:5], axis=1)
    assert np.allclose(radii, radii[0])
    # a pentagram's height over its circumradius: 1 + cos(36 deg)
    assert bounds([star])[1][1] - bounds([star])[0][1] == pytest.approx(1.0)
    assert radii[0] == pytest.approx(1.0 / (1.0 + math.cos(math.radians(36.0))))


def test_the_circle_and_the_square_are_one_unit_high():
    for shape in ("circle", "square"):
        low, high = bounds(shape_strokes(shape))
        assert (high - low).tolist() == pytest.approx([1.0, 1.0], abs=1e-9)


def test_an_unknown_shape_is_refused():
    with pytest.raises(PlanError, match="--shape 'heart'"):
        shape_strokes("heart")
