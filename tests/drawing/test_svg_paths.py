"""An SVG picture's paths as strokes: lines kept, curves sampled, y turned up."""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.drawing.svg_paths import svg_strokes
from so101_kinematics.errors import PlanError

SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100">'
       '<path d="M 10 10 L 40 10 L 40 40"/>'
       '<circle cx="70" cy="70" r="20"/></svg>')


def test_each_subpath_is_a_stroke_with_svg_y_turned_up(tmp_path):
    picture = tmp_path / "p.svg"
    picture.write_text(SVG)
    strokes = svg_strokes(picture)
    assert len(strokes) == 2
    corner = strokes[0]
    assert corner.tolist() == [[10.0, -10.0], [40.0, -10.0], [40.0, -40.0]]  # lines as given
    circle = strokes[1]
    radius = np.linalg.norm(circle - [70.0, -70.0], axis=1)
    assert radius == pytest.approx(np.full(len(circle), 20.0), abs=1e-9)
    assert len(circle) > 50  # sampled, not its four arcs' ends


def test_a_picture_without_paths_is_refused_with_the_fix(tmp_path):
    picture = tmp_path / "text.svg"
    picture.write_text('<svg xmlns="http://www.w3.org/2000/svg"><text x="1" y="1">hi</text></svg>')
    with pytest.raises(PlanError, match=r"no path.*Fix: in Inkscape"):
        svg_strokes(picture)


def test_a_missing_or_broken_file_is_one_line(tmp_path):
    with pytest.raises(PlanError, match="no such file"):
        svg_strokes(tmp_path / "missing.svg")
    broken = tmp_path / "broken.svg"
    broken.write_text("<svg><path d='M 0 0 L")
    with pytest.raises(PlanError, match="not a readable SVG"):
        svg_strokes(broken)
