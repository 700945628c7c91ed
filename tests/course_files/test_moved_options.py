"""The course scripts' --help is the week's options; the tool modes moved to `so101` (issue 35).

An old option is refused in one line that gives its new spelling, exit 2, before anything runs.
"""

from __future__ import annotations

import re

import pytest

import pick_place_hw
import pick_place_sim
import virtual_so101
from so101_kinematics.commands import so101_command

MOVED = [(pick_place_sim, ["--compare", "run.csv", "--report", "r.png"], "--compare",
          "so101 compare"),
         (pick_place_sim, ["--headless", "--report", "r.png"], "--report", "so101 compare"),
         (pick_place_hw, ["--sheet", "s.pdf"], "--sheet", "so101 sheet"),
         (pick_place_hw, ["--dry-run", "--paper", "letter"], "--paper", "so101 sheet"),
         (virtual_so101, ["--write-default-calibration", "c.json"], "--write-default-calibration",
          "so101 virtual-calibration")]


@pytest.mark.parametrize("script, argv, option, new", MOVED,
                         ids=[f"{s.__name__} {o}" for s, _, o, _ in MOVED])
def test_an_old_option_is_refused_in_one_line_with_its_new_spelling(script, argv, option, new,
                                                                   tmp_path, capsys,
                                                                   monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert script.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert f"{option} moved to the so101 command" in err[0] and f"Fix: run `{new} " in err[0]
    assert list(tmp_path.iterdir()) == []  # nothing was run, nothing written


def test_each_new_spelling_names_a_real_subcommand():
    parser = so101_command.build_parser()
    names = set(parser._subparsers._group_actions[0].choices)
    for spelling in {**so101_command.MOVED_FROM_SIM, **so101_command.MOVED_FROM_HW,
                     **so101_command.MOVED_FROM_VIRTUAL}.values():
        assert re.match(r"so101 (\S+)", spelling)[1] in names


def options_listed(help_text: str) -> set[str]:
    return set(re.findall(r"^\s+(--[\w-]+)", help_text, flags=re.M))


def test_the_hardware_script_lists_about_a_dozen_options(capsys):
    with pytest.raises(SystemExit):
        pick_place_hw.build_parser().parse_args(["--help"])
    listed = options_listed(capsys.readouterr().out)
    assert {"--port", "--id", "--calibration", "--plan", "--dry-run", "--log"} <= listed
    assert len(listed - {"--help", "--help-all"}) <= 15, sorted(listed)
    assert not listed & {"--sheet", "--paper", "--compare", "--rate", "--trims"}


def test_help_all_lists_the_expert_options_and_they_still_work(capsys):
    assert pick_place_hw.main(["--help-all"]) == 0
    listed = options_listed(capsys.readouterr().out)
    assert {"--rate", "--max-speed", "--trims", "--approach", "--base-height"} <= listed
    assert "--sheet" not in listed
    assert pick_place_hw.main(["--dry-run", "--rate", "50", "--approach", "straight"]) == 0
    assert "nothing was sent" in capsys.readouterr().out


def test_the_simulator_no_longer_lists_the_comparison(capsys):
    assert pick_place_sim.main(["--help"]) == 0
    listed = options_listed(capsys.readouterr().out)
    assert "--plan" in listed and not listed & {"--compare", "--report", "--supply", "--fps"}
    assert len(listed - {"--help", "--help-all"}) <= 15, sorted(listed)
    assert pick_place_sim.main(["--help-all"]) == 0
    assert {"--supply", "--fps", "--approach"} <= options_listed(capsys.readouterr().out)
