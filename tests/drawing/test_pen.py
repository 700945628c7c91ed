"""The pen's IK: its tip on the point, at the tilt, the wrist's roll held; checked by the FK."""

from __future__ import annotations

import math

import numpy as np
import pytest

from so101_kinematics.drawing.pen import (
    PEN_TIP_BELOW_CENTRE,
    PenPose,
    pen_configuration,
    pen_residual,
    tip_position,
)
from so101_kinematics.errors import UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import ARM_JOINTS


def _tip_and_tilt(cfg):
    """The tip and the pen's tilt from the course's FK (not the module's own chain)."""
    position, rotation = forward_kinematics(cfg)
    approach = -rotation[:, 2]
    tip = position + PEN_TIP_BELOW_CENTRE * approach
    pan = math.radians(cfg["shoulder_pan"])
    outwards = approach @ [math.cos(pan), -math.sin(pan), 0.0]
    return tip, math.degrees(math.atan2(outwards, -approach[2]))


@pytest.mark.parametrize("tip", [(0.2, 0.0, 0.0), (0.25, 0.08, -0.0015), (0.15, -0.1, 0.008)])
@pytest.mark.parametrize("tilt", [0.0, 20.0])
def test_the_tip_is_on_the_point_at_the_tilt(tip, tilt):
    cfg = pen_configuration(tip, PenPose(tilt_deg=tilt, roll_deg=10.0))
    reached, leaning = _tip_and_tilt(cfg)
    assert reached == pytest.approx(tip, abs=1e-6)
    assert leaning == pytest.approx(tilt, abs=1e-4)
    assert cfg["wrist_roll"] == pytest.approx(10.0, abs=1e-4)
    assert tip_position(cfg) == pytest.approx(reached, abs=1e-9)


def test_the_jacobian_is_the_residuals_derivative():
    rng = np.random.default_rng(7)
    pose = PenPose(tilt_deg=15.0)
    cfg = pen_configuration((0.22, 0.05, 0.0), pose)
    theta = np.radians([cfg[j] for j in ARM_JOINTS]) + rng.normal(0.0, 0.05, 5)
    _, jac = pen_residual(theta, (0.2, 0.0, 0.0), pose)
    numeric = np.empty((5, 5))
    for j in range(5):
        step = np.zeros(5)
        step[j] = 1e-6
        plus, _ = pen_residual(theta + step, (0.2, 0.0, 0.0), pose)
        minus, _ = pen_residual(theta - step, (0.2, 0.0, 0.0), pose)
        numeric[:, j] = -(plus - minus) / 2e-6  # the residual is wanted - actual
    assert jac == pytest.approx(numeric, abs=1e-6)


def test_a_point_out_of_reach_is_refused():
    with pytest.raises(UnreachableError):
        pen_configuration((0.6, 0.0, 0.0), PenPose())
