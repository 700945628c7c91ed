"""Messages that said the wrong thing (issue 33, "Messages that say the wrong thing"): each now
says what is true, and a fix it suggests is one the code accepts."""

from __future__ import annotations

import json
import random
from pathlib import Path

import pytest

from so101_kinematics.errors import CallShapeError, PlanError
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.planning.plans import load_plan

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "waypoints" / "example.json"


@pytest.mark.parametrize("seed", range(3))
def test_a_binary_plan_is_called_binary_not_utf16_text(tmp_path, seed):
    """Bytes that start like UTF-16's byte-order mark are not UTF-16 text for that."""
    path = tmp_path / "plan.json"
    path.write_bytes(b"\xff\xfe" + random.Random(seed).randbytes(300))
    with pytest.raises(PlanError) as error:
        load_plan(path)
    assert "is UTF-16 text" not in str(error.value)
    assert "is not text but binary data" in str(error.value)


def test_a_utf16_plan_is_still_called_utf16(tmp_path):
    path = tmp_path / "plan.json"
    path.write_bytes(EXAMPLE.read_text().encode("utf-16"))
    with pytest.raises(PlanError, match="is UTF-16 text, not UTF-8. Fix: save it as UTF-8."):
        load_plan(path)


def test_a_list_configuration_is_named_a_list_with_the_table_fix(tmp_path):
    data = json.loads(EXAMPLE.read_text())
    data["steps"][0]["configuration"] = list(data["steps"][0]["configuration"].values())
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(data))
    with pytest.raises(PlanError) as error:
        load_plan(path)
    message = str(error.value)
    assert "'configuration' is a list of 6 values; a plan names each joint" in message
    assert "needs a 'configuration' table" not in message
    del data["steps"][0]["configuration"]
    path.write_text(json.dumps(data))
    with pytest.raises(PlanError, match="needs a 'configuration' table"):
        load_plan(path)


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_a_non_finite_target_is_not_told_to_be_at_least_minus_infinity(capsys, value):
    import test_ik_mujoco

    code = test_ik_mujoco.main(["--target", value, "0.1", "0", "--headless"])
    err = capsys.readouterr().err
    assert code == 2 and "-inf" not in err.replace(f"'{value}'", "")
    assert f"'{value}' is not a finite number. Fix: give a finite number." in err


def test_one_number_too_many_is_a_call_shape_not_a_bad_target():
    import mujoco

    from so101_mujoco_utils import load_model, move_to_pose

    m = load_model()
    d = mujoco.MjData(m)
    cfg = dict.fromkeys(("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex",
                         "wrist_roll"), 0.0) | {"gripper": 50.0}
    with pytest.raises(CallShapeError) as error:
        move_to_pose(m, d, None, cfg, 1.0, 5)
    message = str(error.value)
    assert message.startswith("move_to_pose got a configuration, then 1 and 5")
    assert "target must be a dict" not in message


@pytest.mark.parametrize("given", ["up", "side", "down", "pitch"])
def test_the_approach_hint_suggests_only_an_approach_that_is_accepted(given):
    from so101_inverse_kinematics import get_inverse_kinematics
    from so101_kinematics.errors import KinematicsInputError

    with pytest.raises(KinematicsInputError) as error:
        get_inverse_kinematics([0.2, 0.0, 0.05], given)
    fix = str(error.value).split("Fix: ")[1]
    if given in ("down", "pitch"):
        assert fix == f"pass the approach by keyword: approach={given!r}."
        get_inverse_kinematics([0.2, 0.0, 0.05], approach=given,
                               **({"pitch_deg": 90.0} if given == "pitch" else {}))
    else:
        assert f"approach={given!r}" not in fix and "approach='down'" in fix


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_raw_ticks_refused_after_a_move_do_not_claim_nothing_moved(course_arm, capsys):
    """The arm moved before the refused write: the refusal says that write moved nothing, and
    the run's ending (back at the start, torque off) follows at the script's exit."""
    import so101_kinematics.hw.course_helpers as course
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(REPO / "calibration" / "virtual_so101.json")),
                       course_arm.port)
    pose = bus.sync_read("Present_Position")
    move_to_pose(bus, dict(pose, wrist_roll=pose["wrist_roll"] + 20.0), 0.5)  # a short move
    with pytest.raises(ScriptEnded) as ended:
        bus.sync_write("Goal_Position", {"shoulder_pan": 2047}, normalize=False)
    assert ended.value.code == 2
    assert "nothing moved" not in ended.value.line
    assert ended.value.line.startswith("Refused (this write; it moved nothing): ")
    capsys.readouterr()
    course._end_forgotten_runs()  # what the script's exit runs
    last = capsys.readouterr().out.strip().splitlines()[-1].lower()
    assert "back at the starting pose" in last and "torque off" in last


@pytest.mark.parametrize("script", ["pick_place_sim", "pick_place_hw"])
@pytest.mark.parametrize("options", [["--move-duration", "3"], ["--hold", "0.5"],
                                     ["--hold", "1", "--move-duration", "2"]])
def test_timing_options_given_with_a_plan_are_refused_not_ignored(capsys, script, options):
    """A plan's waypoints carry their own duration and hold: --move-duration and --hold (even
    at their default values) did nothing with --plan, silently."""
    import importlib

    main = importlib.import_module(script).main
    extra = ["--headless"] if script == "pick_place_sim" else ["--dry-run"]
    code = main([*extra, "--plan", str(EXAMPLE), *options])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    for option in options[::2]:
        assert f"{option}" in err
    assert "Fix: leave out --" in err and "in the plan file" in err


def test_timing_options_without_a_plan_still_time_the_built_in_plan(capsys):
    from pick_place_hw import main

    assert main(["--dry-run", "--move-duration", "3", "--hold", "0"]) == 0
    carry = next(line for line in capsys.readouterr().out.splitlines() if " carry " in line)
    assert carry.split()[2:4] == ["3.00", "0.00"]  # move [s], hold [s]


def test_the_feedforward_line_gives_the_offsets_at_the_arms_pose_and_says_so(caplog):
    """It printed the all-zero pose's offsets (the arm stretched up) as if they were the arm's."""
    import logging

    from hw_fakes import FakeBus

    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.constants import HOME_POSE
    from so101_kinematics.frames import ARM_JOINTS
    from so101_kinematics.hw.feedforward import read_feedforward

    pose = dict(HOME_POSE)  # the folded rest, where a script starts
    bus = FakeBus(load_calibration(REPO / "calibration" / "virtual_so101.json"), pose)
    with caplog.at_level(logging.INFO, logger="so101_kinematics.hw.feedforward"):
        feedforward = read_feedforward(bus)
    (line,) = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
    assert line.endswith("; offsets at the arm's pose as read now")
    at_pose = feedforward.offsets(pose)
    at_zero = feedforward.offsets(dict.fromkeys(pose, 0.0))
    shown = {j: f"{at_pose[j]:+.1f}" for j in ARM_JOINTS if at_pose[j]}
    assert shown and all(f"{j} {v}" in line for j, v in shown.items())
    assert any(f"{at_pose[j]:+.1f}" != f"{at_zero[j]:+.1f}" for j in ARM_JOINTS)
    bus.fail_reads = 100  # a pose that cannot be read: the line says whose offsets it shows
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="so101_kinematics.hw.feedforward"):
        read_feedforward(bus)
    assert caplog.records[-1].getMessage().endswith(
        "offsets at the all-zero pose (the arm's was not read)")
