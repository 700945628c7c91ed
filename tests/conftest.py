"""Shared fixtures and helpers for the test suite."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
# Offscreen rendering on machines without a display (CI): Mesa's EGL, chosen before mujoco loads.
import so101_kinematics.display as so101_display  # noqa: E402, F401


def assert_transforms_close(g_actual, g_expected, pos_tol: float = 1e-9, rot_tol: float = 1e-9,
                            label: str = "") -> None:
    """Assert two 4x4 poses agree: position within pos_tol [m], rotation within rot_tol [rad]."""
    g_actual, g_expected = np.asarray(g_actual), np.asarray(g_expected)
    pos_err = np.linalg.norm(g_actual[:3, 3] - g_expected[:3, 3])
    r_rel = g_actual[:3, :3].T @ g_expected[:3, :3]
    rot_err = np.arccos(np.clip((np.trace(r_rel) - 1.0) / 2.0, -1.0, 1.0))
    # arccos loses precision near 0: use the skew part for small angles.
    skew = 0.5 * np.array([r_rel[2, 1] - r_rel[1, 2], r_rel[0, 2] - r_rel[2, 0],
                           r_rel[1, 0] - r_rel[0, 1]])
    rot_err = min(rot_err, np.arcsin(min(1.0, np.linalg.norm(skew)))) if rot_err < 0.1 else rot_err
    assert pos_err <= pos_tol, f"{label} position error {pos_err:.3g} m > {pos_tol:.3g} m"
    assert rot_err <= rot_tol, f"{label} rotation error {rot_err:.3g} rad > {rot_tol:.3g} rad"


@pytest.fixture(scope="session")
def model():
    import so101_mujoco_utils

    return so101_mujoco_utils.load_model()


@pytest.fixture
def data(model):
    import mujoco

    return mujoco.MjData(model)


class _EveryStep:
    """A headless stand-in for a viewer: ``move_to_pose`` calls ``sync()`` after every step."""

    offscreen, sync_every_step = True, True

    def __init__(self, after_step):
        self.sync = after_step

    def is_running(self) -> bool:
        return True


def run_default_plan(m, d, after_step) -> None:
    """Run the default plan from the home keyframe, calling ``after_step()`` after each step."""
    import mujoco

    import so101_mujoco_utils as utils
    from so101_kinematics.planning.motion import run_plan
    from so101_kinematics.planning.plans import default_plan

    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    viewer = _EveryStep(after_step)
    run_plan(default_plan(), lambda cfg, duration: utils.move_to_pose(m, d, viewer, cfg, duration),
             lambda duration: utils.hold_position(m, d, viewer, duration),
             utils.get_configuration(m, d))


@pytest.fixture
def calibration():
    """The virtual arm's lerobot calibration (calibration/virtual_so101.json), loaded."""
    from so101_kinematics.calibration import load_calibration

    return load_calibration(REPO / "calibration" / "virtual_so101.json")


@pytest.fixture
def clock():
    """A deterministic clock (tests/hw_fakes.py)."""
    from hw_fakes import FakeClock

    return FakeClock()


@pytest.fixture
def course_arm():
    """A virtual arm for so101_utils' helpers; a run a failed test left going is ended on it.

    (Ended while the arm is still alive: otherwise the helpers' exit hook would try
    to end it later on a closed virtual arm.)
    """
    pytest.importorskip("lerobot")
    import so101_kinematics.hw.course_helpers as course
    from so101_kinematics.servo import KIT_SUPPLY_V
    from so101_kinematics.virtual.arm import VirtualSO101

    # the kit's 5 V C001 arm: the figures the helpers' tests check were worked out for it
    # (e.g. test_velocity_ff's hand lag, test_clearance's friction push); the virtual arm's
    # default is the course's 12 V C018 follower
    with VirtualSO101(calibration=REPO / "calibration" / "virtual_so101.json",
                      supply=KIT_SUPPLY_V) as virtual:
        yield virtual
        for run in list(course._RUNS.values()):
            course.end_at_start(run, "test teardown")


@pytest.hookimpl(tryfirst=True)  # before xdist names the groups (its hook, registered after
def pytest_collection_modifyitems(config, items):  # this file, runs first otherwise) and -m
    """Under pytest-xdist (dev.sh: -n auto --dist loadgroup), a file whose tests share a
    module-scoped fixture of its own (a virtual arm started once, a whole run on it, a checker
    run over every submission) goes to one worker: the fixture's 10-40 s are paid once, not on
    every worker. The rest spread over the workers one test at a time.

    The real-time virtual arms do run side by side (one per worker): 98 of the heaviest
    quick ones (lerobot's bus, the guarded registers, the course's helpers, the hardware
    script) passed with two arms at once on 2 cores at load 2-3; at load 8-11 (six other
    jobs) they miss servos and read holds as drops with or without xdist.
    """
    for item in items:
        if runs_an_arm(item):
            item.add_marker(pytest.mark.arm)
        module = item.nodeid.split("::")[0]
        defs = getattr(getattr(item, "_fixtureinfo", None), "name2fixturedefs", {})
        if item.path.name in EXCLUSIVE_ARM_FILES:
            item.add_marker(pytest.mark.xdist_group(EXCLUSIVE_GROUP))
        elif any(d.scope == "module" and d.baseid == module for fds in defs.values()
                 for d in fds):
            item.add_marker(pytest.mark.xdist_group(module))
    items[:] = _exclusive_first_then_armless(items)


