"""See and pick on the virtual arm: lerobot's camera class finds the cube, lerobot's bus moves it.

``see_and_pick.py --port PORT --camera ADDRESS`` (``lab/see_and_pick_arm.py``): the virtual
arm serves its overhead camera (the cube and the target tag drawn, ``sim/tag_textures.py``);
lerobot opens it with its own camera class (``lerobot_camera_so101_virtual``); the one
detection path (``vision/detect.py``) gives the cube's and the target's positions; the
course's Cartesian plan (as ``pick_place_hw.py --pick/--place``) runs through lerobot's
``FeetechMotorsBus`` (``hw/run.py``'s ``run_on_arm``). The expected end: the cube resting on
the target tag, within the 10 mm the course's pick-and-place asks of the arm.
"""

from __future__ import annotations

import json
import math
import os
import signal

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("cv2")
pytestmark = [pytest.mark.hw, pytest.mark.vision]

import see_and_pick  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402

CUBE_AT = (0.20, 0.08, 20.0)  # [m, m, deg]
TARGET_AT = (0.22, -0.10, -15.0)
PLACE_TOLERANCE_M = 0.010  # the course's pick-and-place on the arm: 10 mm


@pytest.mark.slow
def test_the_virtual_arm_puts_the_cube_it_saw_on_the_target_it_saw(tmp_path, capsys):
    report = tmp_path / "report.json"
    with VirtualSO101(cube=CUBE_AT, target=TARGET_AT, cameras=["overhead"]) as arm:
        code = see_and_pick.main(["--port", arm.port, "--camera",
                                  arm.camera_addresses["overhead"], "--json", str(report)])
        cube, torque = arm.cube(), arm.torque_enabled()
    out, err = capsys.readouterr()
    assert code == 0, err
    # the last line is the arm's, as its servos read back: where it is and its torque
    assert out.strip().splitlines()[-1] == "Done: back at the starting pose, torque off."
    # "back at the starting pose" is the read-back before the release (hw/run.ending); a limp
    # arm then settles on its own (the elbow 7 deg here), so the servos are asked the torque
    assert not any(torque.values()), torque
    x, y, _ = cube.position_m
    assert math.hypot(x - TARGET_AT[0], y - TARGET_AT[1]) <= PLACE_TOLERANCE_M
    assert cube.tilt_deg <= 10.0 and not cube.held
    result = json.loads(report.read_text())
    seen = result["cube_seen"]
    assert math.hypot(seen[0] - CUBE_AT[0], seen[1] - CUBE_AT[1]) <= 0.002
    trial = result["trials"][0]
    assert result["success_rate"] == 1.0 and trial["picked"] and trial["placed"]
    assert trial["placed_error_mm"] == pytest.approx(
        1000 * math.hypot(x - result["target_seen"][0], y - result["target_seen"][1]), abs=2.0)
    print(out)


def fault_at(monkeypatch, arm, fault: str, step: str = "pre_grasp") -> None:
    """``fault`` (a virtual-arm fault, or a signal to this process) at ``step``'s first cycle.

    As ``lab/fault_drill.py`` injects them, through ``run_on_arm``'s cycle hook.
    """
    from so101_kinematics.hw.run import run_on_arm
    from so101_kinematics.lab import see_and_pick_arm

    fired = []

    def on_cycle(session, cycle):
        if cycle.step == step and not fired:
            fired.append(cycle.step)
            if fault.startswith("SIG"):
                os.kill(os.getpid(), getattr(signal, fault))
            else:
                arm.inject(fault)

    monkeypatch.setattr(see_and_pick_arm, "run_on_arm",
                        lambda *args, **kwargs: run_on_arm(*args, on_cycle=on_cycle, **kwargs))


@pytest.mark.parametrize(("fault", "says", "last_line"), [
    pytest.param("overheat:elbow_flex", "elbow_flex", "Back at the starting pose, torque off.",
                 marks=pytest.mark.slow),  # ~20 s each: one in the quick tier
    ("SIGTERM", "stopped by SIGTERM", "Back at the starting pose, torque off."),
    pytest.param("remove:wrist_flex", "did not answer", "Not answering: wrist_flex (id 4).",
                 marks=pytest.mark.slow),
])
def test_an_aborted_run_ends_with_the_arms_last_line_not_an_unexpected_error(
        fault, says, last_line, monkeypatch, capsys):
    # the fault policy (docs/hardware_safety.md, the fault matrix): a hot servo or a stop
    # signal stops the arm and brings it back to its start, released there; a servo gone from
    # the bus leaves the others holding where they stopped, torqued
    with VirtualSO101(cube=CUBE_AT, target=TARGET_AT, cameras=["overhead"]) as arm:
        fault_at(monkeypatch, arm, fault)
        code = see_and_pick.main(["--port", arm.port, "--camera",
                                  arm.camera_addresses["overhead"]])
        torque = arm.torque_enabled()
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 1 and "nexpected" not in err, err
    assert lines[-2].startswith("ABORTED: ") and says in lines[-2], err
    assert lines[-1].startswith(last_line), err
    if "torque off" in last_line:  # what the line says, the servos say
        assert not any(torque.values()), torque
    else:  # the others held where they stopped, torqued
        assert "torque ON" in lines[-1] and "--release --port" in lines[-1], err
        assert all(on for joint, on in torque.items() if joint != "wrist_flex"), torque


