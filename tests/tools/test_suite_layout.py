"""The test suite's shape: folders mirroring the package, a quick tier touching every module.

``./dev.sh test`` runs the quick tier (every test not marked ``slow``); ``./dev.sh test-all`` runs
everything. A module that only slow tests reach would go unchecked by the command students and
maintainers run most, so the quick tier's files must reach every module of the package: through
their imports, the course files they import, and the package's own imports from there (the
closure, read from the source with ``ast``; a ``python -m so101_kinematics...`` in a test counts).
"""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TESTS = REPO / "tests"
PACKAGE = REPO / "so101_kinematics"
AREAS = {"core", "sim", "hw", "virtual", "checker", "planning", "ik", "lab", "vision", "drawing",
         "throwing", "two_arms", "course_files", "tools", "docs"}
"""tests/<area>/: a package subfolder, ``core`` for the package's top-level modules,
``course_files`` for the course's files at the root, ``tools`` for dev.sh, CI, the benchmarks
and this suite, ``docs`` for the documentation."""


def module_name(path: Path) -> str:
    name = ".".join(path.relative_to(REPO).with_suffix("").parts)
    return name.removesuffix(".__init__")


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
COURSE_FILES = {p.stem: p for p in REPO.glob("*.py")}
TEST_FILES = sorted(TESTS.rglob("test_*.py"))


def imported_names(path: Path) -> set[str]:
    """Every module name ``path`` imports anywhere (functions too), or names in a string."""
    found = set()
    package = module_name(path)
    if path.name != "__init__.py":
        package = package.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from .x import y
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            found |= named_in_text(node.value, package)
    return found


def named_in_text(text: str, package: str) -> set[str]:
    """Modules a string runs: ``-m so101_kinematics.checker`` (its ``__main__`` too), code given
    to ``python -c`` (``from so101_kinematics.virtual import emulator``), a sibling's file name
    (``Path(__file__).with_name("probe.py")``)."""
    found = set()
    for match in re.finditer(r"from (so101_kinematics[\w.]*) import (\w+)", text):
        found |= {match[1], f"{match[1]}.{match[2]}"}
    for name in re.findall(r"so101_kinematics(?:\.\w+)*", text):
        found |= {name, f"{name}.__main__"}
    if re.fullmatch(r"\w+\.py", text):
        found.add(f"{package}.{text[:-3]}")
    return found


def reached(name: str) -> set[str]:
    """The package modules (and parents) a name stands for: a.b.c -> a, a.b, a.b.c if modules."""
    parts = name.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1)} & MODULES.keys()


def closure(seeds: set[str]) -> set[str]:
    seen, todo = set(), set(seeds)
    while todo:
        name = todo.pop()
        for module in reached(name) | ({name} & COURSE_FILES.keys()):
            if module in seen:
                continue
            seen.add(module)
            todo |= imported_names(MODULES.get(module) or COURSE_FILES[module])
    return seen


def has_quick_tests(path: Path) -> bool:
    """True when a test of the file is not marked ``slow`` (itself or by its ``pytestmark``)."""
    body = ast.parse(path.read_text()).body
    for node in body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "pytestmark"
                                                for t in node.targets):
            if "slow" in ast.unparse(node.value):
                return False
    return any(isinstance(node, ast.FunctionDef) and node.name.startswith("test")
               and not any("slow" in ast.unparse(d) for d in node.decorator_list)
               for node in body)


def test_each_test_file_sits_in_an_area_folder_with_a_name_of_its_own():
    misplaced = [str(p.relative_to(TESTS)) for p in TEST_FILES
                 if len(p.relative_to(TESTS).parts) != 2 or p.parent.name not in AREAS]
    assert not misplaced, f"test files outside tests/<area>/ ({sorted(AREAS)}): {misplaced}"
    names = [p.name for p in TEST_FILES]
    twice = sorted({n for n in names if names.count(n) > 1})
    # pytest's default import mode puts each test folder on sys.path: equal basenames collide
    assert not twice, f"test file names used twice: {twice}; name each after what it tests"


def test_the_quick_tier_reaches_every_package_module():
    quick = [p for p in TEST_FILES if has_quick_tests(p)]
    seeds = set()
    for path in [*quick, TESTS / "conftest.py", TESTS / "hw_fakes.py"]:
        seeds |= imported_names(path)
    missing = sorted(set(MODULES) - closure(seeds))
    assert not missing, f"no quick test reaches {missing}: add one, or un-slow one that does"


def test_the_closure_can_tell_a_module_nobody_imports(tmp_path):
    """The check above is not vacuous: a module only slow files import is found missing."""
    leaf = "so101_kinematics.hw.home_check"
    assert leaf in closure({leaf})
    assert leaf not in closure({"so101_kinematics.errors"})


@pytest.mark.parametrize("name", sorted(n for n in MODULES if not n.endswith("__main__")))
def test_every_package_module_imports(name):
    """Importable without the hw extra's lerobot where the module does not need it."""
    try:
        importlib.import_module(name)
    except ModuleNotFoundError as error:
        if error.name and error.name.split(".")[0] in {"lerobot", "scservo_sdk", "serial"}:
            pytest.skip(f"{name} needs the hw extra ({error.name})")
        raise


GROUPED = '''
import os
import pytest

@pytest.mark.parametrize("k", range(4))
def test_static(k, tmp_path_factory):
    (tmp_path_factory.getbasetemp().parent.parent / f"static-{k}").write_text(
        os.environ["PYTEST_XDIST_WORKER"])

@pytest.mark.parametrize("k", range(4))
def test_added(k, tmp_path_factory):
    (tmp_path_factory.getbasetemp().parent.parent / f"added-{k}").write_text(
        os.environ["PYTEST_XDIST_WORKER"])
'''
ADDS_THE_GROUP = '''
import pytest

@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.name.startswith("test_added"):
            item.add_marker(pytest.mark.xdist_group("added"))
'''


def test_xdist_keeps_each_group_on_one_worker(tmp_path):
    # the virtual arms' lock (a file that takes it alone runs on one worker) and the shared
    # module fixtures rely on --dist loadgroup; with pytest 9.2 and xdist 3.8 it grouped
    # nothing, silently (pytest-xdist issue 1386; pyproject.toml pins pytest below 9.2)
    import subprocess
    import sys

    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "run").mkdir()
    (tmp_path / "conftest.py").write_text(ADDS_THE_GROUP)
    (tmp_path / "test_groups.py").write_text(GROUPED.replace(
        'def test_static', '@pytest.mark.xdist_group("static")\ndef test_static'))
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "-n", "2", "--dist", "loadgroup", "--basetemp",
                           str(tmp_path / "run" / "base"), str(tmp_path)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    for group in ("static", "added"):
        workers = {(tmp_path / "run" / f"{group}-{k}").read_text() for k in range(4)}
        assert len(workers) == 1, f"the {group} group ran on {sorted(workers)}"
