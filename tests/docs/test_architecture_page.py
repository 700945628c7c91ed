"""docs/architecture.md's table names every module of the package in its folder, and no
module that is gone: the page stays one picture of the tree as modules come and go."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "so101_kinematics"
ROW = re.compile(r"^\| (?P<folder>\(top level\)|`\w+/`) \| (?P<modules>.*?) \| .* \|$")


def table(text: str) -> dict[str, list[str]]:
    """Folder ("" for the top level, else e.g. "sim") -> the module names of its row."""
    rows = {}
    for line in text.splitlines():
        row = ROW.match(line)
        if row:
            folder = "" if row["folder"] == "(top level)" else row["folder"].strip("`/")
            rows[folder] = re.findall(r"`(\w+)`", row["modules"])
    return rows


def modules_of(folder: Path) -> set[str]:
    return {f.stem for f in folder.glob("*.py") if f.stem not in ("__init__", "__main__")}


def test_the_table_reader_reads_a_row():
    assert table("| `sim/` | `scene` `cube` | MuJoCo |\n| (top level) | `errors` | x |\n") == {
        "sim": ["scene", "cube"], "": ["errors"]}


def test_every_module_is_on_the_architecture_page():
    rows = table((REPO / "docs" / "architecture.md").read_text())
    folders = {"": PACKAGE} | {d.name: d for d in PACKAGE.iterdir()
                               if d.is_dir() and modules_of(d)}
    assert set(rows) == set(folders), f"folders in the table {sorted(rows)}, in the package " \
        f"{sorted(folders)}"
    for name, folder in folders.items():
        listed, present = set(rows[name]), modules_of(folder)
        assert listed == present, (
            f"docs/architecture.md's row for {name or 'the top level'}: not listed "
            f"{sorted(present - listed)}, no longer there {sorted(listed - present)}")
