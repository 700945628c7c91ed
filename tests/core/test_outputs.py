"""Outputs never replace a file they did not write (issue 28, Deliver 3; issue 33, Deliver 3).

An existing target is replaced only when its content carries this project's
marker for this kind of output (a CSV log's header, a JSON report's generator
key naming the same program, an MP4's comment tag, a PNG's Software text chunk,
a PDF's Creator) or with ``--overwrite``; anything else, a symbolic link, and a
log of an earlier run, is refused in one line, exit 2, before anything runs,
and the file is left byte for byte. Each script is run for real, in a child
process, as a student would run it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from so101_kinematics.errors import OutputPathError
from so101_kinematics.outputs import JSON_REPORT, MP4, PDF, PNG, check_output_path, report_of

REPO = Path(__file__).resolve().parents[2]
CALIBRATION = REPO / "calibration"
A_SOURCE_FILE = REPO / "so101_inverse_kinematics.py"
FK_SUBMISSION = REPO / "tests" / "fk_submissions" / "correct.py"
IK_SUBMISSION = REPO / "tests" / "ik_submissions" / "correct.py"
TRAJ_SUBMISSION = REPO / "tests" / "traj_submissions" / "correct.py"
TRIMS = "shoulder_pan = 1.0\n"  # a trim file (TOML): joint -> [deg]


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


def box(kind: bytes, payload: bytes) -> bytes:
    """An ISO base media box (ISO/IEC 14496-12): 32-bit size, 4-byte type, payload."""
    return (8 + len(payload)).to_bytes(4, "big") + kind + payload


def png_bytes(software: str | None) -> bytes:
    """A 4x4 PNG as Pillow writes it, with a ``Software`` text chunk when given."""
    import io

    from PIL import Image, PngImagePlugin

    info = PngImagePlugin.PngInfo()
    if software is not None:
        info.add_text("Software", software)
    buffer = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 30, 30)).save(buffer, format="PNG", pnginfo=info)
    return buffer.getvalue()


def pdf_bytes(creator: str | None) -> bytes:
    """A one-page PDF as matplotlib writes it, its Creator ``creator`` (default: matplotlib)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(2, 2))
    buffer = io.BytesIO()
    fig.savefig(buffer, format="pdf", metadata={"Creator": creator} if creator else None)
    plt.close(fig)
    return buffer.getvalue()


def mp4_bytes(comment: bytes) -> bytes:
    """An MP4's boxes as ffmpeg lays them out (ftyp, mdat, moov with the tags at the end)."""
    tags = box(b"udta", box(b"meta", bytes(4) + box(b"ilst", box(b"\xa9cmt", box(
        b"data", bytes(8) + comment)))))
    return (box(b"ftyp", b"isom\x00\x00\x02\x00isomiso2avc1mp41") + box(b"mdat", bytes(64))
            + box(b"moov", box(b"mvhd", bytes(100)) + tags))


# --- the one check ------------------------------------------------------------------------
@pytest.mark.parametrize("kind, ours, theirs", [
    (PNG, png_bytes("so101-kinematics pick_place_hw.py --plot"), png_bytes(None)),
    (PNG, png_bytes("so101-kinematics x"), png_bytes("GIMP 2.10")),
    (PDF, pdf_bytes("so101-kinematics so101 sheet"), pdf_bytes(None)),
    (PDF, pdf_bytes("so101-kinematics x"), b"%!PS-Adobe-3.0\n"),
    (MP4, mp4_bytes(b"so101-kinematics video"), mp4_bytes(b"Lavf60 imageio")),
    (MP4, mp4_bytes(b"so101-kinematics video"), b"RIFF\x00\x00\x00\x00AVI LIST"),
    (JSON_REPORT, b'{"generator": "so101-kinematics test_ik_mujoco.py", "results": []}',
     b'{"homing_offset": 0, "range_min": 1000}'),
    (report_of("test_ik_mujoco.py"),
     b'{"generator": "so101-kinematics test_ik_mujoco.py", "results": []}',
     b'{"generator": "so101-kinematics so101-check-fk", "verdict": "pass"}'),
], ids=["png-unmarked", "png-other-program", "pdf-unmarked", "pdf-postscript", "mp4-other-tool",
        "mp4-avi", "json-calibration", "json-other-program"])  # a PDF carries its time: as an
