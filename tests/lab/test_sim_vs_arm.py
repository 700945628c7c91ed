"""so101 compare: a hardware log replayed in the simulator (the virtual arm's run)."""

from __future__ import annotations

import csv
import json
import shutil
import time

import numpy as np
import pytest

import pick_place_hw
from so101_forward_kinematics import get_forward_kinematics
from so101_kinematics.commands import so101_command
from so101_kinematics.frames import ARM_JOINTS
from so101_kinematics.hw.log import sidecar_path
from so101_kinematics.planning.plans import FINAL_CONFIGURATION, STARTING_CONFIGURATION
from so101_kinematics.servo import KIT_SUPPLY_V

pytestmark = [pytest.mark.hw, pytest.mark.slow]
OFFSET_DEG = 3.0


def logged_run(folder, *options: str):
    """The course's plan, shortened, run on a fresh virtual arm with --log: the log's path."""
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    log = folder / "run.csv"
    # the kit's 5 V C001 arm: the figures below (friction band, the report's servo) are its
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=KIT_SUPPLY_V) as arm:
        assert pick_place_hw.main(["--port", arm.port, "--calibration",
                                   str(DEFAULT_CALIBRATION_PATH), "--yes", "--move-duration",
                                   "0.8", "--hold", "0.2", *options, "--log", str(log)]) == 0
    return log


@pytest.fixture(scope="module")
def hw_log(tmp_path_factory):
    return logged_run(tmp_path_factory.mktemp("run"))


@pytest.fixture(scope="module")
def led_log(tmp_path_factory):
    """The same plan and arm with the velocity lead (--velocity-ff)."""
    return logged_run(tmp_path_factory.mktemp("led"), "--velocity-ff")


def compare(log, tmp_path):
    report, out = tmp_path / "report.png", tmp_path / "report.json"
    assert so101_command.main(["compare", str(log), "--report", str(report),
                               "--json", str(out)]) == 0
    assert report.read_bytes().startswith(b"\x89PNG")
    return json.loads(out.read_text())


def test_the_sidecar_holds_what_a_replay_needs(hw_log):
    info = json.loads(sidecar_path(hw_log).read_text())
    assert [s["name"] for s in info["plan"]["steps"]][2] == "start_open"
    assert set(info["start_pose"]) >= set(ARM_JOINTS) and info["rate_hz"] > 0
    with hw_log.open(newline="") as handle:  # the CSV is still plain: one header, then cycles
        header = next(csv.reader(handle))
    assert header[:3] == ["t_s", "wall_s", "step"]


def test_on_the_virtual_arm_simulator_and_arm_agree(hw_log, tmp_path):
    report = compare(hw_log, tmp_path)
    assert all(report["sim_vs_arm_rms_deg"][j] < 1.0 for j in ARM_JOINTS)
    # Both arms are the STS3215 with the feed-forward: each rests anywhere in its friction
    # band (+-0.5 deg a joint at P = 16 on 5 V), so their object frames agree to about 5 mm.
    assert report["pick_position_error_mm"] < 6.0
    assert report["place_position_error_mm"] < 6.0
    assert all(report["max_tracking_error_deg"][j] >= 0.0 for j in ARM_JOINTS)
    # the report says which servo it replayed and the sag the feed-forward took out: at the
    # pick the shoulder holds the reaching arm (gravity torque / stiffness: several degrees)
    assert report["servo"] == "STS3215 at P = 16 on 5.0 V, with the gravity feed-forward"
    assert 1.0 < abs(report["predicted_sag_deg"]["pick"]["shoulder_lift"]) < 9.0


def test_a_led_run_is_replayed_with_the_goals_the_servos_got(led_log, tmp_path):
    # With --velocity-ff each goal written leads the plan by the servo's lag (0.1 s at
    # P = 16) times the planned speed: up to 10 deg on these 0.8 s moves. Replayed without
    # its lead, the simulated arm lags the plan where the arm does not (measured 2026-12-02:
    # 2.2-4.3 deg RMS on pan, shoulder, elbow and wrist); replayed with it, 0.1-0.25 deg.
    rows = list(csv.DictReader(led_log.open(newline="")))
    assert max(abs(float(r["lead_shoulder_lift"] or 0.0)) for r in rows) > 2.0
    report = compare(led_log, tmp_path)
    assert all(report["sim_vs_arm_rms_deg"][j] < 1.0 for j in ARM_JOINTS)
    assert report["servo"].endswith("goals led by the velocity feed-forward (replayed as "
                                    "written)")


