"""docs/so101_command.md says what the so101 command does, as the command does.

The page's usage block is the command's own ``--help`` (a block preceded by
``<!-- output of: COMMAND -->`` is COMMAND's output at 80 columns); every option of every
tool subcommand is named on the page; every old spelling the course's scripts refuse
(``MOVED_FROM_*``) is in the page's table with the spelling the refusal gives.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from so101_kinematics.commands.so101_command import (
    MOVED_FROM_HW,
    MOVED_FROM_SIM,
    MOVED_FROM_VIRTUAL,
)

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "so101_command.md"
OUTPUT_OF = re.compile(r"^<!--\s*output of:\s*(?P<command>.+?)\s*(\(.*\))?\s*-->\s*$")


def _environment() -> dict[str, str]:
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO),
                                                              environment.get("PYTHONPATH")]))
    environment["COLUMNS"] = "80"  # argparse wraps its help to the terminal's width
    environment.pop("FORCE_COLOR", None)
    environment["NO_COLOR"] = "1"  # Python 3.14's argparse colours its help otherwise
    return environment


def output_blocks(text: str) -> list[tuple[str, str]]:
    """(command, block) for each fenced block preceded by an ``output of:`` marker."""
    lines = text.splitlines()
    found = []
    for i, line in enumerate(lines):
        marker = OUTPUT_OF.match(line.strip())
        if not marker:
            continue
        start = i + 1
        assert lines[start].startswith("```"), f"{PAGE.name}:{i + 1}: no block after marker"
        end = next(j for j in range(start + 1, len(lines)) if lines[j].startswith("```"))
        found.append((marker["command"], "\n".join(lines[start + 1:end])))
    return found


def run(command: str) -> str:
    argv = shlex.split(command)
    assert argv[0] == "python", f"a marker's command starts with python: {command!r}"
    done = subprocess.run([sys.executable, *argv[1:]], cwd=REPO, env=_environment(),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_the_page_is_in_the_toctree():
    assert re.search(r"^so101_command$", (REPO / "docs" / "index.md").read_text(), re.M)


def test_the_usage_block_is_the_commands_help():
    blocks = output_blocks(PAGE.read_text())
    assert any(command == "python -m so101_kinematics --help" for command, _ in blocks)
    for command, block in blocks:
        assert block.rstrip() == run(command).rstrip(), (
            f"docs/so101_command.md's block for `{command}` is not its output; paste it "
            f"again: COLUMNS=80 {command}")


def test_the_marker_reader_finds_a_block():
    text = "x\n<!-- output of: python -m so101_kinematics --help (why) -->\n```text\na\nb\n```\n"
    assert output_blocks(text) == [("python -m so101_kinematics --help", "a\nb")]


@pytest.mark.parametrize("subcommand", ["compare", "sheet", "tags", "virtual-calibration"])
def test_every_option_of_a_tool_is_on_the_page(subcommand):
    help_text = run(f"python -m so101_kinematics {subcommand} --help")
    options = set(re.findall(r"(?<![\w-])--[a-z][\w-]*(?![\w-])", help_text)) - {"--help"}
    assert options, help_text
    page = PAGE.read_text()
    named = set(re.findall(r"(?<![\w-])--[a-z][\w-]*(?![\w-])", page))
    missing = sorted(options - named)
    assert not missing, f"so101 {subcommand}'s options not on docs/so101_command.md: {missing}"


def test_every_moved_spelling_is_in_the_table():
    page = PAGE.read_text().replace("\\|", "|")
    table = [line for line in page.splitlines() if line.startswith("| `")]
    for old, new in {**MOVED_FROM_SIM, **MOVED_FROM_HW, **MOVED_FROM_VIRTUAL}.items():
        rows = [row for row in table if old in row.split("|")[1]]
        assert rows, f"{old} (moved to `{new}`) is not in docs/so101_command.md's table"
        command = new.split(" PATH")[0].split(" LOG")[0]  # e.g. "so101 compare"
        assert any(command in row for row in rows), (old, new, rows)
