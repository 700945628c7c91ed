"""Supported versions: the README's table, pyproject.toml's pins, the refusals outside them."""

from __future__ import annotations

import re
import stat
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[2]
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
# "| 3.10 | 3.17.0 | ..." rows of the "Supported versions" table (docs/install.md;
# the README's before issue 35).
README_ROWS = dict(re.findall(r"^\| (3\.\d+) \| (\d+\.\d+\.\d+) \|",
                              (REPO / "docs" / "install.md").read_text(), re.MULTILINE))


def requirements_for(python: str, name: str) -> list[Requirement]:
    """The dependencies named ``name`` that apply on Python ``python`` ("3.10")."""
    environment = {"python_version": python, "python_full_version": f"{python}.0"}
    requirements = [Requirement(line) for line in PROJECT["dependencies"]]
    return [r for r in requirements
            if r.name == name and (r.marker is None or r.marker.evaluate(environment))]


def this_python() -> str:
    return f"{sys.version_info.major}.{sys.version_info.minor}"


def test_readme_lists_python_3_10_to_3_13():
    assert list(README_ROWS) == ["3.10", "3.11", "3.12", "3.13"]


def test_requires_python_admits_exactly_the_readme_pythons():
    specifier = SpecifierSet(PROJECT["requires-python"])
    admitted = [f"3.{minor}" for minor in range(6, 20) if f"3.{minor}.0" in specifier]
    assert admitted == list(README_ROWS)


@pytest.mark.parametrize("python", ["3.10", "3.11", "3.12", "3.13"])
def test_each_python_gets_the_readme_mujoco(python):
    (mujoco_pin,) = requirements_for(python, "mujoco")
    assert str(mujoco_pin.specifier) == f"=={README_ROWS[python]}"


def test_tomli_is_installed_where_tomllib_is_missing():
    assert requirements_for("3.10", "tomli")
    assert not requirements_for("3.11", "tomli")


def test_this_python_runs_the_mujoco_its_row_names():
    # The physics was compared for these releases only (README): another
    # MuJoCo in the environment is not a supported setup.
    if this_python() not in README_ROWS:
        pytest.fail(f"Python {this_python()} is not in the README's supported versions")
    assert mujoco.__version__ == README_ROWS[this_python()]


def fake_python(tmp_path: Path, version: str) -> Path:
    """A stand-in interpreter: this Python, reporting ``version`` ("3.9.18") to ``-c`` code."""
    major, minor, micro = (int(part) for part in version.split("."))
    script = tmp_path / f"python{major}.{minor}"
    script.write_text(
        "#!/bin/sh\n"
        '[ "$1" = "-c" ] || exit 3  # dev.sh needs nothing else before it is refused\n'
        f'exec {sys.executable} -c "import platform, sys\n'
        f"sys.version_info = ({major}, {minor}, {micro}, 'final', 0)\n"
        f"platform.python_version = lambda: '{version}'\n"
        'exec(sys.argv[1])" "$2"\n')
    script.chmod(script.stat().st_mode | stat.S_IXUSR)
    return script


def run_dev_sh(tmp_path: Path, python: str) -> subprocess.CompletedProcess:
    environment = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "PYTHON": python,
                   "SO101_VENV_ROOT": str(tmp_path / "venvs")}
    return subprocess.run([str(REPO / "dev.sh"), "sim"], env=environment, capture_output=True,
                          text=True, timeout=60)


@pytest.mark.parametrize("version", ["3.9.18", "3.14.0"])
def test_dev_sh_refuses_a_python_outside_the_matrix_in_one_line(tmp_path, version):
    run = run_dev_sh(tmp_path, str(fake_python(tmp_path, version)))
    assert run.returncode == 1
    assert run.stderr.splitlines() == [
        f"error: Python {version} ('{tmp_path}/python{version.rsplit('.', 1)[0]}') is not "
        "supported: this project needs Python >=3.10,<3.14. Fix: set PYTHON to a supported one, "
        "e.g. PYTHON=python3.12"]
    assert not (tmp_path / "venvs").exists()


