"""Trims (the course's offset_config) and the home check: the file, the limit, the wire, the log.

The wire tests run pick_place_hw.py against the virtual SO-101, whose
calibration is exact: a trim there moves the simulated joint by the trim,
which is how it shows that the goal on the wire was command + trim.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from so101_forward_kinematics import ARM_JOINTS, JOINTS
from so101_kinematics.calibration import load_calibration, ticks_to_user
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.errors import TrimError
from so101_kinematics.gravity import feedforward
from so101_kinematics.hw import feedforward as hw_feedforward
from so101_kinematics.servo import LEROBOT
from so101_kinematics.trims import TRIM_LIMIT_DEG, Trims, as_trims, load_trims

REPO = Path(__file__).resolve().parents[2]
CALIBRATION_PATH = REPO / "calibration" / "virtual_so101.json"
HOME = HOME_POSE
TRIMS = {"shoulder_lift": 2.0, "elbow_flex": -4.0}  # the course's example: +2 and -4 deg


# --- the trims themselves -------------------------------------------------------------
def test_a_trim_is_added_to_the_goal_and_taken_off_the_reading():
    trims = Trims(TRIMS)
    command = dict(HOME)
    wire = trims.to_wire(command)
    assert wire["shoulder_lift"] == HOME["shoulder_lift"] + 2.0
    assert wire["elbow_flex"] == HOME["elbow_flex"] - 4.0
    assert wire["wrist_flex"] == HOME["wrist_flex"]
    assert trims.from_wire(wire) == pytest.approx(command)
    limits = trims.limits({"elbow_flex": (-90.0, 90.0)})
    assert limits["elbow_flex"] == (-86.0, 94.0)  # the goal (command - 4) stays in [-90, 90]


@pytest.mark.parametrize("suffix, text", [
    (".json", '{"shoulder_lift": 2.0, "elbow_flex": -4.0}'),
    (".toml", "shoulder_lift = 2.0\nelbow_flex = -4\n"),
])
def test_a_trim_file_is_json_or_toml_joint_to_degrees(tmp_path, suffix, text):
    path = tmp_path / f"trims{suffix}"
    path.write_text(text)
    trims = load_trims(path)
    assert trims.offsets == dict(dict.fromkeys(JOINTS, 0.0), **TRIMS)
    assert trims.describe() == "shoulder_lift +2.0 deg, elbow_flex -4.0 deg"


def test_the_course_offset_config_function_gives_the_same_trims():
    def offset_config(config):  # written as the course's helper is
        offset_dict = config.copy()
        offset_dict["shoulder_lift"] += 2.0
        offset_dict["elbow_flex"] -= 4.0
        return offset_dict

    assert as_trims(offset_config).offsets == Trims(TRIMS).offsets
    with pytest.raises(TrimError, match="constant offset"):
        as_trims(lambda config: {j: 2.0 * v for j, v in config.items()})


@pytest.mark.parametrize("trims, words", [
    ({"elbow_flex": 6.0}, ["elbow_flex = 6 deg", "beyond the 5 deg", "recalibrate"]),
    ({"gripper": -5.5}, ["gripper = -5.5 %", "beyond the 5 %"]),
    ({"elbow": 1.0}, ["unknown joint 'elbow'", "shoulder_pan, shoulder_lift"]),
    ({"elbow_flex": "2"}, ["elbow_flex must be a finite number", "'2'"]),
    ({"elbow_flex": float("nan")}, ["elbow_flex must be a finite number"]),
    ([2.0, -4.0], ["must map joint names"]),
])
def test_a_bad_trim_is_refused_naming_joint_value_and_fix(trims, words):
    with pytest.raises(TrimError) as refused:
        Trims(trims)
    message = str(refused.value)
    assert all(word in message for word in words), message
    assert "Fix:" in message and "\n" not in message


def test_the_limit_is_exactly_five_degrees():
    assert TRIM_LIMIT_DEG == 5.0
    assert Trims({"shoulder_pan": -5.0}).offsets["shoulder_pan"] == -5.0
    with pytest.raises(TrimError):
        Trims({"shoulder_pan": 5.01})


def test_pick_place_hw_refuses_a_big_trim_before_the_port_in_one_line(tmp_path, capsys):
    import pick_place_hw as cli

    trims = tmp_path / "trims.json"
    trims.write_text(json.dumps({"shoulder_lift": 8.0}))
    rc = cli.main(["--port", str(tmp_path / "no-such-port"), "--calibration",
                   str(CALIBRATION_PATH), "--yes", "--trims", str(trims)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert err[-1].startswith("Refused, nothing moved: Trim file")
    assert "shoulder_lift = 8 deg is beyond the 5 deg" in err[-1] and "recalibrate" in err[-1]



@pytest.mark.parametrize("name, text, words", [
    (None, None, "No such file"),  # the file is missing
    ("trims.json", '{"shoulder_lfit": 2.0}', "unknown joint 'shoulder_lfit'"),
    ("trims.json", '{"shoulder_lift": 8.0}', "shoulder_lift = 8 deg is beyond the 5 deg"),
])
def test_the_dry_run_checks_the_trims_as_the_real_run(tmp_path, capsys, name, text, words):
    """Issue 28: --dry-run ignored --trims, so a bad trim file failed only on lab day."""
    import pick_place_hw as cli

    trims = tmp_path / (name or "no_such_trims.json")
    if text is not None:
        trims.write_text(text)
    rc = cli.main(["--dry-run", "--calibration", str(CALIBRATION_PATH), "--trims", str(trims)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert err[-1].startswith("Refused, nothing moved:") and words in err[-1]
    assert "Fix:" in err[-1] or "recalibrate" in err[-1]


def test_the_dry_run_checks_the_plan_against_the_trimmed_limits(tmp_path, capsys):
    """A trim moves the servo's range: the plan must fit the calibration minus the trim."""
    import pick_place_hw as cli

    trims = tmp_path / "trims.json"
    trims.write_text('{"shoulder_lift": 2.0}')
    assert cli.main(["--dry-run", "--calibration", str(CALIBRATION_PATH), "--trims",
                     str(trims)]) == 0
    assert "the plan is valid" in capsys.readouterr().out