# id, two xdist workers collecting a second apart would disagree on the tests' names
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


@pytest.mark.slow
def test_trajectory_test_json_and_plot_refuse_a_source_file(student_file, tmp_path):
    before = student_file.read_bytes()
    done = run("test_trajectory_mujoco.py", "--headless", "--json", student_file)
    assert_refused(done, "--json", student_file, before)
    plot = tmp_path / "tracking.png"
    plot.write_text("a student's notes, named .png by mistake\n")
    done = run("test_trajectory_mujoco.py", "--headless", "--plot", plot)
    assert_refused(done, "--plot", plot, plot.read_bytes())


@pytest.mark.slow
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
    done = run("-m", "so101_kinematics", "compare", log, "--report", figure)
    assert_refused(done, "--report", figure, figure.read_bytes())


# --- pick_place_hw.py --log / --plot, so101 sheet ----------------------------------------------
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


@pytest.mark.slow
def test_hw_sheet_replaces_its_own_pdf_and_nothing_else(tmp_path):
    sheet = tmp_path / "sheet.pdf"
    assert run("-m", "so101_kinematics", "sheet", sheet).returncode == 0
    assert sheet.read_bytes().startswith(b"%PDF-")
    done = run("-m", "so101_kinematics", "sheet", sheet, "--paper", "letter")
    assert done.returncode == 0, done.stderr
    sheet.write_text("my own notes\n")
    done = run("-m", "so101_kinematics", "sheet", sheet)
    assert done.returncode == 2 and "so101 sheet" in done.stderr and "--overwrite" in done.stderr
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


def test_check_fk_json_refuses_another_checkers_report(tmp_path):
    ik_report = tmp_path / "ik_report.json"  # what so101-check-ik --json writes: ours, not its
    text = json.dumps([{"generator": "so101-kinematics so101-check-ik", "verdict": "pass"}])
    ik_report.write_text(text)
    done = run("-m", "so101_kinematics.checker", FK_SUBMISSION, "--json", ik_report)
    assert done.returncode == 2, done.stderr
    assert "not a JSON report of so101-check-fk" in done.stderr
    assert ik_report.read_text() == text


@pytest.mark.parametrize("option", ["--json", "--csv"])
def test_check_ik_refuses_a_source_file(student_file, option):
    before = student_file.read_bytes()
    done = run("-m", "so101_kinematics.checker.ik", IK_SUBMISSION, option, student_file)
    assert_refused(done, option, student_file, before)


@pytest.mark.slow
@pytest.mark.parametrize("option", ["--json", "--gradescope"])
def test_check_traj_refuses_a_source_file_and_replaces_its_own(student_file, tmp_path, option):
    before = student_file.read_bytes()
    done = run("-m", "so101_kinematics.checker.traj", TRAJ_SUBMISSION, option, student_file)
    assert_refused(done, option, student_file, before)
    ours = tmp_path / "ours.json"
    for _ in range(2):  # the second run replaces the first's file
        done = run("-m", "so101_kinematics.checker.traj", TRAJ_SUBMISSION, "-q", option, ours)
        assert done.returncode == 0, done.stderr


# --- issue 33: recognised by content, not by type; links; earlier logs; unwritable places -----
NOD_PLAN = {"steps": [{"name": "up", "configuration": {
    "shoulder_pan": 0, "shoulder_lift": 0, "elbow_flex": 0, "wrist_flex": 0,
    "wrist_roll": 0, "gripper": 0}, "duration": 0.1, "hold": 0.0}], "return_to_start": False}
UNWRITABLE = Path("/proc")  # no file can be created there, not even by root


def tiny_plan(tmp_path) -> Path:
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(NOD_PLAN))
    return plan


