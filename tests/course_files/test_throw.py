"""throw.py: the TA's command, its report, and the one-line refusals (exit 2)."""

from __future__ import annotations

import json

import pytest

import throw


def _refused(capsys, *argv) -> str:
    assert throw.main(list(argv)) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "Fix:" in lines[0]
    return lines[0]


@pytest.mark.parametrize(("argv", "said"), [
    (("--trials", "0"), "--trials: 0 is not in [1, 100]"),
    (("--trials", "many"), "--trials"),
    (("--seed", "-1"), "--seed: -1 is not in [0, 999999]"),
    (("--cup", "0.95", "0"), "outside the pingpong ball's throwing range 0.25-0.90 m"),
    (("--cup", "0.6", "0", "--supply", "9"), "needs a release faster than"),
    (("--measure-opening",), "--measure-opening is for an arm: it needs --port PORT"),
    (("--port", "/dev/ttyACM-none", "--trials", "6"), "--trials 6 with --port"),
])
def test_bad_input_is_refused_in_one_line(capsys, argv, said):
    assert said in _refused(capsys, *argv, "--headless")


def test_the_report_has_the_hits_and_each_trials_figures(tmp_path, capsys):
    path = tmp_path / "throws.json"
    assert throw.main(["--headless", "--trials", "1", "--seed", "3", "--json", str(path)]) == 0
    report = json.loads(path.read_text())
    assert report["hits"] == sum(t["in_cup"] for t in report["trials"]) == 1
    trial = report["trials"][0]
    assert isinstance(trial["in_cup"], bool) and 0.0 <= trial["model_error_m"] < 0.03
    assert "1/1 in the cup" in capsys.readouterr().out


def test_the_opening_delay_line_says_what_was_measured_and_what_to_pass():
    from so101_kinematics.lab.throw_arm import opening_line

    measured = {"supply_v": 12.1, "samples": 41, "moved_s": 0.054, "free_s": 0.1534,
                "simulator_s": 0.152}
    line = opening_line("/dev/ttyACM0", measured)
    assert line.startswith("Opening delay at rest on /dev/ttyACM0 (12.1 V, 41 read-backs)")
    assert "after 0.054 s" in line and "after 0.153 s" in line
    assert line.endswith("the simulator's 0.152 s (use: --opening-delay 0.153)")
    never = opening_line("/dev/ttyACM0", dict(measured, moved_s=None, free_s=None))
    assert "after -," in never and never.endswith("(use: --opening-delay S)")
