"""Outputs never replace a file they did not write (issue 28, Deliver 3).

An existing target is replaced only when it is this kind of output from this
project (a CSV log with its header, a JSON report with its generator key, an
MP4, a PNG, a PDF) or with ``--overwrite``; anything else is refused in one
line, exit 2, before anything runs, and the file is left byte for byte. Each
script is run for real, in a child process, as a student would run it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from so101_kinematics.outputs import (
    JSON_REPORT,
    MP4,
    PDF,
    PNG,
    OutputPathError,
    check_output_path,
)

REPO = Path(__file__).resolve().parent.parent
CALIBRATION = REPO / "calibration"
A_SOURCE_FILE = REPO / "so101_inverse_kinematics.py"
FK_SUBMISSION = REPO / "tests" / "fk_submissions" / "correct.py"
IK_SUBMISSION = REPO / "tests" / "ik_submissions" / "correct.py"
TRAJ_SUBMISSION = REPO / "tests" / "traj_submissions" / "correct.py"
TRIMS = "shoulder_pan = 1.0\n"  # a trim file (TOML): joint -> [deg]
# The head of an MP4 as ffmpeg writes one (ISO base media: a box size, then "ftyp").
MP4_HEAD = b"\x00\x00\x00\x20ftypisom\x00\x00\x02\x00isomiso2avc1mp41"


def run(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """One of the project's programs, in a child process, with this checkout's code."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "MUJOCO_GL": "egl"}
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    return subprocess.run([sys.executable, *map(str, args)], cwd=cwd or REPO, env=env,
                          capture_output=True, text=True, timeout=600)


def assert_refused(done: subprocess.CompletedProcess, option: str, path: Path, before: bytes):
    """Exit 2, one line naming the option, the file and the fix; the file as it was."""
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr
    assert len(lines) == 1, done.stderr
    assert f"{option} {path}" in lines[0] and "Fix:" in lines[0] and "--overwrite" in lines[0]
    assert path.read_bytes() == before


@pytest.fixture
def student_file(tmp_path) -> Path:
    """A student's own source file, one tab-completion away from the output's name."""
    path = tmp_path / "so101_inverse_kinematics.py"
    shutil.copy(A_SOURCE_FILE, path)
    return path


# --- the one check ------------------------------------------------------------------------
@pytest.mark.parametrize("kind, ours, theirs", [
    (PNG, b"\x89PNG\r\n\x1a\n" + bytes(20), b"GIF89a" + bytes(20)),
    (PDF, b"%PDF-1.4\n", b"%!PS-Adobe-3.0\n"),
    (MP4, MP4_HEAD, b"RIFF\x00\x00\x00\x00AVI LIST"),
    (JSON_REPORT, b'{"generator": "so101-kinematics test_ik_mujoco.py", "results": []}',
     b'{"homing_offset": 0, "range_min": 1000}'),
])
def test_an_output_replaces_only_its_own_kind(tmp_path, kind, ours, theirs):
    path = tmp_path / "out"
    path.write_bytes(ours)
    assert check_output_path(path, "--out", kind=kind) == path
    path.write_bytes(theirs)
    with pytest.raises(OutputPathError, match="exists and is not .*--overwrite"):
        check_output_path(path, "--out", kind=kind)
    assert check_output_path(path, "--out", kind=kind, overwrite=True) == path


def test_an_input_is_refused_even_with_overwrite(tmp_path):
    plan = tmp_path / "plan.json"
    plan.write_text('{"generator": "so101-kinematics pick_place_sim.py"}')
    with pytest.raises(OutputPathError, match="input files"):
        check_output_path(plan, "--json", inputs=[plan], kind=JSON_REPORT, overwrite=True)


def test_without_a_kind_an_existing_file_is_never_replaced(tmp_path):
    calibration = tmp_path / "arm.json"
    calibration.write_text("{}")
    with pytest.raises(OutputPathError, match="exists already.*--force"):
        check_output_path(calibration, "--write-default-calibration", overwrite_option="--force")


# --- test_ik_mujoco.py --json / --record ----------------------------------------------------
def test_ik_demo_json_refuses_a_source_file(student_file):
    before = student_file.read_bytes()
    done = run("test_ik_mujoco.py", "--headless", "--json", student_file)
    assert_refused(done, "--json", student_file, before)