def another_programs_video(path: Path) -> bytes:
    """A real MP4 that imageio wrote for another program (no marker of ours)."""
    import imageio.v2 as imageio
    import numpy as np

    with imageio.get_writer(str(path), format="FFMPEG", fps=10, codec="libx264",
                            macro_block_size=1, ffmpeg_log_level="error") as writer:
        for _ in range(3):
            writer.append_data(np.full((32, 32, 3), 90, np.uint8))
    return path.read_bytes()


def test_hw_plot_keeps_another_programs_png(tmp_path):
    photo = tmp_path / "photo.png"
    photo.write_bytes(png_bytes(None))
    done = run("pick_place_hw.py", "--dry-run", "--plot", photo)
    assert_refused(done, "--plot", photo, png_bytes(None))


def test_sim_record_keeps_another_programs_video(tmp_path):
    video = tmp_path / "my_lab_video.mp4"
    before = another_programs_video(video)
    done = run("pick_place_sim.py", "--no-cube", "--no-progress", "--plan", tiny_plan(tmp_path),
               "--record", video)
    assert_refused(done, "--record", video, before)


def test_hw_sheet_keeps_the_courses_handout(tmp_path):
    handout = tmp_path / "assignment8.pdf"
    handout.write_bytes(pdf_bytes(None))  # a PDF matplotlib wrote for someone else
    before = handout.read_bytes()
    done = run("-m", "so101_kinematics", "sheet", handout)
    assert_refused(done, "so101 sheet", handout, before)


def test_sim_json_keeps_another_scripts_report(tmp_path):
    checker_report = tmp_path / "report.json"
    checker_report.write_text('{"generator": "so101-kinematics so101-check-fk", "verdict": "pass"}')
    done = run("pick_place_sim.py", "--headless", "--no-cube", "--no-progress",
               "--plan", tiny_plan(tmp_path), "--json", checker_report)
    assert_refused(done, "--json", checker_report, checker_report.read_bytes())


@pytest.mark.slow
def test_an_output_through_a_symlink_is_refused_and_overwrite_replaces_the_link(tmp_path):
    own = tmp_path / "elsewhere" / "report.json"
    own.parent.mkdir()
    own.write_text('{"generator": "so101-kinematics pick_place_sim.py", "done": true}')
    before = own.read_bytes()
    link = tmp_path / "report.json"
    link.symlink_to(own)
    arguments = ("pick_place_sim.py", "--headless", "--no-cube", "--no-progress",
                 "--plan", tiny_plan(tmp_path), "--json", link)
    done = run(*arguments)
    assert_refused(done, "--json", link, before)
    assert "symbolic link" in done.stderr and link.is_symlink()
    done = run(*arguments, "--overwrite")
    assert done.returncode == 0, done.stderr
    assert not link.is_symlink() and json.loads(link.read_text())["generator"].startswith(
        "so101-kinematics pick_place_sim.py")
    assert own.read_bytes() == before  # the file the link pointed to: untouched


@pytest.mark.slow
def test_the_markers_are_written(tmp_path):
    """Each writer's file carries its marker: a second run replaces the first's file (the sheet's
    PDF: test_hw_sheet_replaces_its_own_pdf_and_nothing_else)."""
    shot = tmp_path / "shot.png"
    for _ in range(2):
        done = run("test_fk_mujoco.py", "--screenshot", shot, "--headless", "--seconds", "0.1")
        assert done.returncode == 0, done.stderr
        assert PNG.recognise(shot)
    import mujoco

    from so101_kinematics.sim.scene import load_model
    from so101_kinematics.sim.video import VideoRecorder

    m = load_model()
    d = mujoco.MjData(m)
    video = tmp_path / "clip.mp4"
    with VideoRecorder(m, d, video, size=(64, 48), progress=False) as recorder:
        for _ in range(3):
            mujoco.mj_step(m, d)
            recorder.capture()
    assert MP4.recognise(video)