@pytest.mark.parametrize("version", ["3.10.0", "3.13.0"])
def test_dev_sh_accepts_the_ends_of_the_matrix(tmp_path, version):
    # The stand-in cannot build an environment, so dev.sh fails later, but not here.
    run = run_dev_sh(tmp_path, str(fake_python(tmp_path, version)))
    assert "not supported" not in run.stderr


def test_dev_sh_says_when_the_interpreter_cannot_run(tmp_path):
    run = run_dev_sh(tmp_path, str(tmp_path / "python3.10"))
    assert run.returncode == 1
    assert run.stderr.splitlines() == [
        f"error: cannot run the Python interpreter '{tmp_path}/python3.10'; this project needs "
        "Python >=3.10,<3.14. Fix: install one and set PYTHON=python3.x"]


def environment_key(tmp_path: Path, pyproject: str, job: str = "sim") -> str:
    """The environment dev.sh's ``job`` would set up for ``pyproject`` (a copy of dev.sh beside it).

    A stand-in Python answers ``-V`` and the version check, then cannot build the
    environment: dev.sh names it ("Setting up ...") and stops there.
    """
    folder = tmp_path / f"clone{len(list(tmp_path.iterdir()))}"
    folder.mkdir()
    (folder / "dev.sh").write_text((REPO / "dev.sh").read_text())
    (folder / "dev.sh").chmod(0o755)
    (folder / "pyproject.toml").write_text(pyproject)
    python = folder / "python3.11"
    python.write_text('#!/bin/sh\n[ "$1" = "-V" ] && { echo "Python 3.11.7"; exit 0; }\n'
                      f'[ "$1" = "-c" ] && exec {sys.executable} "$@"\nexit 3\n')
    python.chmod(0o755)
    run = subprocess.run([str(folder / "dev.sh"), job], capture_output=True, text=True,
                         timeout=60, env={"PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
                                          "PYTHON": str(python),
                                          "SO101_VENV_ROOT": str(tmp_path / "venvs")})
    (name,) = re.findall(r"Setting up \S*/(venv-[0-9a-f]{16}-[a-z,]+) ", run.stderr)
    return name


def test_the_environment_is_keyed_by_the_dependencies_only(tmp_path):
    pyproject = (REPO / "pyproject.toml").read_text()
    key = environment_key(tmp_path, pyproject)
    # A console script or a tool setting rebuilds nothing (a hw environment is ~9 GB) ...
    scripts = pyproject.replace("[project.scripts]\n", '[project.scripts]\nx-y = "a.b:main"\n')
    tools = pyproject.replace("line-length = 100", "line-length = 99")
    assert scripts != pyproject and tools != pyproject
    assert environment_key(tmp_path, scripts) == key
    assert environment_key(tmp_path, tools) == key
    # ... a dependency does, in the main list or in an extra: the extra's own environments only
    # (a docs or dev tool added must not rebuild the sim environment, nor the docs one the hw one).
    added = pyproject.replace('    "numpy>=1.24",\n', '    "numpy>=1.24",\n    "scipy",\n')
    extra = pyproject.replace('    "hypothesis>=6.100",\n',
                              '    "hypothesis>=6.100",\n    "pytest-cov",\n')
    assert added != pyproject and extra != pyproject
    assert len({key, environment_key(tmp_path, added)}) == 2
    assert environment_key(tmp_path, extra) == key
    lint = environment_key(tmp_path, pyproject, "lint")
    assert lint.endswith("-dev")
    assert environment_key(tmp_path, extra, "lint") != lint
    assert environment_key(tmp_path, added, "lint") != lint
    docs = pyproject.replace('    "myst-parser>=3.0",\n', '    "myst-parser>=3.0",\n    "furo",\n')
    assert docs != pyproject
    assert environment_key(tmp_path, docs, "lint") == lint