def test_ik_demo_record_refuses_a_file_that_is_not_a_video(tmp_path):
    video = tmp_path / "clip.mp4"
    video.write_text("notes for the lab, named .mp4 by mistake\n")
    done = run("test_ik_mujoco.py", "--record", video, "--target", "0.2", "0", "0")
    assert_refused(done, "--record", video, video.read_bytes())


def test_trajectory_test_json_and_plot_refuse_a_source_file(student_file, tmp_path):
    before = student_file.read_bytes()
    done = run("test_trajectory_mujoco.py", "--headless", "--json", student_file)
    assert_refused(done, "--json", student_file, before)
    plot = tmp_path / "tracking.png"
    plot.write_text("a student's notes, named .png by mistake\n")
    done = run("test_trajectory_mujoco.py", "--headless", "--plot", plot)
    assert_refused(done, "--plot", plot, plot.read_bytes())


def test_ik_demo_replaces_its_own_old_report(tmp_path):
    report = tmp_path / "ik.json"
    first = run("test_ik_mujoco.py", "--headless", "--no-progress", "--json", report,
                "--target", "0.2", "0.0", "0", "--move-duration", "0.2", "--hold", "0.1")
    assert first.returncode in (0, 1), first.stderr
    old = report.read_bytes()
    second = run("test_ik_mujoco.py", "--headless", "--no-progress", "--json", report,
                 "--target", "0.2", "0.05", "0", "--move-duration", "0.2", "--hold", "0.1")
    assert second.returncode in (0, 1), second.stderr
    assert report.read_bytes() != old
    assert json.loads(report.read_text())["results"][0]["target_position_m"][1] == \
        pytest.approx(0.05)


# --- pick_place_sim.py --json / --record / --report ----------------------------------------
def test_sim_json_refuses_a_source_file(student_file):
    before = student_file.read_bytes()
    done = run("pick_place_sim.py", "--headless", "--json", student_file)
    assert_refused(done, "--json", student_file, before)


def test_sim_record_refuses_a_file_that_is_not_a_video(tmp_path):
    video = tmp_path / "run.mp4"
    video.write_text("not a video\n")
    done = run("pick_place_sim.py", "--record", video)
    assert_refused(done, "--record", video, video.read_bytes())


def test_sim_json_with_overwrite_replaces_any_file(tmp_path):
    target = tmp_path / "notes.txt"
    target.write_text("a file of another kind\n")
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps({"steps": [{"name": "up", "configuration": {
        "shoulder_pan": 0, "shoulder_lift": 0, "elbow_flex": 0, "wrist_flex": 0,
        "wrist_roll": 0, "gripper": 0}, "duration": 0.1, "hold": 0.0}],
        "return_to_start": False}))
    done = run("pick_place_sim.py", "--headless", "--no-cube", "--no-progress", "--plan", plan,
               "--json", target, "--overwrite")
    assert done.returncode == 0, done.stderr
    assert json.loads(target.read_text())["generator"].startswith("so101-kinematics")


def test_sim_compare_report_refuses_a_file_that_is_not_a_png(tmp_path):
    log = tmp_path / "run.csv"
    log.write_text("t_s\n")
    figure = tmp_path / "figure.png"
    figure.write_text("a drawing in another format\n")
    done = run("pick_place_sim.py", "--compare", log, "--report", figure)
    assert_refused(done, "--report", figure, figure.read_bytes())


# --- pick_place_hw.py --log / --plot / --sheet ----------------------------------------------
def test_hw_log_refuses_a_calibration_file_in_the_dry_run(tmp_path):
    calibration = tmp_path / "other_arm.json"
    shutil.copy(next(CALIBRATION.rglob("*.json")), calibration)
    before = calibration.read_bytes()
    done = run("pick_place_hw.py", "--dry-run", "--log", calibration)
    assert done.returncode == 2 and "--log" in done.stderr and "--overwrite" in done.stderr
    assert calibration.read_bytes() == before


def test_hw_log_refuses_the_runs_own_trims_even_with_overwrite(tmp_path):
    trims = tmp_path / "trims.toml"
    trims.write_text(TRIMS)
    done = run("pick_place_hw.py", "--dry-run", "--trims", trims, "--log", trims, "--overwrite")
    assert done.returncode == 2 and "input files" in done.stderr
    assert trims.read_text() == TRIMS


def test_hw_plot_refuses_a_source_file(student_file):
    before = student_file.read_bytes()
    done = run("pick_place_hw.py", "--dry-run", "--plot", student_file)
    assert done.returncode == 2 and "--plot" in done.stderr
    assert student_file.read_bytes() == before