@pytest.mark.skipif(not UNWRITABLE.is_dir(), reason="needs Linux's /proc")
@pytest.mark.parametrize("script, option, name", [
    ("pick_place_sim.py", "--json", "r.json"),
    ("pick_place_sim.py", "--record", "v.mp4"),
    ("test_ik_mujoco.py", "--json", "r.json"),
    ("test_trajectory_mujoco.py", "--plot", "p.png"),
])
def test_a_simulator_refuses_an_unwritable_output_before_it_runs(tmp_path, script, option, name):
    extra = (["--no-cube", "--no-progress", "--plan", tiny_plan(tmp_path)]
             if script == "pick_place_sim.py" else [])
    if option != "--record":
        extra.append("--headless")
    done = run(script, *extra, option, UNWRITABLE / name)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert f"{option} {UNWRITABLE / name}" in lines[0] and "Fix:" in lines[0]
    assert "Wrote" not in done.stdout + done.stderr


def _open_elsewhere(path: Path) -> bool:
    """Whether a process has ``path`` open (Linux: its /proc/PID/fd links)."""
    for fd in Path("/proc").glob("[0-9]*/fd/*"):
        try:
            if os.readlink(fd) == str(path):
                return True
        except OSError:  # a process or a descriptor gone meanwhile, or not ours to read
            continue
    return False


