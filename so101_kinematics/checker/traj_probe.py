"""Runs in a child process: a student's ``move_to_pose_cubic`` against a recording stand-in.

Started by :func:`so101_kinematics.checker.sandbox.run_probe` (``probe=`` this file) as
``python -I -B traj_probe.py REQUEST RESULT``. Like ``probe.py`` it uses only the standard
library and numpy, and borrows ``probe.py``'s bounded output and error lines.

Before the student's module is imported, ``mujoco`` (and ``mujoco.viewer``) in
``sys.modules`` is a stand-in: ``mujoco.mj_step(m, d)`` records ``d.ctrl`` with the time,
advances ``d.time`` by ``m.opt.timestep`` and puts the joints where they were commanded
(an ideal servo); ``viewer.sync()`` counts. The ``time`` module's clocks read the same
simulated time (the course's ``move_to_pose`` times its loop with ``time.time()``), and
``time.sleep`` returns at once. ``d.qpos`` holds the six joints in the course's order, so
``convert_to_dictionary(d.qpos)`` reads the start as the course's utils do.

Each move is bounded three ways, each raising :class:`Budget` (a ``BaseException``, so an
``except Exception`` in the student's loop does not swallow it): a number of steps, a
number of clock reads without a step, and a wall-clock alarm.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import signal
import sys
import time
import types

__all__: list[str] = []


def _load_sibling(name: str, as_name: str):
    """``name``.py beside this file (the child runs ``-I``: this folder is not on sys.path)."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), name)
    spec = importlib.util.spec_from_file_location(as_name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


STANDIN = _load_sibling("traj_standin.py", "so101_check_traj_standin")
"""The stand-in model and data (``traj_standin.py``)."""
JOINTS, StandInModel, StandInData = STANDIN.JOINTS, STANDIN.StandInModel, STANDIN.StandInData

CLOCK_READS_PER_STEP = 100_000
"""Clock reads allowed between two steps: more is a loop waiting for a time that never comes."""

EPOCH = 1.7e9
"""What ``time.time()`` reads at the simulated time 0 [s] (any date; only differences count)."""


class Budget(BaseException):
    """A move ran out of steps, clock reads or wall time: ``args[0]`` says which."""


class Clock:
    """Simulated time [s], shared by ``d.time`` and the ``time`` module's clocks."""

    def __init__(self):
        self.now = 0.0
        self.reads = 0
        self.exhausted = ""

    def read(self) -> float:
        """The simulated time; raises :class:`Budget` when read without end between steps."""
        self.reads += 1
        if self.reads > CLOCK_READS_PER_STEP:
            self.exhausted = "clock"
            raise Budget("clock")
        return self.now


CLOCK = Clock()


class Recorder:
    """Every step's time (from the move's start) and controls, within a step budget."""

    def __init__(self, start_time: float, max_steps: int):
        self.start_time, self.max_steps = start_time, max_steps
        self.times, self.ctrls = [], []
        self.steps = self.syncs = 0


RECORDER = Recorder(0.0, 0)


def mj_step(m, d, nstep: int = 1) -> None:
    """Record ``d.ctrl``, advance the time by ``m.opt.timestep``, put the joints there."""
    for _ in range(nstep):
        if RECORDER.steps >= RECORDER.max_steps:
            raise Budget("steps")
        RECORDER.steps += 1
        RECORDER.times.append(d.time - RECORDER.start_time)
        RECORDER.ctrls.append(d.ctrl.tolist())
        previous = d.qpos.copy()
        d.qpos[:] = d.ctrl[:len(JOINTS)]
        d.qvel[:] = (d.qpos - previous) / m.opt.timestep
        d.time += m.opt.timestep
        CLOCK.now += m.opt.timestep
        CLOCK.reads = 0


class StandInViewer:
    """``viewer``: ``sync()`` counts; always running; a context manager."""

    def __init__(self, *args, **keywords):
        self.user_scn = types.SimpleNamespace(
            geoms=[types.SimpleNamespace() for _ in range(100)], ngeom=0)
        self.opt = types.SimpleNamespace(flags=[0] * 64)

    def sync(self, *args, **keywords) -> None:
        """Count a frame."""
        RECORDER.syncs += 1

    def is_running(self) -> bool:
        """Always (a closed viewer is not part of this check)."""
        return True

    def lock(self):
        """A no-op context manager."""
        return self

    def close(self) -> None:
        """Nothing to close."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None


def install_stand_ins() -> None:
    """``mujoco`` and ``mujoco.viewer`` in ``sys.modules``, and the ``time`` clocks simulated."""
    mujoco = types.ModuleType("mujoco")
    mujoco.__file__ = "<so101-check-traj stand-in>"
    mujoco.MjModel, mujoco.MjData, mujoco.mj_step = StandInModel, StandInData, mj_step
    mujoco.mj_forward = mujoco.mj_kinematics = mujoco.mjv_initGeom = lambda *a, **k: None
    constants = STANDIN.Constants
    mujoco.mjtObj = constants(**{f"mjOBJ_{kind.upper()}": n for kind, n in STANDIN.OBJ.items()})
    mujoco.mjtGeom, mujoco.mjtVisFlag = constants(), constants()
    mujoco.mjtJoint = constants(mjJNT_FREE=0, mjJNT_BALL=1, mjJNT_SLIDE=2, mjJNT_HINGE=3)
    mujoco.mj_name2id, mujoco.mj_id2name = STANDIN.mj_name2id, STANDIN.mj_id2name
    viewer = types.ModuleType("mujoco.viewer")
    viewer.launch_passive = viewer.launch = viewer.Handle = StandInViewer
    mujoco.viewer = viewer
    sys.modules["mujoco"], sys.modules["mujoco.viewer"] = mujoco, viewer
    time.time = time.perf_counter = time.monotonic = lambda: EPOCH + CLOCK.read()
    time.time_ns = time.perf_counter_ns = time.monotonic_ns = \
        lambda: int((EPOCH + CLOCK.read()) * 1e9)
    time.sleep = lambda seconds: None


def to_radians(config: dict) -> list[float]:
    """The course's ``convert_to_list``: arm [deg] -> [rad], gripper [0, 100] -> [rad]."""
    return [config[j] * math.pi / (100.0 if j == "gripper" else 180.0) for j in JOINTS]


def _alarm(signum, frame):
    signal.setitimer(signal.ITIMER_REAL, 0.2)  # again, if the student's code swallowed it
    raise Budget("wall")


def run_move(function, parameters: int, move: dict, describe_error) -> dict:
    """Call the student's function for one move; what it commanded, step by step."""
    global RECORDER
    model = StandInModel(SETTINGS["timestep"])
    data = StandInData(model)
    data.time = CLOCK.now
    data.qpos[:] = data.ctrl[:] = to_radians(move["start"])
    steps = int(math.ceil(move["duration"] / model.opt.timestep))
    RECORDER = Recorder(data.time, SETTINGS["step_budget"] * steps + SETTINGS["step_slack"])
    CLOCK.reads = 0
    viewer = StandInViewer()
    goal = dict(move["goal"])
    args = ((model, data, viewer, dict(move["start"]), goal, move["duration"])
            if parameters == 6 else (model, data, viewer, goal, move["duration"]))
    ended, error = "returned", ""
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, SETTINGS["wall_s"])
    try:
        function(*args)
    except Budget as budget:
        ended = budget.args[0]
    except BaseException as raised:  # the student's code may raise anything, even SystemExit
        if isinstance(raised, KeyboardInterrupt):
            raise
        ended, error = "raised", describe_error(raised)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    return {"ended": ended, "error": error, "steps": RECORDER.steps, "syncs": RECORDER.syncs,
            "budget_steps": RECORDER.max_steps, "times": RECORDER.times,
            "ctrls": RECORDER.ctrls}