def test_hw_log_sidecar_is_checked_too(tmp_path):
    sidecar = tmp_path / "run.run.json"
    sidecar.write_text('{"my": "notes"}')
    done = run("pick_place_hw.py", "--dry-run", "--log", tmp_path / "run.csv")
    assert done.returncode == 2 and "sidecar" in done.stderr
    assert sidecar.read_text() == '{"my": "notes"}'


def test_hw_sheet_replaces_its_own_pdf_and_nothing_else(tmp_path):
    sheet = tmp_path / "sheet.pdf"
    assert run("pick_place_hw.py", "--sheet", sheet).returncode == 0
    assert sheet.read_bytes().startswith(b"%PDF-")
    done = run("pick_place_hw.py", "--sheet", sheet, "--paper", "letter")
    assert done.returncode == 0, done.stderr
    sheet.write_text("my own notes\n")
    done = run("pick_place_hw.py", "--sheet", sheet)
    assert done.returncode == 2 and "--sheet" in done.stderr and "--overwrite" in done.stderr
    assert sheet.read_text() == "my own notes\n"


# --- test_fk_mujoco.py --table / --frames / --screenshot ------------------------------------
def test_fk_table_refuses_a_file_that_is_not_the_table(tmp_path):
    readme = tmp_path / "README.md"
    shutil.copy(REPO / "README.md", readme)
    done = run("test_fk_mujoco.py", "--table", readme)
    assert_refused(done, "--table", readme, readme.read_bytes())


def test_fk_table_replaces_its_own_old_table(tmp_path):
    table = tmp_path / "fk_table.md"
    shutil.copy(REPO / "docs" / "fk_table.md", table)
    table.write_text(table.read_text() + "\nan old line\n")
    done = run("test_fk_mujoco.py", "--table", table)
    assert done.returncode == 0, done.stderr
    assert "an old line" not in table.read_text()


@pytest.mark.parametrize("option", ["--frames", "--screenshot"])
def test_fk_pictures_refuse_a_file_that_is_not_a_png(tmp_path, option):
    picture = tmp_path / "picture.png"
    picture.write_text("not a picture\n")
    done = run("test_fk_mujoco.py", option, picture, "--headless", "--seconds", "0.1")
    assert_refused(done, option, picture, picture.read_bytes())


# --- the checkers -------------------------------------------------------------------------
def test_check_fk_json_refuses_another_students_submission(tmp_path):
    other = tmp_path / "bob" / "so101_forward_kinematics.py"
    other.parent.mkdir()
    shutil.copy(FK_SUBMISSION, other)
    done = run("-m", "so101_kinematics.checker", FK_SUBMISSION, "--json", other)
    assert_refused(done, "--json", other, FK_SUBMISSION.read_bytes())


def test_check_fk_replaces_its_own_report_csv_and_gradescope(tmp_path):
    outputs = {"--json": tmp_path / "r.json", "--csv": tmp_path / "r.csv",
               "--gradescope": tmp_path / "results.json"}
    arguments = [a for option, path in outputs.items() for a in (option, path)]
    for _ in range(2):  # the second run replaces the first's files
        done = run("-m", "so101_kinematics.checker", FK_SUBMISSION, "-q", *arguments)
        assert done.returncode == 0, done.stderr
    assert json.loads(outputs["--json"].read_text())["verdict"] == "pass"


@pytest.mark.parametrize("option", ["--json", "--csv"])
def test_check_ik_refuses_a_source_file(student_file, option):
    before = student_file.read_bytes()
    done = run("-m", "so101_kinematics.checker.ik", IK_SUBMISSION, option, student_file)
    assert_refused(done, option, student_file, before)


@pytest.mark.parametrize("option", ["--json", "--gradescope"])
def test_check_traj_refuses_a_source_file_and_replaces_its_own(student_file, tmp_path, option):
    before = student_file.read_bytes()
    done = run("-m", "so101_kinematics.checker.traj", TRAJ_SUBMISSION, option, student_file)
    assert_refused(done, option, student_file, before)
    ours = tmp_path / "ours.json"
    for _ in range(2):  # the second run replaces the first's file
        done = run("-m", "so101_kinematics.checker.traj", TRAJ_SUBMISSION, "-q", option, ours)
        assert done.returncode == 0, done.stderr