def test_the_replay_sends_each_goal_when_the_arm_got_it(hw_log, tmp_path, monkeypatch):
    # A cycle that woke late (the log's wall_s after its t_s) sent its goal late: the
    # simulator is stepped to the wake times, not the schedule.
    from so101_kinematics.lab import sim_vs_arm as compare_module

    late = tmp_path / "late.csv"
    rows, fields = read_rows(hw_log)
    for k, row in enumerate(rows):
        if row["wall_s"]:
            row["wall_s"] = f"{float(row['t_s']) + (0.05 if k % 7 == 3 else 0.0):.6f}"
    write_rows(late, rows, fields)
    shutil.copy(sidecar_path(hw_log), sidecar_path(late))
    seen = {}
    real = compare_module.replay

    def spy(t, commands, start, servo=None):
        seen["t"] = np.array(t)
        return real(t, commands, start, servo)

    monkeypatch.setattr(compare_module, "replay", spy)
    result = compare_module.compare_run(late)
    assert np.array_equal(seen["t"], result.read_s)
    assert np.max(seen["t"] - result.t) == pytest.approx(0.05)


def test_a_shoulder_pan_offset_shows_as_its_shift(hw_log, tmp_path):
    shifted = tmp_path / "shifted.csv"
    with hw_log.open(newline="") as source, shifted.open("w", newline="") as target:
        rows = list(csv.DictReader(source))
        writer = csv.DictWriter(target, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            if row["meas_shoulder_pan"]:
                row["meas_shoulder_pan"] = f"{float(row['meas_shoulder_pan']) + OFFSET_DEG:.4f}"
            writer.writerow(row)
    shutil.copy(sidecar_path(hw_log), sidecar_path(shifted))
    clean, report = compare(hw_log, tmp_path), compare(shifted, tmp_path)
    assert report["sim_vs_arm_rms_deg"]["shoulder_pan"] == pytest.approx(OFFSET_DEG, abs=0.5)
    for key, cfg in (("pick_position_error_mm", STARTING_CONFIGURATION),
                     ("place_position_error_mm", FINAL_CONFIGURATION)):
        # hand check: turning the pan by 3 deg moves the object frame by the chord
        # 2 r sin(1.5 deg), r = its distance from the pan axis (course FK)
        planned = get_forward_kinematics(cfg)[0] * 1000.0
        turned = get_forward_kinematics(dict(cfg, shoulder_pan=cfg["shoulder_pan"]
                                             + OFFSET_DEG))[0] * 1000.0
        expected = float(np.linalg.norm(turned - planned))
        assert expected > 10.0
        assert report[key] == pytest.approx(expected, abs=clean[key] + 1.0)


# --- any log the hardware script can write (issue 28, Deliver 5) ---------------------------
def write_rows(path, rows, fieldnames):
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fieldnames)
        writer.writeheader()
        writer.writerows(rows)


def read_rows(log):
    with log.open(newline="") as handle:
        reader = csv.DictReader(handle)
        return list(reader), list(reader.fieldnames)


def test_a_run_stopped_before_the_pick_is_compared(hw_log, tmp_path, capsys):
    """Ctrl-C during the first move: the log has no cycle of the pick or the place step."""
    from so101_kinematics.lab.sim_vs_arm import logged_plan
    from so101_kinematics.planning.plans import pick_and_place_steps

    info = json.loads(sidecar_path(hw_log).read_text())
    pick, _ = pick_and_place_steps(logged_plan(info["plan"]))
    rows, fields = read_rows(hw_log)
    first_pick = next(k for k, row in enumerate(rows) if row["step"] == pick.name)
    stopped = tmp_path / "stopped.csv"
    write_rows(stopped, rows[:first_pick], fields)
    shutil.copy(sidecar_path(hw_log), sidecar_path(stopped))
    report = compare(stopped, tmp_path)
    assert report["pick_position_error_mm"] is None and report["place_position_error_mm"] is None
    assert "pick: not reached in this log" in capsys.readouterr().out
    assert all(report["sim_vs_arm_rms_deg"][j] < 1.0 for j in ARM_JOINTS)


