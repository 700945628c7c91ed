"""Run a student's FK or IK module in a separate, time-bounded process (see ``probe.py``).

The student's module is never imported by the checker itself: a child Python
(``-I``: isolated from the caller's environment variables and folder; ``-B``:
no ``__pycache__`` written beside the student's file) runs ``probe.py`` with
its working folder a fresh temporary directory, no display, one BLAS thread,
and a cap on the size of any file it writes. Its output is kept up to a few
thousand characters. After ``timeout`` seconds the child and everything it
started are killed.

The submission is confined to that folder: ``HOME`` and ``TMPDIR`` are the
folder too, and before the student's import the probe installs an audit hook
(``probe.confine``: ``sys.addaudithook``) that refuses, with a ``PermissionError``
naming the path, every write outside it (``open`` for writing, remove, rename,
mkdir, link, chmod, ...; ``..`` and symlinks resolved). A refused write is
reported by the checker as the reason the file was not checked, even if the
student's code caught the error. This protects the caller's files from a
module's paths and its runaway output; it is not a security boundary against
deliberately hostile code (a C extension or a program the module starts is not
audited; the child runs with the caller's permissions).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["DEFAULT_TIMEOUT_S", "PROBE", "run_probe"]

PROBE = Path(__file__).with_name("probe.py")

DEFAULT_TIMEOUT_S = 10.0
"""Time a submission gets for its import and every call together [s]."""

_CHILD_ENVIRONMENT_KEEP = ("PATH", "HOME", "LANG", "LC_ALL", "TMPDIR", "USER")


@dataclass
class ProbeRun:
    """What the child process reported about one submission.

    Attributes:
        status: "ok", "import_error", "timeout" or "died".
        reason: one line for the report when status is not "ok".
        results: the probe's results (functions, outputs, names); may be partial.
        seconds: wall time of the child [s].
    """

    status: str
    reason: str = ""
    results: dict = field(default_factory=dict)
    seconds: float = 0.0


def child_environment(work: str | Path | None = None) -> dict[str, str]:
    """The child's environment: the caller's basics, no display, single-threaded numerics.

    With ``work`` (the child's working folder), ``HOME`` and ``TMPDIR`` are that folder too,
    so ``~/...``, ``tempfile`` and a library's caches land inside it.
    """
    environment = {key: os.environ[key] for key in _CHILD_ENVIRONMENT_KEEP if key in os.environ}
    environment.update(OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
                       MUJOCO_GL="egl", PYTHONDONTWRITEBYTECODE="1")
    if work is not None:
        environment.update(HOME=str(work), TMPDIR=str(work))
    return environment


def run_probe(module_path: str | Path, request: dict, timeout: float = DEFAULT_TIMEOUT_S,
              python: str = sys.executable, probe: Path = PROBE) -> ProbeRun:
    """Import ``module_path`` in a child process and evaluate ``request`` there.

    Args:
        module_path: the student's ``so101_forward_kinematics.py`` (or IK module).
        request: what to evaluate (see ``compare.build_request``, ``ik_compare.build_request``).
        timeout: limit for the whole child [s].
        python: the interpreter for the child.
        probe: the child's script (``probe.py``; ``traj_probe.py`` for a trajectory).

    Returns:
        A :class:`ProbeRun`.
    """
    module_path = Path(module_path).resolve()
    with tempfile.TemporaryDirectory(prefix="so101-check-") as folder:
        request_path = Path(folder) / "request.json"
        result_path = Path(folder) / "result.json"
        request_path.write_text(json.dumps({**request, "module": str(module_path)}),
                                encoding="utf-8")
        work = Path(folder) / "work"
        work.mkdir()
        start = time.perf_counter()
        with open(Path(folder) / "stdio.txt", "wb") as stdio:
            child = subprocess.Popen(
                [python, "-I", "-B", str(probe), str(request_path), str(result_path)],
                cwd=work, env=child_environment(work), stdin=subprocess.DEVNULL, stdout=stdio,
                stderr=subprocess.STDOUT, start_new_session=True)
            try:
                code = child.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                code = None
                _kill_group(child)
        seconds = time.perf_counter() - start
        results = _read_json(result_path)
        stage = _read_text(Path(str(result_path) + ".stage")) or "starting"
        raw_output = _read_text(Path(folder) / "stdio.txt")[-2000:]
    if code is None:
        return ProbeRun("timeout", f"timed out after {timeout:g} s while {_stage_words(stage)}; "
                        "a loop that never ends, or input() waiting for a keyboard?",
                        results, seconds)
    if results.get("import_error"):
        return ProbeRun("import_error", f"importing it failed: {results['import_error']}",
                        results, seconds)
    if results.get("stage") != "done":
        last = " ".join(raw_output.split())[-300:]
        return ProbeRun("died", f"the process ended (exit code {code}) while "
                        f"{_stage_words(stage)}" + (f": {last}" if last else ""),
                        results, seconds)
    return ProbeRun("ok", "", results, seconds)


def _stage_words(stage: str) -> str:
    return "importing the module" if stage == "import" else stage


def _kill_group(child: subprocess.Popen) -> None:
    """Kill the child and everything it started (its own session), then reap it."""
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        child.kill()
    child.wait()


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return ""