# --- on the (virtual) arm -----------------------------------------------------------------
@pytest.fixture
def arm(course_arm):
    """The virtual arm (tests/conftest.py's course_arm)."""
    return course_arm


class Sampler(threading.Thread):
    """Records (time [s], the virtual arm's joints) every 50 ms until stopped."""

    def __init__(self, arm):
        super().__init__()
        self.arm, self.samples, self.done = arm, [], threading.Event()

    def run(self):
        while not self.done.is_set():
            self.samples.append((time.monotonic(), self.arm.joint_positions()))
            time.sleep(0.05)

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.done.set()
        self.join()


PLAN = {"steps": [{"name": "pick", "configuration": dict(HOME, shoulder_lift=-40.0,
                                                          elbow_flex=50.0), "duration": 1.5,
                   "hold": 0.5}], "return_duration": 1.5}


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_trims_reach_the_wire_the_log_and_the_report(arm, tmp_path, capsys):
    import pick_place_hw as cli
    from so101_kinematics.lab.sim_vs_arm import compare_run

    (tmp_path / "plan.json").write_text(json.dumps(PLAN))
    (tmp_path / "trims.json").write_text(json.dumps(TRIMS))
    with Sampler(arm) as sampler:
        rc = cli.main(["--port", arm.port, "--calibration", str(CALIBRATION_PATH), "--yes",
                       "--plan", str(tmp_path / "plan.json"), "--trims",
                       str(tmp_path / "trims.json"), "--log", str(tmp_path / "run.csv")])
    assert rc == 0, capsys.readouterr().err
    assert not any(arm.torque_enabled().values())

    # the wire: every goal after the in-place ones is the cycle's command plus its trim
    lines = (tmp_path / "run.csv").read_text().splitlines()
    header, rows = lines[0].split(","), [dict(zip(lines[0].split(","), r.split(","),
                                                  strict=True)) for r in lines[1:]]
    calibration = load_calibration(CALIBRATION_PATH)
    joint_of = {c.id: j for j, c in calibration.items()}
    # the first six: the present position, written before torque on; then the feed-forward's
    # ramp back to where the arm stood
    ramp = round(hw_feedforward.RAMP_S / hw_feedforward.RAMP_PERIOD_S)
    goals = arm.goal_log()[6 * (1 + ramp):]
    assert len(goals) == 6 * len(rows)
    for k, row in enumerate(rows):
        command = {j: float(row[f"cmd_{j}"]) for j in JOINTS}
        sag = feedforward(command, LEROBOT, 5.0)  # the gravity feed-forward's offsets (default)
        for _, servo, ticks in goals[6 * k:6 * k + 6]:
            joint = joint_of[servo]
            sent = ticks_to_user(joint, ticks, calibration[joint])
            expected = command[joint] + TRIMS.get(joint, 0.0) + sag[joint]
            # 1 tick = 0.088 deg; the friction term (0.5 deg at P = 16 on 5 V) in the motion's
            # direction; the supply the servos report (under 5 V with the arm's current) and
            # the offsets' re-evaluation every degree of motion. A trim left out is 2-4 deg.
            assert abs(sent - expected) <= 1.5, (k, joint, sent, expected)

    # the arm: the exact virtual arm stood at the waypoint plus the trims; the log at the waypoint
    waypoint = PLAN["steps"][0]["configuration"]
    trimmed = Trims(TRIMS).to_wire(waypoint)
    assert any(all(abs(s[j] - trimmed[j]) < 1.0 for j in ARM_JOINTS) for _, s in sampler.samples)
    at_pick = [r for r in rows if r["step"] == "pick"][-1]
    assert abs(float(at_pick["meas_elbow_flex"]) - waypoint["elbow_flex"]) < 1.0
    assert [float(at_pick[f"trim_{j}"]) for j in JOINTS] == [TRIMS.get(j, 0.0) for j in JOINTS]
    assert [h for h in header if h.startswith("trim_")] == [f"trim_{j}" for j in JOINTS]

    # the sim-vs-arm report says which trims the run had
    report = compare_run(tmp_path / "run.csv")
    assert report.trims_deg == {j: TRIMS.get(j, 0.0) for j in JOINTS}
    assert report.as_json()["trims_deg"]["elbow_flex"] == -4.0
    assert "trims (added to every goal sent to the arm): shoulder_lift +2.0 deg, elbow_flex " \
           "-4.0 deg" in report.summary()


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_so101_utils_takes_the_course_offset_config(arm, capsys):
    from so101_utils import load_calibration as course_load
    from so101_utils import move_to_pose, setup_motors

    bus = setup_motors(course_load(str(CALIBRATION_PATH)), arm.port, offset_config=TRIMS)
    target = dict(HOME, shoulder_lift=-40.0, elbow_flex=50.0)
    move_to_pose(bus, target, 1.5)
    time.sleep(0.2)  # the servos hold their goals by themselves
    reached = arm.joint_positions()
    for joint in ARM_JOINTS:
        assert abs(reached[joint] - target[joint] - TRIMS.get(joint, 0.0)) < 1.0, joint
    bus.disable_torque()
    assert not any(arm.torque_enabled().values())
    bus.disconnect(disable_torque=False)


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_home_check_goes_home_slowly_prints_the_fk_and_ends_released(arm, monkeypatch,
                                                                     capsys):
    import mujoco

    import pick_place_hw as cli
    import so101_kinematics.hw.home_check as home_check
    import so101_mujoco_utils as mu

    monkeypatch.setattr(home_check, "HOME_CHECK_HOLD_S", 1.0)
    monkeypatch.setattr(home_check, "HOME_CHECK_MOVE_S", 1.0)  # too fast: the speed cap slows it
    with Sampler(arm) as sampler:
        rc = cli.main(["--port", arm.port, "--calibration", str(CALIBRATION_PATH), "--yes",
                       "--home-check"])
    samples = sampler.samples
    out = capsys.readouterr().out
    assert rc == 0

    # the model's own object frame at the all-zero configuration, printed to 0.1 mm
    m = mu.load_model()
    d = mujoco.MjData(m)
    mu.set_initial_pose(d, dict.fromkeys(JOINTS, 0.0))
    mujoco.mj_forward(m, d)
    site = d.site("object_frame").xpos * 1000.0
    assert f"at x, y, z = {site[0]:.1f}, {site[1]:.1f}, {site[2]:.1f} mm" in out
    assert "The measured joints put the object frame at x, y, z =" in out

    # the arm was there, and came back slowly
    at_home = [s for _, s in samples if all(abs(s[j]) < 1.5 for j in ARM_JOINTS)]
    assert at_home, "the arm never reached the all-zero configuration"
    t = np.array([t for t, _ in samples])
    q = np.array([[s[j] for j in ARM_JOINTS] for _, s in samples])
    speeds = np.abs(q[4:] - q[:-4]) / (t[4:] - t[:-4])[:, None]  # over about 0.2 s [deg/s]
    assert speeds.max() < 1.5 * home_check.HOME_CHECK_SPEED_DEG_S  # the default cap is 100
    assert out.strip().splitlines()[-1] == "Done: back at the starting pose, torque off."
    assert not any(arm.torque_enabled().values())
    # the last goal: HOME plus the gravity feed-forward's offsets there (elbow about -4 deg)
    home_goal = {j: HOME[j] + v for j, v in feedforward(HOME, LEROBOT, 5.0).items()}
    assert all(abs(arm.commanded_positions()[j] - home_goal[j]) < 2.0 for j in ARM_JOINTS)