def _load_probe():
    """``probe.py`` beside this file (its bounded output and error lines)."""
    return _load_sibling("probe.py", "so101_check_probe")


def parameter_count(function) -> int:
    """Positional parameters of the student's function (5 or 6 expected)."""
    import inspect

    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return 5
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in parameters)


def main() -> None:
    """Import the module named in the request and run its ``move_to_pose_cubic`` per move."""
    request_path, result_path = sys.argv[1], sys.argv[2]
    probe = _load_probe()
    with open(request_path, encoding="utf-8") as handle:
        request = json.load(handle)
    SETTINGS.update(request["settings"])
    STANDIN.SETTINGS.update(timestep=SETTINGS["timestep"], ranges=SETTINGS["ranges"])
    probe.MODULE_PATH = request["module"]
    results = {"stage": "import", "moves": [], "output": "", "output_size": 0}
    captured = probe.BoundedOutput()

    def save(stage: str) -> None:
        with open(result_path + ".stage", "w", encoding="utf-8") as handle:
            handle.write(stage)
        results["stage"] = stage
        results["output"], results["output_size"] = captured.text(), captured.size
        with open(result_path + ".part", "w", encoding="utf-8") as handle:
            handle.write(json.dumps(results))
        os.replace(result_path + ".part", result_path)

    save("import")
    install_stand_ins()
    probe.add_import_paths(request, result_path)
    results["refused_writes"] = probe.REFUSED
    probe.confine(os.getcwd(), probe.own_files(result_path))
    sys.stdout = sys.stderr = captured
    spec = importlib.util.spec_from_file_location(request["module_name"], probe.MODULE_PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[request["module_name"]] = module
    global RECORDER
    RECORDER = Recorder(0.0, SETTINGS["import_steps"])  # a script that runs its moves
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, SETTINGS["wall_s"])
    try:
        spec.loader.exec_module(module)
    except BaseException as error:
        signal.setitimer(signal.ITIMER_REAL, 0)
        results["import_error"] = (
            "importing it runs without end (keep a script's moves under "
            "`if __name__ == \"__main__\":`)" if isinstance(error, Budget)
            else probe.describe_error(error))
        save("import failed")
        return
    signal.setitimer(signal.ITIMER_REAL, 0)
    results["names"] = sorted(name for name in dir(module)
                              if not name.startswith("__") and callable(getattr(module, name)))
    function = getattr(module, "move_to_pose_cubic", None)
    if callable(function):
        results["parameters"] = parameter_count(function)
        for index, move in enumerate(request["moves"]):
            save(f"running move {index + 1} ({move['name']})")
            results["moves"].append(run_move(function, results["parameters"], move,
                                             probe.describe_error))
            if results["moves"][-1]["ended"] in ("clock", "wall"):
                break  # a loop that never steps: the other moves would only wait as long
    save("done")


SETTINGS = {"timestep": 0.004, "step_budget": 5, "step_slack": 50, "wall_s": 3.0,
            "import_steps": 20_000, "ranges": dict(STANDIN.SETTINGS["ranges"])}
"""Overwritten from the request (see ``traj_compare.build_request``)."""

if __name__ == "__main__":
    main()
