"""draw.py: the TA's command, its report and picture, and the one-line refusals (exit 2)."""

from __future__ import annotations

import json

import pytest

import draw
from so101_kinematics.markers import png_ours


def _refused(capsys, *argv) -> str:
    assert draw.main(list(argv)) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "Fix:" in lines[0]
    return lines[0]


def test_an_empty_text_is_refused(capsys):
    assert "--text is empty" in _refused(capsys, "--text", "", "--headless")


def test_an_unknown_glyph_is_refused(capsys):
    assert "no glyph for 'ß', 'ü'" in _refused(capsys, "--text", "Grüße", "--headless")


def test_an_svg_without_paths_is_refused(capsys, tmp_path):
    picture = tmp_path / "empty.svg"
    picture.write_text('<svg xmlns="http://www.w3.org/2000/svg"></svg>')
    assert "no path" in _refused(capsys, "--svg", str(picture), "--headless")


def test_a_page_out_of_reach_is_refused_naming_the_strokes(capsys):
    line = _refused(capsys, "--shape", "square", "--height-mm", "40", "--page-at", "0.42", "0")
    assert "fall outside the arm's reach" in line and "by up to" in line


def test_a_speed_out_of_range_is_refused(capsys):
    assert "--speed-mm-s" in _refused(capsys, "--shape", "star", "--speed-mm-s", "5000")


def test_a_speed_the_servos_cannot_hold_is_refused_with_one_that_can(capsys):
    line = _refused(capsys, "--shape", "star", "--height-mm", "100", "--speed-mm-s", "900")
    assert "no-load speed" in line
    fits = float(line.split("Fix: --speed-mm-s ")[1].split()[0])
    assert draw.main(["--shape", "star", "--height-mm", "100", "--speed-mm-s", f"{fits:g}"]) == 0


def test_the_image_must_be_a_png(capsys, tmp_path):
    assert "must end in .png" in _refused(capsys, "--shape", "star", "--image",
                                          str(tmp_path / "x.jpg"))


@pytest.mark.slow
def test_a_small_star_is_drawn_and_reported(tmp_path, capsys):
    report, image = tmp_path / "star.json", tmp_path / "star.png"
    assert draw.main(["--shape", "star", "--height-mm", "20", "--speed-mm-s", "25",
                      "--headless", "--json", str(report), "--image", str(image)]) == 0
    data = json.loads(report.read_text())
    assert {"mean_mm", "worst_mm", "stray_mm", "coverage_pct"} <= set(data["ink"])
    assert data["ink"]["mean_mm"] < 1.5
    assert png_ours(image)
    assert "Drew 1 stroke (" in capsys.readouterr().out


def test_an_image_with_the_port_is_refused(capsys):
    assert "--image with --port" in _refused(capsys, "--shape", "star", "--port", "/dev/null",
                                             "--image", "x.png")


@pytest.mark.slow
def test_an_svg_picture_is_drawn(tmp_path):
    picture = tmp_path / "smile.svg"  # a face: a circle, two eyes (short lines), a smile (an arc)
    picture.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100">'
                       '<circle cx="50" cy="50" r="40"/><path d="M 35 35 L 35 45"/>'
                       '<path d="M 65 35 L 65 45"/><path d="M 30 60 A 20 20 0 0 0 70 60"/>'
                       '</svg>')
    report = tmp_path / "smile.json"
    assert draw.main(["--svg", str(picture), "--height-mm", "40", "--json", str(report)]) == 0
    figures = json.loads(report.read_text())
    assert figures["strokes"] == 4 and figures["source"] == {"svg": str(picture)}
    assert figures["ink"]["mean_mm"] <= 1.5 and figures["ink"]["worst_mm"] <= 3.0
