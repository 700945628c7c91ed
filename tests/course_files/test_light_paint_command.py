"""light_paint.py: the TA's command, its report and exposure, and its one-line refusals."""

from __future__ import annotations

import json

import pytest

import light_paint
from so101_kinematics.markers import png_ours


def test_an_empty_text_is_refused_in_one_line(capsys):
    assert light_paint.main(["--text", ""]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--text is empty" in err and "Fix:" in err


def test_a_size_out_of_range_is_refused(capsys):
    assert light_paint.main(["--shape", "star", "--size-mm", "500"]) == 2
    assert "--size-mm" in capsys.readouterr().err


@pytest.mark.slow
def test_the_star_is_painted_and_reported(tmp_path):
    report, image = tmp_path / "star.json", tmp_path / "star.png"
    assert light_paint.main(["--shape", "star", "--size-mm", "120", "--headless", "--json",
                             str(report), "--image", str(image)]) == 0
    exposure = json.loads(report.read_text())["exposure"]
    assert exposure["mean_mm"] <= 2.0 and exposure["brightness_spread_pct"] <= 20.0
    assert png_ours(image)