@pytest.mark.parametrize("option", [["--port", "/dev/null"], ["--camera", "http://x/o.mjpg"]])
def test_the_arm_needs_both_its_port_and_its_camera(option, capsys):
    assert see_and_pick.main(option) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Fix: give both" in err


def test_no_target_tag_in_view_is_one_line_and_nothing_moves(capsys):
    with VirtualSO101(cube=CUBE_AT, cameras=["overhead"]) as arm:
        before = arm.cube()
        code = see_and_pick.main(["--port", arm.port, "--camera", arm.camera_addresses["overhead"]])
        after = arm.cube()
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "target" in err
    assert after.position_m == pytest.approx(before.position_m, abs=1e-4)


def calibration_report(path, K, g_bc, size=(640, 480)):
    """A report as calibrate_camera.py --photos DIR --mount fixed --json writes it."""
    path.write_text(json.dumps({
        "intrinsics": {"K": np.asarray(K).tolist(), "distortion": [0.0] * 5, "rms_px": 0.1,
                       "views_used": 12, "image_size": list(size)},
        "hand_eye": {"fixed": {"camera_in_base": np.asarray(g_bc).tolist(),
                               "residual_mm": 0.2, "residual_deg": 0.05}}}))
    return path


def test_a_camera_calibration_file_is_the_camera_the_arm_sees_by(tmp_path):
    # The report's camera moved 10 mm along the base's x: every ray moves with it, so each tag
    # is seen 10 mm further along x (a rigid shift, by hand), its y and yaw unchanged.
    from so101_kinematics.lab.see_and_pick_arm import camera_view, look_through_lerobot

    K, _, g_bc = camera_view("overhead")
    moved = g_bc.copy()
    moved[0, 3] += 0.010
    with VirtualSO101(cube=CUBE_AT, target=TARGET_AT, cameras=["overhead"]) as arm:
        address = arm.camera_addresses["overhead"]
        model = look_through_lerobot(address)
        same = look_through_lerobot(address, camera_calibration=calibration_report(
            tmp_path / "same.json", K, g_bc))
        shifted = look_through_lerobot(address, camera_calibration=calibration_report(
            tmp_path / "moved.json", K, moved))
    for name, g in model.items():
        assert same[name][:3, 3] == pytest.approx(g[:3, 3], abs=0.0005)
        assert shifted[name][:3, 3] - g[:3, 3] == pytest.approx([0.010, 0.0, 0.0], abs=0.0005)
        assert shifted[name][:3, :3] == pytest.approx(g[:3, :3], abs=1e-3)


def test_a_calibration_without_the_fixed_cameras_pose_is_one_line_and_nothing_moves(
        tmp_path, capsys):
    from so101_kinematics.lab.see_and_pick_arm import camera_view

    K, _, g_bc = camera_view("overhead")
    wrist_only = calibration_report(tmp_path / "wrist.json", K, g_bc)
    data = json.loads(wrist_only.read_text())
    data["hand_eye"] = {"wrist": {"camera_in_gripper": np.eye(4).tolist()}}
    wrist_only.write_text(json.dumps(data))
    with VirtualSO101(cube=CUBE_AT, target=TARGET_AT, cameras=["overhead"]) as arm:
        before = arm.cube()
        code = see_and_pick.main(["--port", arm.port, "--camera",
                                  arm.camera_addresses["overhead"],
                                  "--camera-calibration", str(wrist_only)])
        after = arm.cube()
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "--mount fixed" in err and str(wrist_only) in err
    # nothing picked it: where it lay, give or take its settling on the table (0.3 mm seen)
    assert after.position_m == pytest.approx(before.position_m, abs=1e-3)


def test_a_camera_calibration_without_an_arm_is_refused(tmp_path, capsys):
    assert see_and_pick.main(["--camera-calibration", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--port PORT --camera ADDRESS" in err