EXCLUSIVE_GROUP = "virtual-arms-alone"
"""The xdist group of every file in :data:`EXCLUSIVE_ARM_FILES`: one worker runs them."""


def _exclusive_first_then_armless(items: list) -> list:
    """The order xdist hands work out in (dev.sh: ``--no-loadscope-reorder``), files kept whole:
    the files that take the arms' lock for themselves first, on one worker; then the files that
    run no arm, which the other worker runs meanwhile instead of waiting for that lock (xdist's
    own order, the biggest groups first, gave both workers an exclusive file at the start: the
    quick tier's worker waited 60 s on the other's); then the files that run an arm. In each
    part the grouped files first, the biggest first, as xdist would; the rest in file order."""
    modules: dict[str, list] = {}
    for item in items:
        modules.setdefault(item.nodeid.split("::")[0], []).append(item)

    def rank(entry):
        index, tests = entry
        grouped = tests[0].get_closest_marker("xdist_group") is not None
        part = (0 if tests[0].path.name in EXCLUSIVE_ARM_FILES else
                2 if any(t.get_closest_marker("arm") for t in tests) else 1)
        return part, not grouped, -len(tests) if grouped else 0, index

    ordered = sorted(enumerate(modules.values()), key=rank)
    return [item for _, tests in ordered for item in tests]


# Raw-protocol tests (Feetech's SDK and bare packets with its ~35 ms reply timeout): beside
# another virtual arm on 2 cores a reply came late (a -n 2 run: 3 of 56 failed; alone: 35 of
# 35 passed). The stops with a cube in the jaws too: their grip is real-time physics, and in
# CI's -n 2 slow leg a Ctrl-C during the lift left the cube 0.39 m from its place (alone: 1 of
# 1 passed; the tests helper saw it once at -n 2 as well). Such a file takes the arms' lock
# exclusively, once for all its tests on one worker (one xdist group; taken per test, each of
# the quick tier's 76 such tests waited for another leg's test in progress: the quick tier
# took 689 s beside the 3.12 leg, 231 s alone). So do lerobot's own tools, each test for
# itself (marked `alone`): they read with one try and a 35 ms timeout, and lerobot-calibrate
# missed a reply in the slow leg beside another arm in two rehearsals on 2026-12-04, the
# emulator at nice -10. test_pick_place_hw.py takes it shared again: its stall drill, the
# reason it was exclusive, now holds the ending to the run's own read-back. Every other test
# that runs a virtual arm (marked hw, or in tests/virtual/) takes it shared. Under xdist, or
# across processes when SO101_ARMS_LOCK names a lock file (.ci/run: its arm legs share one).
EXCLUSIVE_ARM_FILES = {"test_virtual_feetech_sdk.py", "test_virtual_protocol.py",
                       "test_virtual_fidelity.py", "test_virtual_so101.py",
                       "test_stop_with_cube.py"}


def _arms_lock_path(tmp_path_factory) -> str | None:
    """The arms' lock file of this run (None: one process, no other leg: no lock needed)."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    shared_lock = os.environ.get("SO101_ARMS_LOCK")
    if run is None and not shared_lock:
        return None
    return shared_lock or str(tmp_path_factory.getbasetemp().parent / f"virtual-arms-{run}.lock")


@contextlib.contextmanager
def _arms_lock(path: str, exclusive: bool):
    import fcntl

    with open(path, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture(scope="module", autouse=True)
def _virtual_arms_alone_for_the_file(request, tmp_path_factory):
    path = _arms_lock_path(tmp_path_factory)
    if path is None or request.path.name not in EXCLUSIVE_ARM_FILES:
        yield
        return
    with _arms_lock(path, exclusive=True):
        yield


def runs_an_arm(item) -> bool:
    """Whether a test runs a real-time virtual arm (marked hw or alone, or in tests/virtual/):
    it takes the arms' lock, and collection marks it ``arm`` (.ci/run runs the slow ones
    that do not in a leg of their own)."""
    return (item.get_closest_marker("alone") is not None or item.get_closest_marker("hw")
            is not None or item.path.parent.name == "virtual")


@pytest.fixture(autouse=True)
def _virtual_arm_turn(request, tmp_path_factory):
    node = request.node
    path = _arms_lock_path(tmp_path_factory)
    alone = node.get_closest_marker("alone") is not None
    if path is None or node.path.name in EXCLUSIVE_ARM_FILES or not runs_an_arm(node):
        yield  # no lock, or the file's (held by the fixture above), or no arm
        return
    with _arms_lock(path, exclusive=alone):
        yield
