"""The README is not part of the docs site, so Sphinx does not check it: its links and the
scripts its commands name must exist in the repository."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
README = (REPO / "README.md").read_text()


def test_every_relative_link_of_the_readme_exists():
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", README)
    local = [t for t in targets if not re.match(r"[a-z]+://", t)]
    assert "docs/week6.md" in local  # the parser sees the week table's links
    missing = [t for t in local if not (REPO / t).exists()]
    assert not missing, f"README links to files that do not exist: {missing}"


def test_every_script_the_readme_runs_exists():
    scripts = set(re.findall(r"python (?:scripts/)?([\w/]+\.py)", README))
    assert "pick_place_hw.py" in scripts
    missing = [s for s in scripts
               if not (REPO / s).exists() and not (REPO / "scripts" / s).exists()]
    assert not missing, f"README runs scripts that do not exist: {missing}"
