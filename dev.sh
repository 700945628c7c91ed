#!/usr/bin/env bash
# Set up the Python environment (once, cached) and run a job in it.
#
#   ./dev.sh sim [ARGS]   the simulated pick-and-place (headless + video when
#                         there is no display); ARGS go to pick_place_sim.py
#   ./dev.sh test [ARGS]  the quick tier: every test not marked slow (-m "not slow"),
#                         on every core (pytest-xdist -n auto); it reaches every
#                         module of the package (tests/tools/test_suite_layout.py)
#                         in minutes. Installs the hw extra (lerobot)
#   ./dev.sh test-all [ARGS]
#                         every test, on every core, and the 25 slowest named
#   ./dev.sh test-base [ARGS]
#                         the tests that need no lerobot and no OpenCV
#                         (-m "not hw and not vision"), on every core, in an
#                         environment with the dev extra only: minutes, not the
#                         hw extra's PyTorch (CI's Python 3.10 leg; OpenCV comes
#                         with lerobot)
#   ./dev.sh docs [ARGS]  the docs site (Sphinx, warnings as errors) into docs/_build/html
#   ./dev.sh lint         ruff check (the dev extra only)
#   ./dev.sh bench [ARGS] the benchmarks (benchmarks/run.py)
#   ./dev.sh shell        a shell inside the environment
#
# PYTHON=python3.x picks the interpreter (default python3); one outside the
# project's requires-python (pyproject.toml) is refused here in one line.
#
# The virtual environment lives outside the clone, keyed by a hash of the
# dependencies and the extras, so a new clone reuses it and changed
# dependencies build a fresh one:
#   ${SO101_VENV_ROOT:-${XDG_CACHE_HOME:-~/.cache}/so101-kinematics}/venv-<hash>-<extras>
set -euo pipefail
cd "$(dirname "$0")"

job="${1:-sim}"
[ $# -gt 0 ] && shift
case "$job" in
  sim) extras="" ;;
  test|test-all|bench|shell) extras="dev,hw" ;;
  test-base|lint) extras="dev" ;;
  docs) extras="docs" ;;
  *) echo "usage: ./dev.sh {sim|test|test-all|test-base|lint|docs|bench|shell} [ARGS]" >&2; exit 2 ;;
esac

python="${PYTHON:-python3}"
# The supported Pythons are pyproject.toml's requires-python (">=3.10,<3.14").
requires="$(sed -n 's/^requires-python = "\(.*\)"/\1/p' pyproject.toml)"
lowest="$(echo "$requires" | sed -n 's/.*>=\([0-9.]*\).*/\1/p')"
above="$(echo "$requires" | sed -n 's/.*<\([0-9.]*\).*/\1/p')"
if ! version="$("$python" -c 'import platform; print(platform.python_version())' 2>/dev/null)"; then
  echo "error: cannot run the Python interpreter '$python'; this project needs Python $requires. Fix: install one and set PYTHON=python3.x" >&2
  exit 1
fi
if ! "$python" -c "import sys; sys.exit(not (${lowest/./, }) <= sys.version_info[:2] < (${above/./, }))"; then
  echo "error: Python $version ('$python') is not supported: this project needs Python $requires. Fix: set PYTHON to a supported one, e.g. PYTHON=python3.12" >&2
  exit 1
fi

root="${SO101_VENV_ROOT:-${XDG_CACHE_HOME:-$HOME/.cache}/so101-kinematics}"
# Keyed by what the environment contains: the base dependency list and the
# lists of the extras it installs (comments and blank lines dropped) and the
# interpreter; not the rest of pyproject.toml, so moving modules, adding a
# console script (the editable install below refreshes those on every run),
# editing tool settings or another extra's list rebuilds nothing.
block() {  # block NAME: the lines of pyproject.toml's list "NAME = [" up to its "]"
  awk -v name="$1" '$0 ~ "^" name " = \\[" { on = 1; next } on && /^\]/ { exit } on' pyproject.toml \
    | grep -v -e '^ *#' -e '^ *$' || true
}
deps="$(block dependencies; for extra in ${extras//,/ }; do echo "[$extra]"; block "$extra"; done)"
key="$( (echo "$deps"; echo "$extras"; "$python" -V) | sha256sum | cut -c1-16)"
venv="$root/venv-$key-${extras:-base}"

if [ ! -f "$venv/.complete" ]; then
  note="about a minute"
  [[ "$extras" == *hw* ]] && note="the hw extra pulls PyTorch: several minutes"
  echo "Setting up $venv with Python $version (first run only; $note) ..." >&2
  rm -rf "$venv"
  mkdir -p "$root"
  "$python" -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --upgrade pip "setuptools>=77" wheel
  "$venv/bin/python" -m pip install --quiet --progress-bar off -e ".${extras:+[$extras]}"
  touch "$venv/.complete"
  # Keep the two newest environments of this kind (extras and Python
  # major.minor: a 3.10 one does not push out the 3.11 one); each hw one is ~9 GB.
  ls -dt "$root"/venv-*-"${extras:-base}" 2>/dev/null \
    | while read -r env; do
        if grep -q "^version = ${version%.*}\." "$env/pyvenv.cfg" 2>/dev/null; then echo "$env"; fi
      done | tail -n +3 | xargs -r rm -rf
fi
# The venv is shared by clones: point its editable install at this clone.
"$venv/bin/python" -m pip install --quiet --no-deps --no-build-isolation -e . >/dev/null 2>&1 \
  || "$venv/bin/python" -m pip install --quiet --no-deps -e . >/dev/null
"$venv/bin/python" -m so101_kinematics.sim.meshes >/dev/null

if [ -z "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  export MUJOCO_GL="${MUJOCO_GL:-egl}"
fi

# The test jobs run on every core (-n auto; ARGS after it win: -n 0 runs in this
# process, -m replaces the tier's marker). --dist loadgroup keeps the tests of one
# xdist_group on one worker (tests/conftest.py groups the real-time virtual arms), and
# --no-loadscope-reorder hands the work out in the order tests/conftest.py sets (the files
# that take the arms' lock alone first, then those that run no arm).
# pytest's exit 5 (no test collected) fails the job as any other failure.
parallel=(-n auto --dist loadgroup --no-loadscope-reorder)
case "$job" in
  test|test-all)
    # Which lerobot line this run checks (0.4.x on 3.10/3.11, 0.6.x on 3.12+).
    "$venv/bin/python" -c 'import importlib.metadata as m, platform
print("Python", platform.python_version() + ", lerobot", m.version("lerobot"))' >&2 || true ;;
esac
case "$job" in
  sim) exec "$venv/bin/python" pick_place_sim.py "$@" ;;
  test) exec "$venv/bin/python" -m pytest "${parallel[@]}" -m "not slow" "$@" ;;
  test-all) exec "$venv/bin/python" -m pytest "${parallel[@]}" --durations=25 "$@" ;;
  test-base) exec "$venv/bin/python" -m pytest "${parallel[@]}" -m "not hw and not vision" "$@" ;;
  docs) exec "$venv/bin/python" -m sphinx -W --keep-going -q -b html docs docs/_build/html "$@" ;;
  lint) exec "$venv/bin/python" -m ruff check "$@" . ;;
  bench) exec "$venv/bin/python" benchmarks/run.py "$@" ;;
  shell) PATH="$venv/bin:$PATH" exec "${SHELL:-bash}" ;;
esac