def test_a_stop_leaves_no_hidden_part_file(tmp_path):
    """SIGTERM while the video is being written: the temporary file is removed."""
    import signal
    import time

    video = tmp_path / "run.mp4"
    env = {**os.environ, "PYTHONPATH": str(REPO), "MUJOCO_GL": "egl"}
    child = subprocess.Popen([sys.executable, "pick_place_sim.py", "--no-progress",
                              "--record", str(video)], cwd=REPO, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        # frames are being written: ffmpeg has the part file open. Not a fixed wait: on CI's
        # loaded cores ffmpeg was not yet running 0.5 s after the file appeared, and an
        # ffmpeg that opens its output after the stop is the next test's case)
        deadline = time.monotonic() + 300
        while not any(_open_elsewhere(part) for part in tmp_path.glob(".run.mp4.*.part.mp4")):
            assert child.poll() is None, child.stderr.read()
            assert time.monotonic() < deadline, "the recording never began"
            time.sleep(0.05)
        time.sleep(0.5)
        child.send_signal(signal.SIGTERM)
        child.wait(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
    assert list(tmp_path.iterdir()) == []


LATE_WRITER = """
import subprocess, sys, time
from so101_kinematics.outputs import temporary_beside
part = temporary_beside(sys.argv[1])
# an encoder that opens its output late (ffmpeg on loaded cores): its own session, as imageio
# starts it, so the stop signal reaches this program only
subprocess.Popen([sys.executable, "-c", "import sys, time; time.sleep(1.5); "
                  "open(sys.argv[1], 'wb').write(b'frames')", str(part)], start_new_session=True)
print("started", flush=True)
time.sleep(60)
"""


def test_a_stop_before_the_encoder_opens_its_output_leaves_no_part_file(tmp_path):
    """SIGTERM before the encoder (a child) has opened the temporary file: it is stopped first,
    or it would make the file again once it was removed (stop 41's closing note's race)."""
    import signal
    import time

    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-c", LATE_WRITER, str(tmp_path / "run.mp4")],
                             env=env, stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline() == "started\n"
        child.send_signal(signal.SIGTERM)
        assert child.wait(timeout=30) == -signal.SIGTERM
        time.sleep(2.5)  # the writer would have made it 1.5 s after it started
    finally:
        if child.poll() is None:
            child.kill()
    assert list(tmp_path.iterdir()) == []


# --- pick_place_hw.py on the virtual arm ------------------------------------------------------
@pytest.fixture
def arm():
    pytest.importorskip("lerobot")
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as virtual:
        virtual.calibration_path = DEFAULT_CALIBRATION_PATH
        yield virtual


def run_on_virtual_arm(arm, tmp_path, *extra) -> subprocess.CompletedProcess:
    from so101_kinematics.constants import HOME_POSE

    plan = tmp_path / "nod.json"
    plan.write_text(json.dumps({"steps": [{"name": "nod", "configuration": dict(
        HOME_POSE, wrist_flex=50.0), "duration": 0.5, "hold": 0.1}], "return_duration": 0.5}))
    arm.clear_goal_log()
    return run("pick_place_hw.py", "--port", arm.port, "--calibration", arm.calibration_path,
               "--yes", "--plan", plan, *extra)


def refusal(done: subprocess.CompletedProcess) -> list[str]:
    """The lines of stderr but the INFO log's (the calibration's path)."""
    return [line for line in done.stderr.strip().splitlines() if not line.startswith("INFO:")]


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_hw_log_and_sidecar_of_an_earlier_run_are_never_replaced(arm, tmp_path):
    log, plot = tmp_path / "run1.csv", tmp_path / "run1.png"
    first = run_on_virtual_arm(arm, tmp_path, "--log", log, "--plot", plot)
    assert first.returncode == 0, first.stderr
    assert PNG.recognise(plot)
    sidecar = tmp_path / "run1.run.json"
    kept = {path: path.read_bytes() for path in (log, sidecar)}
    second = run_on_virtual_arm(arm, tmp_path, "--log", log)
    lines = refusal(second)
    assert second.returncode == 2 and len(lines) == 1, second.stderr
    assert f"--log {log}" in lines[0] and "earlier run" in lines[0]
    assert str(tmp_path / "run1-2.csv") in lines[0] and "--overwrite" in lines[0]
    assert arm.goal_log() == [] and not any(arm.torque_enabled().values())
    assert {path: path.read_bytes() for path in (log, sidecar)} == kept


@pytest.mark.hw
@pytest.mark.skipif(not UNWRITABLE.is_dir(), reason="needs Linux's /proc")
@pytest.mark.parametrize("option, name", [("--log", "run.csv"), ("--plot", "run.png")])
def test_hw_unwritable_output_is_refused_before_the_port_opens(arm, tmp_path, option, name):
    torque = arm.torque_enabled()  # as the arm powered up
    done = run_on_virtual_arm(arm, tmp_path, option, UNWRITABLE / name)
    lines = refusal(done)
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert f"{option} {UNWRITABLE / name}" in lines[0] and "writable" in lines[0]
    assert arm.goal_log() == [] and arm.torque_enabled() == torque  # the port never opened


# --- virtual_so101.py --link ------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_link_never_replaces_or_deletes_a_users_symlink(tmp_path):
    pytest.importorskip("lerobot")
    notes = tmp_path / "notes.txt"
    notes.write_text("mine\n")
    mylink = tmp_path / "mylink"
    mylink.symlink_to(notes)
    env = {**os.environ, "PYTHONPATH": str(REPO), "MUJOCO_GL": "egl"}
    done = subprocess.run([sys.executable, "virtual_so101.py", "--link", str(mylink)], cwd=REPO,
                          env=env, input="quit\n", capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert f"--link {mylink}" in done.stderr and "Fix:" in done.stderr
    assert mylink.is_symlink() and os.readlink(mylink) == str(notes)
    # a path of its own: made for the run, removed at its end
    fresh = tmp_path / "ttySO101"
    done = subprocess.run([sys.executable, "virtual_so101.py", "--link", str(fresh)], cwd=REPO,
                          env=env, input="quit\n", capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[0].startswith("/dev/pts/")
    assert not fresh.is_symlink()


def test_a_png_written_from_pixels_is_ours_and_replaceable(tmp_path):
    import numpy as np
    from PIL import Image

    from so101_kinematics.outputs import write_png_atomic

    pixels = np.zeros((4, 6, 3), dtype=np.uint8)
    pixels[1, 2] = (255, 0, 0)
    ours = write_png_atomic(tmp_path / "ours.png", pixels, "a test")
    assert PNG.recognise(ours)
    assert np.array_equal(np.asarray(Image.open(ours)), pixels)
    check_output_path(ours, "--image", kind=PNG)  # replaceable without --overwrite
    theirs = tmp_path / "theirs.png"
    Image.fromarray(pixels).save(theirs)  # the same pixels, no marker
    with pytest.raises(OutputPathError, match="not a PNG image written by this project"):
        check_output_path(theirs, "--image", kind=PNG)
