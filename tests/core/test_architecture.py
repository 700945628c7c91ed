"""The package's folders are its architecture: who may import whom (docs/architecture.md)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "so101_kinematics"
COURSE_FILES = {"so101_forward_kinematics", "so101_mujoco_utils", "so101_inverse_kinematics",
                "test_fk_mujoco", "test_ik_mujoco", "test_trajectory_mujoco", "pick_place_sim",
                "pick_place_hw", "read_position", "virtual_so101", "so101_utils", "see_and_pick",
                "follow_tag", "calibrate_camera", "draw", "light_paint", "throw", "register_page",
                "two_arms"}
MAY_IMPORT = {
    "core": {"core", "ik"},
    "ik": {"core", "ik"},
    "sensors": {"core", "sensors"},
    "sim": {"core", "ik", "sensors", "sim"},
    "hw": {"core", "ik", "sensors", "hw"},
    "virtual": {"core", "sensors", "sim", "virtual"},
    "vision": {"core", "ik", "sensors", "sim", "vision"},
    "drawing": {"core", "ik", "sensors", "sim", "vision", "drawing"},
    "throwing": {"core", "ik", "sensors", "sim", "vision", "throwing"},
    "two_arms": {"core", "ik", "sensors", "sim", "two_arms"},
    "lab": {"core", "ik", "sensors", "sim", "hw", "virtual", "vision", "drawing", "throwing",
            "two_arms", "lab"},
    "commands": {"core", "ik", "sensors", "sim", "hw", "virtual", "vision", "drawing",
                 "throwing", "two_arms", "lab", "commands"},
}
"""Layer -> the layers it may import. hw and virtual are interchangeable backends: neither
imports the other; the core imports no backend; sensors sit beside the core, under every
backend (a sensor rides on a backend's transport, passed in); vision (cameras, tags, their
poses) sits on the simulator, and neither backend imports it: the lab and the commands may;
drawing (strokes, the pen's path, the simulator's ink, the light painting's exposure through
a camera) sits on vision and the simulator; throwing (the ball's flight, the release the
servos reach, the throw, the cup found by a camera) sits on vision and the simulator;
nothing imports the course's files."""


def layer(module: str) -> str:
    """so101_kinematics.hw.bus -> "hw"; so101_kinematics.planning.motion -> "core"."""
    parts = module.split(".")
    if module == "so101_kinematics.__main__":  # python -m so101_kinematics: the so101 command
        return "commands"
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
    """The course's files stay short; a module's size is a backstop, not the rule (below)."""
    root = PACKAGE.parent
    scripts = [p for p in root.glob("*.py")]
    assert {p.stem for p in scripts} == COURSE_FILES
    assert max(len(p.read_text().splitlines()) for p in scripts) <= 300
    too_long = {str(p.relative_to(PACKAGE)): n for p in MODULES
                if (n := len(p.read_text().splitlines())) > MODULE_LINES_BACKSTOP}
    assert too_long == {}, "a module this long holds more than one idea: split it by idea"


MODULE_LINES_BACKSTOP = 500
"""A module past this many lines is checked by hand: the rules below are the real ones."""

FUNCTION_LINES = 80
"""A function's body past this many lines (its docstring aside) does more than one step."""

LONG_FUNCTIONS = {
    "sim/sts3215.py:torques": "the servo firmware's loop for one physics step, kept inline: "
    "the simulator's hot path (benchmarks/bench_pick_place.py)",
    "fast_fk.py:forward_kinematics_batch": "the closed-form FK unrolled on preallocated buffers "
    "(benchmarks/bench_fk.py measures it)",
}
"""Functions allowed past FUNCTION_LINES, each with its reason; the list only shrinks."""


def function_lengths(path: Path, base: Path = PACKAGE) -> dict[str, int]:
    """``path:name`` -> the lines of each function's body, its docstring not counted."""
    lengths = {}
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0]
            docstring = (first.end_lineno - first.lineno + 1 if isinstance(first, ast.Expr)
                         and isinstance(first.value, ast.Constant)
                         and isinstance(first.value.value, str) else 0)
            key = f"{path.relative_to(base).as_posix()}:{node.name}"
            lengths[key] = max(lengths.get(key, 0), node.end_lineno - node.lineno + 1 - docstring)
    return lengths


def test_long_functions_are_split():
    lengths = {k: n for p in MODULES for k, n in function_lengths(p).items()}
    too_long = {k: n for k, n in lengths.items() if n > FUNCTION_LINES and k not in LONG_FUNCTIONS}
    assert too_long == {}, f"split each into named steps (at most {FUNCTION_LINES} lines)"
    fixed = {k for k in LONG_FUNCTIONS if lengths.get(k, 0) <= FUNCTION_LINES}
    assert fixed == set(), "short enough now (or gone): drop them from LONG_FUNCTIONS"


def test_function_lengths_count_the_body_not_the_docstring(tmp_path):
    module = tmp_path / "rogue.py"
    module.write_text('def f():\n    """Doc.\n\n    More.\n    """\n    x = 1\n    return x\n')
    assert function_lengths(module, tmp_path) == {"rogue.py:f": 3}


def test_no_two_modules_share_a_file_name():
    """A file name says one thing: ``checks.py`` in two folders is two things under one name."""
    stems = {}
    for path in MODULES:
        if path.stem not in ("__init__", "__main__"):
            stems.setdefault(path.stem, []).append(str(path.relative_to(PACKAGE)))
    assert {stem: paths for stem, paths in stems.items() if len(paths) > 1} == {}


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_each_module_says_its_one_thing_in_its_first_line(path):
    """The docstring's first line is one sentence (at most 100 characters) saying what it is."""
    docstring = ast.get_docstring(ast.parse(path.read_text()))
    assert docstring, f"{path.relative_to(PACKAGE)} has no docstring"
    first = docstring.splitlines()[0]
    assert first.strip() and len(first) <= 100 and first.rstrip().endswith((".", ":", "?")), first