def test_a_partial_log_without_its_sidecar_is_compared(hw_log, tmp_path, capsys):
    """A SIGKILL: the temporary CSV, its last row cut mid-line, and no sidecar written."""
    text = hw_log.read_text()
    partial = tmp_path / "partial.csv"
    partial.write_text(text[:len(text) // 2].rsplit("\n", 1)[0] + "\n" + "12.5,12.6,sta")
    report = compare(partial, tmp_path)
    out = capsys.readouterr().out
    assert "1 row(s) cut short" in out and "first measured pose" in out
    assert all(report["sim_vs_arm_rms_deg"][j] < 1.0 for j in ARM_JOINTS)


def test_a_start_just_past_the_elbow_limit_is_a_warning(hw_log, tmp_path, capsys):
    """The virtual arm rests 0.05 deg past the model's elbow limit after a release."""
    from so101_kinematics.sim.scene import joint_limits, load_model

    low, _ = joint_limits(load_model())["elbow_flex"]
    info = json.loads(sidecar_path(hw_log).read_text())
    info["start_pose"]["elbow_flex"] = low - 0.05
    past = tmp_path / "past.csv"
    shutil.copy(hw_log, past)
    sidecar_path(past).write_text(json.dumps(info))
    compare(past, tmp_path)
    out = capsys.readouterr().out
    assert "warning: the measured start has elbow_flex" in out and "0.05 deg outside" in out


# --- a lab day: one virtual arm, runs one after the other (issue 33) -----------------------
def _settled_past(arm, limits, timeout_s: float = 10.0) -> None:
    """Wait (the emulator's wall-clock physics, however loaded the host) until the limp arm
    presses past the elbow's upper or the shoulder's lower limit, as the lab day's did."""
    deadline = time.monotonic() + timeout_s
    time.sleep(1.0)
    while time.monotonic() < deadline:
        pose = arm.joint_positions()
        if pose["elbow_flex"] > limits["elbow_flex"][1] \
                or pose["shoulder_lift"] < limits["shoulder_lift"][0]:
            return
        time.sleep(0.1)


def test_a_lab_days_logs_compare_though_the_arm_slumps_past_a_limit(tmp_path, capsys):
    """Each run ends released at the folded rest; the elbow slumps further each time (the
    virtual arm, 2026-12-03: 90.02, 95.21, then 96.879 deg at the third start, past the
    model's 96.83): that log's start and its return are replayed at the limit, with a note
    naming the joint and by how much, and the three logs compare together."""
    from so101_kinematics.sim.scene import joint_limits, load_model
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    logs = [tmp_path / f"run{k}.csv" for k in range(3)]
    # the slumps above were measured on the kit's 5 V C001 arm: that arm, pinned. How far a
    # released arm slumps follows the servo model's friction and damping (after the D fit the
    # elbow stopped short of the limit), so the third run starts where the lab day's did:
    # the arm set by hand on its elbow's and shoulder's limits, limp, where gravity presses
    # it a little past them (the model's limits are soft), as the log recorded it.
    limits = joint_limits(load_model())
    slumped = {"elbow_flex": limits["elbow_flex"][1], "shoulder_lift": limits["shoulder_lift"][0]}
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=KIT_SUPPLY_V) as arm:
        for k, log in enumerate(logs):
            if k == 2:
                arm.set_pose({**arm.joint_positions(), **slumped})
                _settled_past(arm, limits)  # limp: it settles against the limits
            assert pick_place_hw.main(["--port", arm.port, "--calibration",
                                       str(DEFAULT_CALIBRATION_PATH), "--yes", "--move-duration",
                                       "0.8", "--hold", "0.2", "--log", str(log)]) == 0
    # Gravity presses the limp elbow about 0.05 deg past its limit, under one encoder count
    # (0.088 deg) and within the reading's one count of noise: whether the third start *reads*
    # past is the count's rounding (CI read it inside once in five rehearsals). The lab day's
    # reading, 96.879 deg (0.049 past), is written into that log's start when it read inside.
    third = json.loads(sidecar_path(logs[2]).read_text())
    lab_day = limits["elbow_flex"][1] + 0.049
    third["start_pose"]["elbow_flex"] = max(third["start_pose"]["elbow_flex"], lab_day)
    sidecar_path(logs[2]).write_text(json.dumps(third))
    past = {}
    for log in logs:
        start = json.loads(sidecar_path(log).read_text())["start_pose"]
        for joint, (low, high) in limits.items():
            if not low <= start[joint] <= high:
                past[(log.name, joint)] = max(low - start[joint], start[joint] - high)
    assert ("run2.csv", "elbow_flex") in past
    capsys.readouterr()
    out = tmp_path / "day.json"
    assert so101_command.main(["compare", *map(str, logs), "--report",
                               str(tmp_path / "day.png"), "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert sum(len(runs) for runs in report["profiles"].values()) == 3
    for (name, joint), by in past.items():
        assert any(n.startswith(name) and joint in n and f"{by:.2g}" in n
                   for n in report["notes"]), (name, joint, report["notes"])
    assert all(run["aborted"] is None for runs in report["profiles"].values() for run in runs)
    for run in (run for runs in report["profiles"].values() for run in runs):
        assert run["sim"]["tracking_rms_deg"] == pytest.approx(run["arm"]["tracking_rms_deg"],
                                                               abs=0.5)
