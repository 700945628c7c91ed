"""pick_place_hw.py's command line without an arm: prompts, refusals, dry run, no lerobot."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hw_fakes import HOME, FakeBus, FakeClock, make_session  # noqa: F401

import pick_place_hw as cli
from so101_kinematics.errors import CalibrationError, ConnectionFailed
from so101_kinematics.hw.bus import bus_errors

REPO = Path(__file__).resolve().parents[2]
VIRTUAL_CALIBRATION = REPO / "calibration" / "virtual_so101.json"


# --- prompts and the command line ---------------------------------------------------------
def test_prompt_never_blocks_without_a_terminal():
    class Pipe:
        def isatty(self):
            return False

        def readline(self):
            raise AssertionError("must not read")

    assert cli.ask("Go?", assume_yes=True, stdin=Pipe())
    with pytest.raises(cli.NotConfirmed, match="--yes"):
        cli.ask("Go?", assume_yes=False, stdin=Pipe())

    class Terminal:
        def __init__(self, answer):
            self.answer = answer

        def isatty(self):
            return True

        def readline(self):
            return self.answer

    assert cli.ask("Go?", False, Terminal("y\n"))
    assert not cli.ask("Go?", False, Terminal("\n"))


def test_dry_run_prints_plan_and_cube_positions(capsys):
    assert cli.main(["--dry-run", "--calibration", str(VIRTUAL_CALIBRATION)]) == 0
    out = capsys.readouterr().out
    assert "Dry run: the plan is valid; nothing was sent" in out
    assert "pick  (start_open): x = 23.0 cm, y = 19.0 cm" in out


def test_dry_run_refuses_a_bad_waypoint_file(tmp_path, capsys):
    plan = {"steps": [{"name": "reach", "configuration": dict(HOME, shoulder_lift=120.0)}]}
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan))
    args = ["--dry-run", "--calibration", str(VIRTUAL_CALIBRATION), "--plan", str(path)]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert "shoulder_lift = 120" in err and "'reach'" in err and "nothing moved" in err


def test_a_real_run_needs_to_know_which_arm(capsys):
    assert cli.main(["--port", "/dev/ttyACM0", "--yes"]) == 2
    assert "--id ROBOT_ID" in capsys.readouterr().err


def test_bad_rate_is_refused(capsys):
    assert cli.main(["--dry-run", "--rate", "0"]) == 2
    assert "rate" in capsys.readouterr().err


def _run_without_lerobot(args: list[str]) -> subprocess.CompletedProcess:
    code = (f"import sys; sys.modules['lerobot'] = None; sys.path.insert(0, {str(REPO)!r}); "
            f"import pick_place_hw; rc = pick_place_hw.main({args!r}); "
            "assert 'torch' not in sys.modules; sys.exit(rc)")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=120, cwd=REPO)


def test_help_and_dry_run_work_without_lerobot():
    help_run = subprocess.run([sys.executable, str(REPO / "pick_place_hw.py"), "--help"],
                              capture_output=True, text=True, timeout=60, cwd=REPO)
    assert help_run.returncode == 0 and "--dry-run" in help_run.stdout
    dry = _run_without_lerobot(["--dry-run", "--calibration", str(VIRTUAL_CALIBRATION)])
    assert dry.returncode == 0, dry.stderr
    assert "nothing was sent" in dry.stdout


def test_without_lerobot_a_real_run_says_how_to_install_it(tmp_path):
    run = _run_without_lerobot(["--port", str(tmp_path / "ttyACM0"), "--yes",
                                "--calibration", str(VIRTUAL_CALIBRATION)])
    assert run.returncode == 2
    assert "pip install -e '.[hw]'" in run.stderr


def test_bus_failures_while_setting_up_say_what_to_do():
    with pytest.raises(ConnectionFailed) as info:
        with bus_errors("configuring the servos"):
            raise RuntimeError("Failed to write 'P_Coefficient' on id_=3 after 1 tries.")
    assert "configuring the servos" in str(info.value) and "id_=3" in str(info.value)
    assert "power supply" in str(info.value)
    with pytest.raises(CalibrationError):  # our own errors pass through unchanged
        with bus_errors("reading"):
            raise CalibrationError("mismatch")


def test_outputs_are_checked_before_anything_moves(tmp_path, capsys):
    calibration = tmp_path / "arm.json"
    calibration.write_text(VIRTUAL_CALIBRATION.read_text())
    before = calibration.read_text()
    base = ["--port", str(tmp_path / "ttyACM0"), "--calibration", str(calibration), "--yes"]
    assert cli.main(base + ["--log", str(tmp_path)]) == 2
    assert f"--log {tmp_path}: is a folder" in capsys.readouterr().err
    assert cli.main(base + ["--log", str(calibration)]) == 2
    assert "is one of this run's input files" in capsys.readouterr().err
    assert calibration.read_text() == before
    assert cli.main(base + ["--plot", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err


@pytest.mark.parametrize("option, value", [
    ("--max-speed", "0"), ("--max-speed", "1e9"), ("--move-duration", "1e9"),
    ("--move-duration", "-1"), ("--hold", "nan"), ("--rate", "5000"),
    ("--tracking-tolerance", "90"),
])
def test_numbers_out_of_range_are_refused_with_the_range(option, value, capsys):
    assert cli.main(["--dry-run", option, value]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("Refused, nothing moved: " + option)
    assert "Fix:" in err and ("[0, " in err or "(0, " in err or "[20, 500]" in err)
