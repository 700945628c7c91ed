"""The forward model: a ball's flight under gravity and quadratic drag, by hand calculations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from so101_kinematics.throwing.ball import BALLS, FALL_ACCELERATION, flight, landing_point

PINGPONG = BALLS["pingpong"]


def test_a_pingpong_ball_is_the_ittf_ball():
    assert PINGPONG.diameter == pytest.approx(0.040) and PINGPONG.mass == pytest.approx(0.0027)


def test_the_drag_constant_is_rho_cd_area_over_twice_the_mass():
    # 1.204 kg/m^3 x 0.47 x pi (0.02 m)^2 / (2 x 0.0027 kg) = 0.13169 1/m
    assert PINGPONG.drag_per_speed_squared == pytest.approx(0.13169, rel=1e-4)
    force = PINGPONG.drag_force([2.5, 0.0, 0.0])  # [N]: -m k v^2 along x
    assert force == pytest.approx([-0.0027 * 0.13169 * 6.25, 0.0, 0.0], rel=1e-4)


def test_without_drag_the_flight_is_the_parabola():
    # from 0.3 m up at 2 m/s level: t = sqrt(2 h / g), x = v t
    x, y, z, t = flight([0.0, 0.0, 0.3], [2.0, 0.0, 0.0], PINGPONG, 0.0, drag=False)[0]
    fall = math.sqrt(2 * 0.3 / FALL_ACCELERATION)
    assert (x, y, z, t) == pytest.approx((2.0 * fall, 0.0, 0.0, fall), abs=1e-6)


def test_a_ball_at_its_terminal_speed_keeps_it():
    terminal = math.sqrt(FALL_ACCELERATION / PINGPONG.drag_per_speed_squared)  # 8.63 m/s
    *_, t = flight([0.0, 0.0, 1.0], [0.0, 0.0, -terminal], PINGPONG, 0.0)[0]
    assert t == pytest.approx(1.0 / terminal, rel=1e-6)


def test_drag_shortens_a_throw_by_centimetres_at_the_projects_speeds():
    dragged = landing_point([0, 0, 0.43], [1.8, 0, 1.6], PINGPONG, 0.06)
    no_drag = flight([0, 0, 0.43], [1.8, 0, 1.6], PINGPONG, 0.06, drag=False)[0, :2]
    assert 0.03 < no_drag[0] - dragged[0] < 0.10  # a beanbag's is a tenth of that
    beanbag = BALLS["beanbag"]
    bag_loss = (flight([0, 0, 0.43], [1.8, 0, 1.6], beanbag, 0.06, drag=False)[0, 0]
                - landing_point([0, 0, 0.43], [1.8, 0, 1.6], beanbag, 0.06)[0])
    assert bag_loss < 0.15 * (no_drag[0] - dragged[0])


def test_many_starts_at_once_are_the_same_as_one_by_one():
    starts = np.array([[0.0, 0.0, 0.4], [0.1, -0.1, 0.5]])
    speeds = np.array([[1.5, 0.2, 1.0], [2.0, 0.0, 0.5]])
    together = flight(starts, speeds, PINGPONG, 0.06)
    for row, p, v in zip(together, starts, speeds, strict=True):
        assert row == pytest.approx(flight(p, v, PINGPONG, 0.06)[0])


def test_a_ball_that_never_comes_down_has_no_landing():
    assert np.isnan(flight([0, 0, 0.0], [1, 0, 1], PINGPONG, 0.06)).all()  # starts below
    assert np.isnan(flight([0, 0, 0.3], [0, 0, 60.0], PINGPONG, 0.06)).all()  # over 2 s up
