"""The package's folders are its architecture: who may import whom (docs/architecture.md)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "so101_kinematics"
COURSE_FILES = {"so101_forward_kinematics", "so101_mujoco_utils", "so101_inverse_kinematics",
                "test_fk_mujoco", "test_ik_mujoco", "test_trajectory_mujoco", "pick_place_sim",
                "pick_place_hw", "read_position", "virtual_so101", "so101_utils"}
MAY_IMPORT = {
    "core": {"core", "ik"},
    "ik": {"core", "ik"},
    "sim": {"core", "ik", "sim"},
    "hw": {"core", "ik", "hw"},
    "virtual": {"core", "sim", "virtual"},
    "lab": {"core", "ik", "sim", "hw", "virtual", "lab"},
}
"""Layer -> the layers it may import. hw and virtual are interchangeable backends: neither
imports the other; the core imports no backend; nothing imports the course's files."""


def layer(module: str) -> str:
    """so101_kinematics.hw.bus -> "hw"; so101_kinematics.planning.motion -> "core"."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 and parts[1] in MAY_IMPORT else "core"


def imports_of(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names
                         if node.module == "so101_kinematics")
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


MODULES = sorted(PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_each_module_imports_only_what_its_layer_may(path):
    name = ".".join(("so101_kinematics", *path.relative_to(PACKAGE).with_suffix("").parts))
    name = name.removesuffix(".__init__")
    mine = layer(name)
    for imported in imports_of(path):
        top = imported.split(".")[0]
        assert top not in COURSE_FILES, f"{name} imports the course's file {imported}"
        if top == "so101_kinematics" and imported != "so101_kinematics":
            assert layer(imported) in MAY_IMPORT[mine], f"{name} ({mine}) imports {imported}"


def test_the_rules_can_catch_a_backend_importing_the_other(tmp_path):
    rogue = tmp_path / "rogue.py"
    rogue.write_text("from so101_kinematics.virtual.arm import VirtualSO101\n")
    assert layer("so101_kinematics.virtual.arm") not in MAY_IMPORT["hw"]
    assert "so101_kinematics.virtual.arm" in imports_of(rogue)


def test_size_limits_of_the_layout():
    """The course's files stay short; no module of the package grows past one idea's size."""
    root = PACKAGE.parent
    scripts = [p for p in root.glob("*.py")]
    assert {p.stem for p in scripts} == COURSE_FILES
    assert max(len(p.read_text().splitlines()) for p in scripts) <= 300
    assert max(len(p.read_text().splitlines()) for p in MODULES) <= 400
