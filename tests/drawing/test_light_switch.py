"""The torch's switch pressed by the gripper: on/off times, the led and capped goals."""

from __future__ import annotations

import numpy as np
import pytest

import light_paint
from so101_kinematics.drawing.light_switch import TorchSwitch, gripper_goals, switch_times
from so101_kinematics.errors import PlanError

DT = 0.01  # [s]: the arm's control period
CAP = 100.0  # [%/s]: the hardware path's gripper speed cap (hw/timing.py)


def lit_between(on: int, off: int, n: int = 80) -> np.ndarray:
    lit = np.zeros(n, dtype=bool)
    lit[on:off] = True
    return lit


def test_switch_times_are_each_lit_stretchs_first_and_after_last_sample():
    lit = lit_between(10, 30) | lit_between(50, 60)
    assert switch_times(lit, DT) == [(0.1, 0.3), (0.5, 0.6)]
    assert switch_times(np.zeros(5, dtype=bool), DT) == []


def test_the_press_starts_its_lead_before_the_light_and_the_release_its_own():
    switch = TorchSwitch(30.0, 24.0, 20.0, lead_on_s=0.1, lead_off_s=0.05)
    goals = gripper_goals(lit_between(40, 60), DT, switch, CAP)
    moving = np.flatnonzero(np.diff(goals) != 0.0) + 1
    # the press: 10 samples (0.1 s) before sample 40; the release 5 (0.05 s) before 60
    assert moving[0] == 30 and goals[29] == 30.0
    assert goals[54] == pytest.approx(20.0) and goals[55] > 20.0
    assert goals[-1] == pytest.approx(30.0) and goals.min() == pytest.approx(20.0)


def test_the_gripper_goal_never_moves_faster_than_its_cap():
    goals = gripper_goals(lit_between(5, 12), DT, TorchSwitch(), CAP)
    assert np.abs(np.diff(goals)).max() <= CAP * DT  # 1 % a cycle: no step is stretched


def test_a_switch_whose_press_opens_the_jaw_is_refused_in_one_line():
    with pytest.raises(PlanError, match=r"released > click > pressed.*Fix:"):
        TorchSwitch(20.0, 24.0, 30.0).check()


@pytest.mark.parametrize("options, expected", [
    (["--port", "/dev/null", "--switch-gripper", "20", "24", "30"], "released > click"),
    (["--port", "/dev/null", "--image", "x.png"], "--image with --port"),
])
def test_light_paint_refuses_a_bad_arm_option_in_one_line(tmp_path, capsys, monkeypatch,
                                                          options, expected):
    monkeypatch.chdir(tmp_path)
    assert light_paint.main(["--shape", "square", "--size-mm", "40", *options]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and expected in err
