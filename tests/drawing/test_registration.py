"""The page's pose from touched marks: the rigid fit, its residual and its refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import draw
import register_page
from so101_kinematics.drawing.page import PAGES, Page, page_to_base
from so101_kinematics.drawing.registration import (
    check_fit,
    fit_page,
    page_marks,
    read_page_pose,
)
from so101_kinematics.errors import PlanError

TRUE_PAGE = Page("a5", PAGES["a5"], (0.215, 0.032), 12.5)  # [m], [deg]: turned and moved


def touches(page: Page, count: int = 4, noise_mm: float = 0.0, seed: int = 7) -> np.ndarray:
    """Where a tip on each mark of ``page`` is (x, y) [m], with seeded touch noise."""
    marks = page_marks(page.name, count)
    noise = np.random.default_rng(seed).normal(0.0, noise_mm / 1000.0, (count, 2))
    return page_to_base(page, marks)[:, :2] + noise


def test_marks_are_10_mm_in_from_the_corners_counter_clockwise_from_the_bottom_left():
    # A5 landscape is 210 x 148 mm: the corners at (+-105, +-74)
    assert page_marks("a5").tolist() == [[-95, -64], [95, -64], [95, 64], [-95, 64]]


def test_exact_touches_give_the_page_back():
    fit = fit_page(page_marks("a5"), touches(TRUE_PAGE))
    assert fit.centre == pytest.approx(TRUE_PAGE.centre, abs=1e-12)
    assert fit.yaw == pytest.approx(12.5, abs=1e-9) and fit.rms_mm < 1e-9


@pytest.mark.parametrize("yaw", [-170.0, -90.0, 0.0, 45.0, 179.0])
def test_any_turn_of_the_page_is_found(yaw):
    page = Page("a4", PAGES["a4"], (0.18, -0.05), yaw)
    fit = fit_page(page_marks("a4", 3), touches(page, 3), "a4")
    assert math.isclose(math.remainder(fit.yaw - yaw, 360.0), 0.0, abs_tol=1e-9)
    assert fit.centre == pytest.approx(page.centre, abs=1e-12)


def test_noisy_touches_fit_within_the_noise_and_report_it():
    # a tip put on a cross by eye: 0.5 mm standard deviation per axis
    touched = touches(TRUE_PAGE, noise_mm=0.5)
    fit = fit_page(page_marks("a5"), touched)
    # 4 points, 3 parameters: the RMS residual is below the touch error (0.5 * sqrt(2))
    assert 0.1 < fit.rms_mm < 0.71 and len(fit.residuals_mm) == 4
    assert np.hypot(*np.subtract(fit.centre, TRUE_PAGE.centre)) < 0.5e-3  # [m]
    assert abs(fit.yaw - 12.5) < 0.5  # [deg]: 0.5 mm over 190 mm is 0.15 deg
    check_fit(fit, page_marks("a5"), touched)  # accepted


def test_touches_in_the_wrong_order_are_refused_with_the_order_that_fits():
    touched = touches(TRUE_PAGE, noise_mm=0.3)[[0, 3, 2, 1]]  # clockwise: left side first
    marks = page_marks("a5")
    fit = fit_page(marks, touched)
    assert fit.rms_mm > 20.0
    with pytest.raises(PlanError) as refused:
        check_fit(fit, marks, touched)
    message = str(refused.value)
    assert "wrong order" in message and "bottom-right as touch 4" in message
    assert "\n" not in message and "Fix:" in message


def test_a_page_moved_between_touches_is_refused_as_moved():
    touched = touches(TRUE_PAGE)
    touched[2] += (0.006, 0.0)  # the page slid 6 mm before the third touch
    fit = fit_page(page_marks("a5"), touched)
    with pytest.raises(PlanError, match=r"page moved between touches.*Fix:"):
        check_fit(fit, page_marks("a5"), touched)


def write_points(path, points) -> str:
    path.write_text(json.dumps({"points_m": np.asarray(points).tolist()}))
    return str(path)


def test_register_page_prints_each_residual_and_writes_the_pose_draw_reads(tmp_path, capsys):
    points = write_points(tmp_path / "points.json", touches(TRUE_PAGE, noise_mm=0.3))
    pose = tmp_path / "page.json"
    assert register_page.main(["--points", points, "--out", str(pose)]) == 0
    out = capsys.readouterr().out
    assert out.count("residual") == 5 and "mark 4 (top-left)" in out and "RMS residual" in out
    page = read_page_pose(pose)
    assert page.centre == pytest.approx(TRUE_PAGE.centre, abs=1e-3)
    assert page.yaw == pytest.approx(12.5, abs=0.3)


def test_register_page_refuses_a_bad_fit_in_one_line_and_writes_nothing(tmp_path, capsys):
    points = write_points(tmp_path / "points.json", touches(TRUE_PAGE)[[1, 0, 2, 3]])
    pose = tmp_path / "page.json"
    assert register_page.main(["--points", points, "--out", str(pose)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "wrong order" in err and not pose.exists()


@pytest.mark.parametrize("content, expected", [
    ('{"points_m": [[0.1, 0.2], [0.3, 0.1]]}', "not 3 or 4 touched points"),
    ("not json", "not 3 or 4 touched points"),
])
def test_register_page_refuses_a_bad_points_file(tmp_path, capsys, content, expected):
    points = tmp_path / "points.json"
    points.write_text(content)
    assert register_page.main(["--points", str(points), "--out", str(tmp_path / "p.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and expected in err


def test_draw_takes_the_page_from_the_pose_file(tmp_path, capsys):
    # a page registered 0.42 m out: draw.py's reach check names that centre, from the file
    far = Page("a5", PAGES["a5"], (0.42, 0.0), 0.0)
    points = write_points(tmp_path / "points.json", touches(far))
    pose = tmp_path / "page.json"
    assert register_page.main(["--points", points, "--out", str(pose)]) == 0
    capsys.readouterr()
    assert draw.main(["--shape", "square", "--height-mm", "20", "--page-pose", str(pose),
                      "--headless"]) == 2
    assert "page centre at (0.420, 0.000) m" in capsys.readouterr().err


def test_draw_refuses_a_pose_file_beside_a_page_option(tmp_path, capsys):
    assert draw.main(["--shape", "square", "--page-pose", str(tmp_path / "x.json"),
                      "--page-at", "0.2", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--page-pose with --page-at" in err
