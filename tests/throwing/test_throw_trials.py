"""Seeded throws at cups 0.3-0.6 m away: issue 38's acceptance, and a picture of one."""

from __future__ import annotations

import math

import imageio.v2 as imageio
import pytest

from so101_kinematics.markers import mp4_ours, png_ours
from so101_kinematics.throwing.ball import BALLS
from so101_kinematics.throwing.throw_scene import build_throw_model
from so101_kinematics.throwing.throw_trials import (
    AZIMUTH_RANGE_DEG,
    cup_positions,
    run_throws,
    save_picture,
    save_video,
)

BALL = BALLS["pingpong"]


def test_the_cups_are_seeded_and_between_0_3_and_0_6_m():
    cups = cup_positions(50, 7)
    assert cups == cup_positions(50, 7) and cups != cup_positions(50, 8)
    for x, y in cups:
        assert 0.3 <= math.hypot(x, y) <= 0.6
        assert AZIMUTH_RANGE_DEG[0] <= math.degrees(math.atan2(y, x)) <= AZIMUTH_RANGE_DEG[1]


@pytest.mark.slow
def test_eight_of_ten_throws_land_in_the_cup_and_the_model_within_3_cm_of_each():
    m = build_throw_model(BALL)
    report = run_throws(m, BALL, cup_positions(10, 0))
    assert report["hits"] >= 8, report
    assert all(t["model_error_m"] < 0.03 for t in report["trials"]), report


def test_a_picture_of_a_throw_is_ours(tmp_path):
    m = build_throw_model(BALL)
    path = tmp_path / "throw.png"
    trial = save_picture(path, m, BALL, (0.35, 0.05))
    assert png_ours(path) and trial["in_cup"]


def test_a_video_of_a_throw_is_ours_and_plays_in_real_time(tmp_path):
    m = build_throw_model(BALL)
    path = tmp_path / "throw.mp4"
    trial = save_video(path, m, BALL, (0.35, 0.05))
    assert mp4_ours(path)
    frames = imageio.get_reader(str(path)).count_frames()
    # from the wind-up to AFTER_TOUCH_S after the first touch, at 30 frames/s
    assert frames >= 30 * (trial["release_s"] + trial["flight_s"])
