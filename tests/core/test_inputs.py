"""Issue 13, row by row: every input gets a clear answer, and no output file is ever lost."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

import pick_place_sim
import so101_forward_kinematics as fk
import so101_inverse_kinematics as ik
import so101_mujoco_utils as utils
import test_fk_mujoco
from so101_kinematics import cli
from so101_kinematics.errors import KinematicsTypeError, OutputPathError, PlanError
from so101_kinematics.frames import Rx
from so101_kinematics.inputs import check_number
from so101_kinematics.outputs import (
    MP4,
    atomic_output,
    check_output_path,
    temporary_beside,
)
from so101_kinematics.planning.cartesian_plan import cartesian_plan
from so101_kinematics.planning.motion import Plan, Step, Trajectory
from so101_kinematics.planning.plans import STARTING_CONFIGURATION, load_plan
from so101_kinematics.sim import cube as cube_world
from so101_kinematics.sim import stepping

REPO = Path(__file__).resolve().parents[2]
ARM = {"shoulder_pan": 0.0, "shoulder_lift": 0.0, "elbow_flex": 0.0, "wrist_flex": 0.0,
       "wrist_roll": 0.0}
UP = dict(STARTING_CONFIGURATION, shoulder_lift=0.0)


def plan_text(**top) -> str:
    """A one-waypoint JSON plan with the given top-level keys (and step keys under "step")."""
    step = {"name": "up", "configuration": UP, **top.pop("step", {})}
    return json.dumps({"steps": [step], **top})


def write_plan(tmp_path, content, name="plan.json") -> Path:
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def one_line_error(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    return lines[0]


def run_sim(capsys, argv) -> tuple[int, str]:
    code = pick_place_sim.main(argv)
    return code, capsys.readouterr().err


# --- Durations: 1e9, "x", null, -5 -----------------------------------------------------
@pytest.mark.parametrize("field, value, shown", [
    ("duration", 1e9, "1e+09"),
    ("hold", -1, "-1"),
    ("return_duration", "x", "'x' (text)"),
    ("return_duration", None, "None (null)"),
    ("return_duration", -5, "-5"),
])
def test_plan_durations_are_checked_naming_the_field(tmp_path, field, value, shown):
    content = plan_text(step={field: value}) if field != "return_duration" else \
        plan_text(return_duration=value)
    path = write_plan(tmp_path, content)
    with pytest.raises(PlanError) as info:
        load_plan(path)
    message = str(info.value)
    assert str(path) in message and field in message and shown in message
    assert "[0, 600] s" in message and "Fix:" in message and "\n" not in message


def test_move_duration_1e9_is_refused_on_the_command_line(capsys):
    code, err = run_sim(capsys, ["--headless", "--move-duration", "1e9"])
    assert code == 2
    assert "--move-duration" in one_line_error(err) and "[0, 600] s" in err


MEMORY_PROBE = """
import json, sys, tracemalloc
import mujoco
import so101_mujoco_utils as utils
from so101_kinematics.planning.plans import STARTING_CONFIGURATION
up = json.loads(sys.argv[1])
model = utils.load_model()
d = mujoco.MjData(model)
utils.set_initial_pose(d, STARTING_CONFIGURATION)
tracemalloc.start()
utils.move_to_pose(model, d, None, up, 120.0)
_, peak = tracemalloc.get_traced_memory()
tracemalloc.stop()
print(json.dumps([peak, utils.get_command(model, d)["shoulder_lift"]]))
"""


@pytest.mark.slow
def test_a_long_move_keeps_its_memory_bounded():
    # 120 s = 30000 steps; the old up-front table of commands was 30000 x 6 floats
    # (1.44 MB) plus its temporaries: 3.19 MB peak measured with one block for the whole move,
    # 0.72 MB with blocks of 4096 steps (2026-12-03, Python 3.11). The bound is the table
    # alone: the blocks pass it by half, the table cannot. Measured in a child process:
    # tracemalloc counts every thread's allocations, and under pytest-xdist the worker's own
    # messaging thread allocated beside the move (0.76 MB).
    path = os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PYTHONPATH": path}
    run = subprocess.run([sys.executable, "-c", MEMORY_PROBE, json.dumps(UP)], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    peak, lift = json.loads(run.stdout.strip().splitlines()[-1])
    assert peak < 30000 * 6 * 8, f"peak {peak / 1e6:.2f} MB"
    assert lift == pytest.approx(0.0, abs=1e-9)


def test_commands_in_blocks_are_the_same_physics(model, monkeypatch):
    def final_state(block):
        monkeypatch.setattr(stepping, "COMMAND_BLOCK_STEPS", block)
        d = mujoco.MjData(model)
        utils.set_initial_pose(d, STARTING_CONFIGURATION)
        utils.move_to_pose(model, d, None, UP, 0.5)  # 125 steps
        return d.qpos.copy(), d.time

    (q_small, t_small), (q_big, t_big) = final_state(7), final_state(4096)
    np.testing.assert_array_equal(q_small, q_big)
    assert t_small == t_big


@pytest.mark.parametrize("duration", ["x", None, -5, math.nan, 1e9, 10**400])
def test_simulated_move_and_hold_refuse_bad_durations(model, data, duration):
    with pytest.raises(PlanError, match="duration"):
        utils.move_to_pose(model, data, None, STARTING_CONFIGURATION, duration)
    with pytest.raises(PlanError, match="duration"):
        utils.hold_position(model, data, None, duration)
    assert data.time == 0.0


def test_trajectory_names_its_duration():
    with pytest.raises(PlanError, match="Trajectory duration .*'x'"):
        Trajectory({"gripper": 0.0}, {"gripper": 1.0}, "x")


# --- Joint values, encodings, booleans ---------------------------------------------------
def test_a_joint_of_10_to_the_400_is_refused(tmp_path):
    text = plan_text().replace('"shoulder_pan": -45.0', '"shoulder_pan": 1' + "0" * 400)
    with pytest.raises(PlanError, match=r"shoulder_pan.*an integer of about 401 digits"):
        load_plan(write_plan(tmp_path, text))


@pytest.mark.parametrize("content, expected", [
    (plan_text().encode("utf-16"), "is UTF-16 text, not UTF-8. Fix: save it as UTF-8."),
    (b"\x89PNG\r\n\x1a\n\x00\x00", "is not text but binary data (a NUL byte at 8)."),
    (plan_text().encode("latin-1").replace(b'"up"', b'"\xe9"'), "Fix: save it as UTF-8."),
])
def test_an_undecodable_plan_names_the_file_and_says_save_as_utf8(tmp_path, capsys, content,
                                                                  expected):
    path = write_plan(tmp_path, content)
    code, err = run_sim(capsys, ["--headless", "--plan", str(path)])
    assert code == 2
    assert str(path) in one_line_error(err) and expected in err


@pytest.mark.parametrize("suffix", [".json", ".toml"])
def test_a_plan_saved_with_a_bom_is_read(tmp_path, suffix):
    text = plan_text() if suffix == ".json" else (
        '[[steps]]\nname = "up"\nconfiguration = { '
        + ", ".join(f"{joint} = {value}" for joint, value in UP.items()) + " }\n")
    path = write_plan(tmp_path, b"\xef\xbb\xbf" + text.encode("utf-8"), f"plan{suffix}")
    plan = load_plan(path)
    assert [step.name for step in plan.steps] == ["up"]
    assert plan.steps[0].configuration == UP


@pytest.mark.parametrize("value", ["false", "true", 0, 1, None])
def test_return_to_start_must_be_a_boolean(tmp_path, value):
    path = write_plan(tmp_path, plan_text(return_to_start=value))
    with pytest.raises(PlanError, match="return_to_start must be true or false"):
        load_plan(path)


@pytest.mark.parametrize("value", [False, True])
def test_return_to_start_booleans_are_read_as_written(tmp_path, value):
    assert load_plan(write_plan(tmp_path, plan_text(return_to_start=value))).return_to_start \
        is value


# --- --record, --json ---------------------------------------------------------------------
# An old video of ours (an MP4's boxes: ftyp, then moov holding our comment tag): ours to replace.
OLD_VIDEO = (b"\x00\x00\x00\x10ftypisom\x00\x00\x02\x00"
             b"\x00\x00\x00\x28moov" + b"so101-kinematics the old video".ljust(32))
SHORT_PLAN = json.dumps({"steps": [{"name": "up", "configuration": UP, "duration": 0.1,
                                    "hold": 0.0}], "return_to_start": False})


def test_ctrl_c_during_record_keeps_the_old_video(tmp_path, capsys, monkeypatch):
    video = tmp_path / "clip.mp4"
    video.write_bytes(OLD_VIDEO)
    plan = write_plan(tmp_path, SHORT_PLAN)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(stepping, "move_to_pose", interrupted)
    code, err = run_sim(capsys, ["--record", str(video), "--plan", str(plan), "--size", "32x32",
                                 "--no-cube", "--no-progress"])
    assert code == 130
    assert "Interrupted" in one_line_error(err)
    assert video.read_bytes() == OLD_VIDEO
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.mp4", "plan.json"]


def test_a_complete_recording_replaces_the_old_video(tmp_path, capsys):
    video = tmp_path / "clip.mp4"
    video.write_bytes(OLD_VIDEO)
    plan = write_plan(tmp_path, SHORT_PLAN)
    code, _ = run_sim(capsys, ["--record", str(video), "--plan", str(plan), "--size", "32x32",
                               "--no-cube", "--no-progress"])
    assert code == 0
    assert video.read_bytes() != OLD_VIDEO and MP4.recognise(video)  # a new MP4 of ours
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.mp4", "plan.json"]


@pytest.mark.parametrize("option", ["--json", "--record"])
def test_an_output_pointing_at_a_folder_is_refused_before_the_run(tmp_path, capsys, monkeypatch,
                                                                   option):
    monkeypatch.setattr(pick_place_sim, "run_pick_place", lambda *a, **k: pytest.fail("ran"))
    code, err = run_sim(capsys, ["--headless", option, str(tmp_path)])
    assert code == 2
    assert f"{option} {tmp_path}: is a folder" in one_line_error(err)


def test_json_may_not_overwrite_the_plan(tmp_path, capsys):
    plan = write_plan(tmp_path, SHORT_PLAN)
    code, err = run_sim(capsys, ["--headless", "--plan", str(plan), "--json", str(plan)])
    assert code == 2 and "input files" in one_line_error(err)
    assert plan.read_text() == SHORT_PLAN


def test_atomic_output_keeps_the_old_file_on_an_error(tmp_path):
    target = tmp_path / "report.json"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_output(target) as temporary:
        temporary.write_text("partial")
        raise RuntimeError("crash")
    assert target.read_text() == "old"
    assert list(tmp_path.iterdir()) == [target]


def test_temporary_keeps_the_suffix_so_writers_pick_the_format(tmp_path):
    temporary = temporary_beside(tmp_path / "clip.mp4")
    assert temporary.parent == tmp_path and temporary.suffix == ".mp4"
    assert temporary.name.startswith(".clip.mp4.")


def test_output_path_with_a_nul_is_refused():
    with pytest.raises(OutputPathError, match="NUL"):
        check_output_path("a\0b.json", "--json")


# --- --size, --fps ------------------------------------------------------------------------
@pytest.mark.parametrize("size, expected", [
    ("10000x10000", "each edge must be in [16, 4096] px (MuJoCo renders into an offscreen "
                    "buffer"),
    ("641x480", "must be even"),
    ("8x8", "[16, 4096]"),
    ("640by480", "'640by480' is not a size"),
])
def test_size_is_bounded(capsys, size, expected):
    assert pick_place_sim.main(["--headless", "--size", size]) == 2
    err = one_line_error(capsys.readouterr().err)
    assert "--size" in err and expected in err


@pytest.mark.parametrize("fps", ["500", "1e6", "250.5"])
def test_fps_above_one_frame_per_physics_step_is_refused(capsys, fps):
    # The model steps every 4 ms (model/scene.xml's option): at most 1 / 0.004 = 250 frames/s.
    code, err = run_sim(capsys, ["--headless", "--fps", fps])
    assert code == 2
    assert "--fps" in one_line_error(err) and "[1, 250] frames/s" in err


@pytest.mark.parametrize("fps", ["nan", "0", "-30", "x"])
def test_fps_must_be_a_positive_number(capsys, fps):
    assert pick_place_sim.main(["--headless", "--fps", fps]) == 2
    assert "--fps" in one_line_error(capsys.readouterr().err)


def test_fps_of_one_frame_per_step_gives_a_video_as_long_as_the_simulation(tmp_path):
    plan = Plan([Step("up", UP, 0.2, 0.0)], return_to_start=False)
    report = pick_place_sim.run_pick_place(plan, cube=None, mode="record",
                                           video=tmp_path / "v.mp4", fps=250.0, size=(32, 32),
                                           progress=False)
    # 0.2 s at 4 ms: 50 steps, a frame at each and one at the start.
    assert report.frames_written == 51
    assert report.frames_written / 250.0 == pytest.approx(report.sim_time_s + 1 / 250.0)


# --- --pick nan, --lift-height -0.1, --cube-yaw nan, --cube-offset ----------------------
@pytest.mark.parametrize("argv, option", [
    (["--pick", "nan", "0.1", "0.013", "--place", "0.2", "-0.1", "0.013"], "--pick"),
    (["--lift-height", "-0.1"], "--lift-height"),
    (["--cube-yaw", "nan"], "--cube-yaw"),
    (["--cube-offset", "0", "-2000"], "--cube-offset"),
    (["--cube-turn", "inf"], "--cube-turn"),
    (["--hold", "ten"], "--hold"),
])
def test_bad_numbers_are_one_line_naming_the_option(capsys, argv, option):
    assert pick_place_sim.main(["--headless", *argv]) == 2
    assert f"argument {option}:" in one_line_error(capsys.readouterr().err)


def test_a_cube_off_the_table_is_refused_before_the_run(capsys, monkeypatch):
    # Waypoint start_open puts the cube at x = 0.230 m; the table ends at x = 0.5 m.
    monkeypatch.setattr(cube_world, "CUBE_OFFSET_RANGE_MM", (-1000.0, 1000.0))
    with pytest.raises(PlanError, match=r"off the table, which spans x in \[-0.5, 0.5\] m"):
        pick_place_sim.run_pick_place(cube=pick_place_sim.CubeStart((0.28, 0.0)))


def test_a_cube_out_of_reach_is_refused_before_the_run(monkeypatch):
    # (0.23 + 0.2, 0.19 + 0.2) m is on the table but 0.58 m from the base: the two
    # links and the wrist span about 0.45 m.
    monkeypatch.setattr(cube_world, "CUBE_OFFSET_RANGE_MM", (-1000.0, 1000.0))
    with pytest.raises(PlanError, match=r"\(0.430, 0.390\) m .*out of the arm's reach.*beyond"
                                        r".*--cube-offset"):
        pick_place_sim.run_pick_place(cube=pick_place_sim.CubeStart((0.2, 0.2)))


def test_cube_yaw_and_lift_height_are_checked_in_the_library():
    pick, place = (0.230054, 0.190308, 0.013), (0.229144, -0.191219, 0.013)
    with pytest.raises(PlanError, match=r"lift_height = -0.1 m is not in \[0, 0.3\] m"):
        cartesian_plan(pick, place, lift_height=-0.1)
    with pytest.raises(PlanError, match="cube_yaw_deg must be a finite number"):
        cartesian_plan(pick, place, cube_yaw_deg=math.nan)


# --- FK / IK ------------------------------------------------------------------------------
@pytest.mark.parametrize("value", [720.0, 1e12, -361.0])
def test_fk_outside_one_turn_is_refused_naming_the_joint(value):
    with pytest.raises(fk.KinematicsInputError, match=r"'wrist_roll' = .* \[-360, 360\] deg"):
        fk.get_forward_kinematics(dict(ARM, wrist_roll=value))
    with pytest.raises(fk.KinematicsInputError, match="wrist_roll"):
        fk.get_g45(value)


def test_fk_at_plus_and_minus_one_turn_is_the_zero_pose():
    zero = fk.get_forward_kinematics(ARM)
    for turn in (360.0, -360.0):
        position, rotation = fk.get_forward_kinematics(dict(ARM, shoulder_pan=turn))
        np.testing.assert_allclose(position, zero[0], atol=1e-15)
        np.testing.assert_allclose(rotation, zero[1], atol=1e-15)


@pytest.mark.parametrize("call, match", [
    (lambda: fk.get_gw1("45"), "shoulder_pan must be a number of degrees, got '45'"),
    (lambda: Rx(None), "thetadeg must be a number of degrees, got None"),
    (lambda: fk.get_g23(True), "elbow_flex"),
])
def test_text_and_none_are_type_errors_of_the_family(call, match):
    with pytest.raises(KinematicsTypeError, match=match) as info:
        call()
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)


def test_nan_is_refused_by_the_elementary_transforms():
    with pytest.raises(fk.KinematicsInputError, match="shoulder_pan must be a finite number"):
        fk.get_gw1(math.nan)


@pytest.mark.parametrize("kwargs, error, match", [
    ({"position": ("0.2", "0", "0.05")}, KinematicsTypeError, "position x must be a number"),
    ({"position": (0.2, 0.0, 0.05), "yaw_deg": "45"}, KinematicsTypeError, "yaw_deg"),
    ({"position": (0.2, 0.0, 0.05), "gripper": math.nan}, fk.KinematicsInputError,
     r"gripper must be a finite number in \[0, 100\]"),
    ({"position": (0.2, 0.0, 0.05), "gripper": 500}, fk.KinematicsInputError,
     r"gripper = 500 % is not in \[0, 100\] %"),
    ({"position": (1e300, 0.0, 0.05)}, fk.KinematicsInputError, r"position x .*\[-10, 10\] m"),
    ({"position": (0.2, 0.0, 0.05), "min_height": "0"}, fk.KinematicsInputError, "min_height"),
])
def test_ik_refuses_malformed_arguments_with_a_project_error(kwargs, error, match):
    with pytest.raises(error, match=match):
        ik.get_inverse_kinematics(**kwargs)


@pytest.mark.parametrize("chunk, error", [(2.5, KinematicsTypeError),
                                          (True, KinematicsTypeError),
                                          (0, fk.KinematicsInputError)])
def test_batch_chunk_must_be_a_whole_number(chunk, error):
    with pytest.raises(error, match="chunk must be a whole number >= 1"):
        fk.get_forward_kinematics_batch(np.zeros((3, 5)), chunk=chunk)


@pytest.mark.parametrize("angles", [np.array([["1"] * 5]), [[0, 0, 0, 0, None]],
                                    [[0.0] * 4 + ["x"]],
                                    np.zeros((2, 5), dtype=bool)])
def test_batch_refuses_non_numbers(angles):
    with pytest.raises(KinematicsTypeError):
        fk.get_forward_kinematics_batch(angles)


def test_batch_with_numpy_chunk_equals_single():
    angles = np.random.default_rng(3).uniform(-180.0, 180.0, (5, 5))
    positions, _ = fk.get_forward_kinematics_batch(angles, chunk=np.int64(2))
    for row, position in zip(angles, positions, strict=True):
        np.testing.assert_allclose(position, fk.get_forward_kinematics(
            dict(zip(fk.ARM_JOINTS, row, strict=True)))[0], atol=1e-14)


def test_check_number_refuses_booleans_and_huge_integers():
    for value in (True, 10**400, "1", None, math.inf):
        with pytest.raises(PlanError, match="must be"):
            check_number(value, "x", 0.0, 1.0)


# --- Scripts: one line, exit codes, never a traceback -------------------------------------
def run_script(*argv, timeout=120):
    env = dict(os.environ, PYTHONPATH=str(REPO), MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    return subprocess.run([sys.executable, *argv], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=timeout)


@pytest.mark.parametrize("argv", [
    ["pick_place_sim.py", "--headless", "--fps", "nan"],
    ["pick_place_sim.py", "--headless", "--size", "10000x10000"],
    ["test_fk_mujoco.py", "--headless", "--seconds", "-1"],
    # the hardware side's parsers too: no usage block above the line
    ["pick_place_hw.py", "--dry-run", "--profile", "smooth"],
    ["read_position.py", "--port", "/dev/null", "--rate", "fast"],
    ["virtual_so101.py", "--base-height", "low"],
    ["-m", "so101_kinematics.sim.meshes", "--check", "--everything", "now"],
])
def test_scripts_answer_bad_options_in_one_line(argv):
    result = run_script(*argv)
    assert result.returncode == 2
    assert argv[-2] in one_line_error(result.stderr)


def test_an_unexpected_error_is_one_line_with_a_hint(capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(pick_place_sim, "run_pick_place", broken)
    code, err = run_sim(capsys, ["--headless"])
    assert code == 1
    assert "rerun with -v" in one_line_error(err) and "ZeroDivisionError" in err
    with pytest.raises(ZeroDivisionError):
        pick_place_sim.main(["--headless", "-v"])


def test_every_script_ending_is_one_line_and_its_exit_code(capsys):
    # run_script is the ending test_fk_mujoco.py, test_ik_mujoco.py, test_trajectory_mujoco.py
    # and pick_place_sim.py share: bad input 2, Ctrl-C 130, a bug 1 (traceback with -v).
    parser = cli.ArgumentParser(prog="demo")
    parser.add_argument("-v", "--verbose", action="store_true")

    def raising(error):
        def run(args):
            raise error
        return run

    endings = ((raising(PlanError("steps[0]: bad")), 2, "error: steps[0]: bad"),
               (raising(KeyboardInterrupt()), 130, "Interrupted (Ctrl-C): existing output"),
               (raising(ZeroDivisionError("x")), 1, "error: unexpected ZeroDivisionError: x"),
               (lambda args: 0, 0, ""))
    for run, code, line in endings:
        assert cli.run_script(parser, [], run, refused=(PlanError,)) == code
        err = capsys.readouterr().err
        if line:
            assert one_line_error(err).startswith(line), err
        else:
            assert err == ""
    assert cli.run_script(parser, ["--nonsense"], lambda args: 0) == 2  # the parser's one line
    assert "unrecognized arguments" in one_line_error(capsys.readouterr().err)
    with pytest.raises(ZeroDivisionError):
        cli.run_script(parser, ["-v"], raising(ZeroDivisionError("x")))


def test_fk_script_checks_its_outputs_before_the_hold(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(test_fk_mujoco, "hold_position", lambda *a: pytest.fail("held"))
    for option, value, expected in (("--screenshot", tmp_path, "is a folder"),
                                    ("--screenshot", tmp_path / "a.jpg", "must end in .png"),
                                    ("--table", REPO / "model" / "scene.xml", "input files")):
        assert test_fk_mujoco.main(["--headless", option, str(value)]) == 2
        assert expected in one_line_error(capsys.readouterr().err)


# --- options that do nothing alone, durations that cannot be followed (issue 28) -----------
def test_the_moved_report_is_refused_before_anything_runs(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(pick_place_sim, "run_pick_place", lambda *a, **k: pytest.fail("ran"))
    monkeypatch.chdir(tmp_path)
    figure = tmp_path / "figure.png"
    code, err = run_sim(capsys, ["--report", str(figure)])
    assert code == 2
    line = one_line_error(err)
    assert "--report moved to the so101 command" in line and "Fix: run `so101 compare" in line
    assert list(tmp_path.iterdir()) == []  # no figure, no video


def test_zero_move_durations_are_warned_before_the_run(capsys, monkeypatch):
    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pick_place_sim, "run_pick_place", stop)
    code, err = run_sim(capsys, ["--headless", "--move-duration", "0", "--hold", "0"])
    assert code == 130
    warning = next(line for line in err.splitlines() if line.startswith("warning:"))
    assert "--move-duration 0 s" in warning and "--hold 0" in warning and "Fix:" in warning
    code, err = run_sim(capsys, ["--headless"])  # the defaults: no warning
    assert code == 130 and "warning" not in err
