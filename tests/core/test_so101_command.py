"""The so101 command: one console script, a subcommand per tool (issue 35)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from so101_kinematics.checker import fk as fk_checker
from so101_kinematics.commands import so101_command
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

REPO = Path(__file__).resolve().parents[2]
SUBCOMMANDS = {"compare", "sheet", "check-fk", "check-ik", "check-traj", "check-vision",
               "virtual-calibration"}


def tomllib():
    try:
        import tomllib as toml
    except ModuleNotFoundError:  # Python 3.10
        import tomli as toml
    return toml


def run_module(*args: str | Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO), "MUJOCO_GL": "egl"}
    return subprocess.run([sys.executable, "-m", "so101_kinematics", *map(str, args)],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)


def test_so101_is_a_console_script_and_the_old_ones_stay():
    scripts = tomllib().loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["so101"] == "so101_kinematics.commands.so101_command:main"
    assert {"so101-check-fk", "so101-check-ik", "so101-check-traj",
            "so101-check-vision"} <= set(scripts)


def test_python_m_lists_every_subcommand():
    done = run_module("--help")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: so101 ")
    for name in SUBCOMMANDS:
        assert f"    {name}" in done.stdout


def test_an_unknown_subcommand_is_one_line_and_exit_2(capsys):
    assert so101_command.main(["stack-cubes"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "stack-cubes" in err[0] and "Fix:" in err[0]


def test_compare_needs_its_report_figure(tmp_path, capsys):
    assert so101_command.main(["compare", str(tmp_path / "run.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--report" in err[0]


@pytest.mark.parametrize("name", ["check-fk", "check-ik", "check-traj", "check-vision"])
def test_the_checkers_answer_as_their_own_scripts(name, capsys):
    """`so101 check-fk ARGS` is `so101-check-fk ARGS`: same options, same exit codes."""
    assert so101_command.main([name, "--no-such-option"]) == 2
    assert capsys.readouterr().err.startswith(f"so101-{name}: error: ")
    assert so101_command.main([name, "--help"]) == 0
    assert f"usage: so101-{name}" in capsys.readouterr().out


def test_check_fk_reports_a_missing_file_as_the_checker_does(tmp_path, capsys):
    missing = str(tmp_path / "my_fk.py")
    assert so101_command.main(["check-fk", missing]) == fk_checker.main([missing]) == 2
    first, second = capsys.readouterr().out.split("Checking ")[1:]
    assert first == second and "no such file" in first


def test_sheet_writes_the_course_plan_with_no_arm(tmp_path, capsys):
    sheet = tmp_path / "sheet.pdf"
    assert so101_command.main(["sheet", str(sheet), "--paper", "letter"]) == 0
    assert sheet.read_bytes().startswith(b"%PDF-")
    assert "letter" in capsys.readouterr().out


@pytest.mark.vision
def test_tags_writes_the_printable_tags(tmp_path, capsys):
    tags = tmp_path / "tags.pdf"
    assert so101_command.main(["tags", str(tags)]) == 0
    assert tags.read_bytes().startswith(b"%PDF-")
    assert "DICT_4X4_50" in capsys.readouterr().out


@pytest.mark.vision
def test_tags_board_writes_the_charuco_board(tmp_path, capsys):
    board = tmp_path / "board.pdf"
    assert so101_command.main(["tags", str(board), "--board"]) == 0
    assert board.read_bytes().startswith(b"%PDF-")
    assert "ChArUco board" in capsys.readouterr().out


def test_tags_without_opencv_is_one_line_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 raises ImportError
    assert so101_command.main(["tags", str(tmp_path / "tags.pdf")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install" in err[0] and not (tmp_path / "tags.pdf").exists()


def test_virtual_calibration_writes_the_shipped_file_and_keeps_an_existing_one(tmp_path, capsys):
    """The file the virtual arm ships with (calibration/), derived again from the model."""
    path = tmp_path / "virtual.json"
    assert so101_command.main(["virtual-calibration", str(path)]) == 0
    assert json.loads(path.read_text()) == json.loads(DEFAULT_CALIBRATION_PATH.read_text())
    path.write_text("my notes\n")
    assert so101_command.main(["virtual-calibration", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--overwrite" in err[-1] and path.read_text() == "my notes\n"
