"""The README and the docs pages: every shell and Python block runs, or says why it does not.

A fenced block in ``bash``, ``sh``, ``shell``, ``console`` or ``python`` is either run here
(Python blocks in a subprocess from the repository root; a shell block only when every
command in it is a cheap ``--help``) or preceded by a line ``<!-- not run: REASON -->`` with
a reason. Also: the README stays a two-minute read (at most 200 lines), and no page cites
the workplace's notes folder beside the clone (:data:`OUTSIDE`: a user's clone has none).
The site itself is built by ``./dev.sh docs``; ``test_docs_site_builds`` builds it here when
Sphinx is installed.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SHELL = {"bash", "sh", "shell", "console"}
PYTHON = {"python", "py", "python3"}
MARKER = re.compile(r"^<!--\s*not run:\s*(?P<reason>.*?)\s*-->\s*$")
FENCE = re.compile(r"^(?P<fence>`{3,}|~{3,})\s*(?P<lang>[^\s`]*)")
# A shell command cheap enough to run: a script's or a module's --help.
CHEAP = re.compile(r"^(python3? (-m [\w.]+|[\w/.-]+\.py)|so101-[\w-]+) --help$")
README_MAX_LINES = 200


@dataclass
class Block:
    path: Path
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    reason: str | None  # the not-run marker's reason; None without a marker

    @property
    def name(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}"


def doc_files() -> list[Path]:
    """The README, the changelog and every Markdown page of docs/ (not generated ones)."""
    pages = sorted(p for p in (REPO / "docs").glob("*.md") if not p.name.startswith("_"))
    return [REPO / "README.md", REPO / "CHANGELOG.md", *pages]


def blocks_of(path: Path, text: str | None = None) -> list[Block]:
    """The shell and Python fenced blocks of one Markdown file, with their markers."""
    lines = (path.read_text() if text is None else text).splitlines()
    found, i = [], 0
    while i < len(lines):
        opening = FENCE.match(lines[i])
        if not opening:
            i += 1
            continue
        fence, lang = opening["fence"], opening["lang"].lower()
        end = i + 1
        while end < len(lines) and not lines[end].startswith(fence):
            end += 1
        if lang in SHELL | PYTHON:
            before = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            marker = MARKER.match(before.strip())
            reason = marker["reason"] if marker and marker["reason"] else None
            found.append(Block(path, i + 1, "python" if lang in PYTHON else "shell",
                               "\n".join(lines[i + 1:end]) + "\n", reason))
        i = end + 1
    return found


def shell_commands(code: str) -> list[str]:
    """A shell block's commands: its lines without comments, blank lines and prompts."""
    commands = []
    for line in code.splitlines():
        line = line.split(" #")[0].strip()
        if line.startswith("$ "):
            line = line[2:]
        if line and not line.startswith("#"):
            commands.append(line)
    return commands


def runs_here(block: Block) -> bool:
    """Whether this test runs the block (Python always; shell only cheap --help commands)."""
    if block.reason is not None:
        return False
    if block.lang == "python":
        return True
    commands = shell_commands(block.code)
    return bool(commands) and all(CHEAP.match(command) for command in commands)


ALL_BLOCKS = [block for path in doc_files() if path.exists() for block in blocks_of(path)]
RUN = [block for block in ALL_BLOCKS if runs_here(block)]


def test_every_block_is_run_or_says_why_not():
    unmarked = [f"{b.name} ({b.lang})" for b in ALL_BLOCKS
                if b.reason is None and not runs_here(b)]
    assert not unmarked, (
        "blocks neither run by this test nor marked '<!-- not run: REASON -->' on the line "
        "before them: " + ", ".join(unmarked))


def test_the_docs_have_blocks_and_some_run():
    # The parser found the README's blocks and the week pages' Python examples.
    assert any(b.path.name == "README.md" for b in ALL_BLOCKS)
    assert any(b.lang == "python" for b in RUN)


def test_a_marker_needs_a_reason():
    text = ("<!-- not run: -->\n```bash\npython pick_place_hw.py\n```\n\n"
            "<!-- not run: needs an arm -->\n\n```bash\npython pick_place_hw.py\n```\n"
            "```python\nprint(1)\n```\n```text\nnot code\n```\n"
            "```bash\npython pick_place_sim.py --help  # cheap\n```\n")
    empty, marked, python, cheap = blocks_of(REPO / "README.md", text)
    assert empty.reason is None and not runs_here(empty)
    assert marked.reason == "needs an arm" and not runs_here(marked)
    assert python.lang == "python" and runs_here(python)
    assert runs_here(cheap)


def _environment() -> dict[str, str]:
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO),
                                                              environment.get("PYTHONPATH")]))
    environment["MUJOCO_GL"] = "egl"
    return environment


@pytest.mark.parametrize("block", RUN, ids=[b.name for b in RUN])
def test_block_runs(block):
    if block.lang == "python":
        command = [sys.executable, "-c", block.code]
    else:  # every line a --help: run with this interpreter as "python"
        script = block.code.replace("python3 ", "python ").replace(
            "python ", f"{sys.executable} ")
        command = ["bash", "-e", "-c", "\n".join(shell_commands(script))]
    done = subprocess.run(command, cwd=REPO, env=_environment(), capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, f"{block.name} failed:\n{done.stdout}\n{done.stderr}"


def test_readme_is_a_two_minute_read():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"


OUTSIDE = re.compile(r"\.\./shared\b")
"""A citation of the notes folder beside the clone (the sources are cited in the repository)."""


def test_no_page_cites_a_folder_outside_the_repository():
    citing = [str(p.relative_to(REPO)) for p in doc_files()
              if p.exists() and OUTSIDE.search(p.read_text())]
    assert not citing, f"cite the original source inside the repository instead: {citing}"


@pytest.mark.slow
def test_docs_site_builds(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q",
                           "-b", "html", "docs", str(tmp_path / "html")],
                          cwd=REPO, env=_environment(), capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
