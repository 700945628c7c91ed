"""Judge a student's cubic moves against the course's cubic, and say what is wrong.

The probe (``traj_probe.py``) records the controls at every ``mujoco.mj_step``; here they
are turned back into the student's units (arm [deg], gripper [0, 100]) and compared with
the course's cubic (:func:`so101_kinematics.planning.profiles.cubic_coefficients`, time clipped to
``[0, duration]``) sample by sample, allowing the command to be read one step early or
late (whether ``t`` is taken before or after the step is the student's choice). A move
that is off is then explained, most basic first: no command, units, where it starts,
the duration's unit, linear instead of cubic, which coefficient (a least-squares cubic
fitted to the samples), time not clipped after ``duration``, a loop that never ends.
"""

from __future__ import annotations

import math
import re

import numpy as np

from so101_kinematics.checker.traj_fallback import FALLBACK_UTILS
from so101_kinematics.frames import ARM_JOINTS, JOINT_RANGES_RAD, JOINTS
from so101_kinematics.planning.profiles import cubic_coefficients

__all__ = ["MOVES", "TOLERANCE_DEG", "build_request", "judge", "reference", "summary"]

TIMESTEP_S = 0.004
"""The stand-in's ``m.opt.timestep`` [s]: the project's model (``model/so101.xml``, ``<option
timestep>``)."""

STEP_BUDGET = 5
"""A move may take this many times its expected steps before it counts as never ending."""

WALL_S = 2.0
"""Wall-clock time a move may take in the child [s] (a loop that never steps); a right move
takes about 30 ms."""

VELOCITY_TOLERANCE_DEG_S = 1.0
"""A velocity command (the optional feed-forward) within this of ``a1 + 2 a2 t + 3 a3 t^2`` is
right [deg/s]: one 4 ms step of the steepest move's acceleration (6 x 90 deg / (2 s)^2 =
135 deg/s^2) is 0.54 deg/s."""

TOLERANCE_DEG = 0.1
"""A command within this of the course's cubic is right [deg] (gripper: [0, 100] units)."""

MATCH = 0.03
"""A ratio (units, duration, coefficient factors) is named when within this fraction."""

_START = {"shoulder_pan": -40.0, "shoulder_lift": -30.0, "elbow_flex": -20.0,
          "wrist_flex": 25.0, "wrist_roll": -50.0, "gripper": 10.0}
_GOAL = {"shoulder_pan": 50.0, "shoulder_lift": 35.0, "elbow_flex": 60.0, "wrist_flex": 75.0,
         "wrist_roll": 40.0, "gripper": 70.0}
_STILL = {"shoulder_pan": 30.0, "shoulder_lift": -25.0, "elbow_flex": 45.0,
          "wrist_flex": -35.0, "wrist_roll": 20.0, "gripper": 40.0}
MOVES = (
    {"name": "forward", "what": "every joint forward", "start": _START, "goal": _GOAL,
     "duration": 2.0},
    {"name": "backward", "what": "every joint backward (a negative move)", "start": _GOAL,
     "goal": _START, "duration": 1.5},
    {"name": "zero", "what": "a zero move (goal = start)", "start": _STILL, "goal": _STILL,
     "duration": 1.0},
)
"""The moves run, in order [deg], gripper [0, 100], duration [s]: no joint starts near 0, so
a move from zeros (or from radians) shows; two durations, so a wrong power of T shows."""

STAND_IN_RANGES = {**{joint: JOINT_RANGES_RAD[joint] for joint in ARM_JOINTS},
                   "gripper": (0.0, math.pi)}
"""The stand-in's joint ranges [rad]: the arm's the model's (``frames.JOINT_RANGES_RAD``); the
gripper's [0, pi], on which a utils mapping [0, 100] linearly over the range (this project's)
is the course's ``value * pi / 100`` (``_TO_STUDENT``), so either utils reads back the same."""

_TO_STUDENT = np.array([180.0 / math.pi] * len(ARM_JOINTS) + [100.0 / math.pi])
"""ctrl [rad] -> the student's units: the course's ``convert_to_dictionary``."""

def build_request(module_name: str = "student_move") -> dict:
    """What the probe runs: the moves, the stand-in's settings, the fallback utils.

    ``module_name`` is the name the file is imported under (its own: a student's
    ``so101_mujoco_utils.py`` is then found by its own scripts, and no fallback is used).
    """
    return {"kind": "traj", "module_name": module_name, "moves": [dict(m) for m in MOVES],
            "settings": {"timestep": TIMESTEP_S, "step_budget": STEP_BUDGET, "step_slack": 50,
                         "wall_s": WALL_S, "import_steps": 20_000,
                         "ranges": STAND_IN_RANGES},
            "fallback_modules": {"so101_mujoco_utils": FALLBACK_UTILS}}


def _vector(config: dict) -> np.ndarray:
    return np.array([config[j] for j in JOINTS], dtype=float)


def reference(move: dict, t) -> np.ndarray:
    """The course's cubic at times ``t`` [s] (clipped to [0, duration]): (n, 6)."""
    a0, a1, a2, a3 = (np.array(c) for c in zip(*(
        cubic_coefficients(q0, qf, move["duration"])
        for q0, qf in zip(_vector(move["start"]), _vector(move["goal"]), strict=True)),
        strict=True))
    tc = np.clip(np.asarray(t, dtype=float), 0.0, move["duration"])[:, None]
    return a0 + a1 * tc + a2 * tc**2 + a3 * tc**3


def _near(value: float, target: float) -> bool:
    return abs(value / target - 1.0) < MATCH


def _cubic_s(f):
    """The fraction of the duration at which the cubic ``3 s^2 - 2 s^3`` reaches ``f``."""
    return 0.5 + np.sin(np.arcsin(np.clip(2.0 * f - 1.0, -1.0, 1.0)) / 3.0)


def _start_cause(first: np.ndarray, q0: np.ndarray, qf: np.ndarray, tol: float) -> str:
    arm = slice(0, len(ARM_JOINTS))
    off = np.abs(first - q0)[arm].max()
    if off <= tol:
        return ""
    if np.abs(first - qf)[arm].max() <= tol:
        return ("the start is ignored: the first command is already the goal (jumps to the "
                "goal; is a0 the goal, or t not measured from the move's start?)")
    if np.abs(first - q0 * math.pi / 180.0)[arm].max() <= tol:
        return ("the start is read in radians: the first command is the start's angles in "
                "radians used as degrees (read d.qpos through convert_to_dictionary)")
    if np.abs(first)[arm].max() <= tol:
        return ("the start is ignored: the move starts from zeros, not from where the arm is "
                "(a0 = the starting position read from d.qpos)")
    return f"the first command is {off:.2f} deg from where the arm is: a0 must be the start"


def _fit(t: np.ndarray, cmd: np.ndarray, q0, qf, duration: float) -> dict | None:
    """The cubic through the samples in [0, duration], per unit of the move and of s = t/T."""
    inside = t <= duration + 1e-9
    delta = qf - q0
    joints = np.abs(delta) >= 10.0
    if inside.sum() < 6 or not joints.any():
        return None
    s = t[inside] / duration
    basis = np.vstack([np.ones_like(s), s, s**2, s**3]).T
    coefficients, *_ = np.linalg.lstsq(basis, cmd[inside][:, joints], rcond=None)
    residual = np.abs(basis @ coefficients - cmd[inside][:, joints]).max()
    unit = coefficients / delta[joints]  # rows: a0 - q0 (as c0), a1 T, a2 T^2, a3 T^3 over delta
    return {"n1": float(np.median(unit[1])), "n2": float(np.median(unit[2])),
            "n3": float(np.median(unit[3])), "residual_deg": float(residual)}


def _factor_words(name: str, factor: float, course: str) -> str:
    if _near(factor, -1.0):
        return f"{name} has the wrong sign (the course's is {course})"
    return f"{name} is {factor:.3g}x the course's {course}"


def _coefficient_causes(fit: dict, tol: float) -> list[str]:
    """The wrong commands named by their fitted cubic: linear, not a cubic, or which factor."""
    if abs(fit["n1"] - 1.0) < MATCH and abs(fit["n2"]) < MATCH and abs(fit["n3"]) < MATCH:
        return ["linear interpolation, not the cubic: the velocity is (qf - q0)/T at both "
                "ends, not zero (a1 = 0, a2 = 3 (qf - q0)/T^2, a3 = -2 (qf - q0)/T^3)"]
    if fit["residual_deg"] > tol * 5:
        return [f"the commands are not a cubic in t (a cubic fits them only to "
                f"{fit['residual_deg']:.2f} deg)"]
    causes = []
    if abs(fit["n1"]) > MATCH:
        causes.append(f"a1 is not zero: the velocity at the start is {fit['n1']:.3g} "
                      "(qf - q0)/T (a1 = 0 for a move from rest)")
    if not _near(fit["n2"], 3.0):
        causes.append(_factor_words("a2", fit["n2"] / 3.0, "3 (qf - q0)/T^2"))
    if not _near(fit["n3"], -2.0):
        causes.append(_factor_words("a3", fit["n3"] / -2.0, "-2 (qf - q0)/T^3"))
    end_velocity = fit["n1"] + 2 * fit["n2"] + 3 * fit["n3"]
    if abs(end_velocity) > MATCH:
        causes.append(f"the velocity at the end is {end_velocity:.3g} (qf - q0)/T, not zero")
    end = fit["n1"] + fit["n2"] + fit["n3"]
    if abs(end - 1.0) > MATCH:
        causes.append(f"at t = T the cubic reaches {end:.3g} of the way to the goal, not 1")
    return causes


def move_causes(move: dict, t, cmd, timestep: float, tol: float, ended: str,
                steps: int, last: float) -> tuple[list, dict]:
    """What is wrong with one move, in the student's terms, and the fitted factors.

    ``t``, ``cmd``: the times [s] a new command reached a step and the command (the
    student's units); ``steps``: the move's steps; ``last``: the last step's time [s].
    """
    q0, qf, duration = _vector(move["start"]), _vector(move["goal"]), move["duration"]
    causes, found = [], {}
    if len(t) == 0:
        return _never_ends(ended, 0, duration) or [
            "it never stepped the simulation with a command (no mujoco.mj_step(m, d) in the "
            "loop, or a loop condition false from the start)"], found
    arm = slice(0, len(ARM_JOINTS))
    ref = reference(move, t)
    scale = float(np.sum(cmd[:, arm] * ref[:, arm]) / max(np.sum(ref[:, arm] ** 2), 1e-12))
    if _near(scale, 180.0 / math.pi):
        return [f"degrees passed as radians: the commands are {scale:.1f}x the angles "
                "(MuJoCo's ctrl takes radians: send convert_to_list(position_dict))"], found
    if _near(scale, math.pi / 180.0):
        return ["radians passed as degrees: the commands are 1/57.3 of the angles (converted "
                "to radians twice?)"], found
    start = _start_cause(cmd[0], q0, qf, tol)
    if start:
        return [start], found
    lasted = steps * timestep
    if ended == "returned" and duration >= 0.5 and lasted <= max(2 * timestep,
                                                                 2 * duration / 1000.0):
        return [f"the move ends after {steps} step(s) ({lasted:.3f} s), not after "
                f"{duration:g} s: the duration is divided by 1000 (seconds treated as ms?)"], found
    big = int(np.argmax(np.abs(qf - q0)[arm]))
    delta = (qf - q0)[big]
    if abs(delta) > tol:
        f = (cmd[:, big] - q0[big]) / delta
        use = (f > 1e-9) & (f < 0.95) & (t > 2 * timestep)
        if use.sum() >= 3:
            spans = t[use] / _cubic_s(f[use])
            span = float(np.median(spans))
            steady = np.mean(np.abs(spans / span - 1.0) < MATCH) > 0.9
            found["duration_s"] = span
            if steady and _near(span / duration, 1000.0):
                causes.append(f"duration in the wrong unit: the cubic is timed for {span:g} s "
                              f"({duration:g} s taken as ms: the move would take 1000x long)")
                return causes + _never_ends(ended, steps, duration), found
            if steady and not _near(span / duration, 1.0):
                causes.append(f"the cubic is timed for {span:.3g} s, not the duration "
                              f"{duration:g} s ({span / duration:.3g}x)")
    if abs(delta) > tol and np.ptp(cmd[:, big]) == 0.0:
        return [f"the command never leaves the start in {steps} steps: t does not advance "
                "(measure t inside the loop: time.time() - start_time, or d.time - t0)"] \
            + _never_ends(ended, steps, duration), found
    inside = t <= duration + 1e-9
    error_in = np.abs(cmd[inside] - _shifted(move, t[inside], timestep, cmd[inside])).max() \
        if inside.any() else 0.0
    fit = _fit(t, cmd, q0, qf, duration)
    if fit:
        found.update(fit)
    if error_in > tol and not causes and fit:
        causes += _coefficient_causes(fit, tol)
    elif error_in > tol and not causes:
        causes.append(f"the commands differ from the course's cubic by up to {error_in:.2f} deg")
    after = t > duration + timestep / 2
    if after.any():
        past = np.abs(cmd[after] - qf).max()
        if past > tol:
            worst = float(t[after][np.argmax(np.abs(cmd[after] - qf).max(axis=1))])
            causes.append(f"time not clipped: after t = {duration:g} s the command leaves the "
                          f"goal ({past:.2f} deg off at t = {worst:.2f} s; clip t to [0, "
                          "duration])")
    elif ended == "returned" and last < duration - 1.5 * timestep:
        causes.append(f"the loop stops at t = {last:.3f} s, before the duration "
                      f"{duration:g} s")
    return causes + _never_ends(ended, steps, duration), found


def reference_velocity(move: dict, t) -> np.ndarray:
    """The course's cubic's velocity ``a1 + 2 a2 t + 3 a3 t^2`` at ``t`` (clipped): (n, 6)."""
    duration = move["duration"]
    s = np.clip(np.asarray(t, dtype=float), 0.0, duration)[:, None] / duration
    return (_vector(move["goal"]) - _vector(move["start"])) * 6.0 * s * (1.0 - s) / duration


def velocity_causes(move: dict, t, vel, timestep: float) -> list[str]:
    """What is wrong with the velocity commands (12 controls), if they are not all zero."""
    if np.abs(vel).max() < 1e-6:
        return []  # no feed-forward (the course's velocity_dict=None), or a zero move
    error = min(np.abs(vel - reference_velocity(move, t + shift * timestep)).max()
                for shift in (0, -1, 1))
    if error <= VELOCITY_TOLERANCE_DEG_S:
        return []
    arm = slice(0, len(ARM_JOINTS))
    ref = reference_velocity(move, t)[:, arm]
    scale = float(np.sum(vel[:, arm] * ref) / max(np.sum(ref**2), 1e-12))
    if _near(scale, 180.0 / math.pi):
        return [f"velocity in deg/s sent as rad/s: the velocity commands are {scale:.1f}x the "
                "cubic's (send convert_to_list(velocity_dict))"]
    if _near(scale, -1.0):
        return ["the velocity commands have the wrong sign"]
    return [f"the velocity commands differ from a1 + 2 a2 t + 3 a3 t^2 by up to {error:.1f} "
            "deg/s"]


def _shifted(move: dict, t, timestep: float, cmd) -> np.ndarray:
    """The reference one step early, on time or late: whichever is closest to ``cmd``."""
    options = [reference(move, t + shift * timestep) for shift in (0, -1, 1)]
    return min(options, key=lambda ref: np.abs(cmd - ref).max())


def _never_ends(ended: str, steps: int, duration: float) -> list[str]:
    why = {"steps": f"still looping after {steps} steps ({steps * TIMESTEP_S:.1f} s simulated, "
                    f"{STEP_BUDGET}x the duration {duration:g} s)",
           "clock": "reading the clock without end and not stepping the simulation",
           "wall": f"still running after {WALL_S:g} s of wall-clock time"}.get(ended)
    return [f"a loop that never ends: {why}; check the loop's exit condition "
            "(e.g. if t > duration: break, with t measured each time round)"] if why else []


def summary(tests: list[dict]) -> list[str]:
    """Every kind of cause once (the first move's words), a wrong power of T first."""
    powers = power_causes(tests)
    causes, kinds = list(powers), {cause.split(" ")[0] + " is" for cause in powers}
    for test in tests:
        for cause in test["causes"]:
            kind = re.split(r" -?[0-9]", cause, maxsplit=1)[0]
            if kind not in kinds:
                kinds.add(kind)
                causes.append(cause)
    return causes


def power_causes(tests: list[dict]) -> list[str]:
    """A coefficient factor that changes with the duration: a wrong power of ``duration``."""
    causes = []
    for name, course, power in (("n2", "a2", 2), ("n3", "a3", 3)):
        points = [(t["duration"], t["found"][name]) for t in tests
                  if name in t.get("found", {}) and abs(t["found"][name]) > 1e-12]
        if len({d for d, _ in points}) < 2:
            continue
        (d1, f1), (d2, f2) = points[0], next(p for p in points if p[0] != points[0][0])
        if f1 / f2 <= 0:
            continue
        slope = math.log(f1 / f2) / math.log(d1 / d2)
        if abs(slope) > 0.5 and abs(slope - round(slope)) < 0.1:
            causes.append(f"{course} changes with the duration like duration^{round(slope)}: it "
                          f"divides by duration^{power - round(slope)}, not duration^{power}")
    return causes


def judge(results: dict, tol: float, timestep: float = TIMESTEP_S) -> list[dict]:
    """One test per move: status ("ok", "wrong", "broken"), error, causes, what was run."""
    tests = []
    for move, run in zip(MOVES, results.get("moves", []), strict=False):
        test = {"function": f"move {len(tests) + 1}", "move": move["name"],
                "what": move["what"], "duration": move["duration"], "steps": run["steps"],
                "expected_steps": math.ceil(move["duration"] / timestep),
                "syncs": run["syncs"], "ended": run["ended"], "max_error_deg": None,
                "causes": [], "found": {}}
        if run["ended"] == "raised":
            test.update(status="broken", causes=[f"it raised {run['error']}"])
            tests.append(test)
            continue
        t = np.array(run["times"], dtype=float)
        ctrls = (np.array(run["ctrls"], dtype=float).reshape(len(t), -1) if len(t)
                 else np.zeros((0, len(JOINTS))))
        cmd = ctrls[:, :len(JOINTS)] * _TO_STUDENT
        last = float(t[-1]) if len(t) else 0.0
        new = np.r_[True, np.any(np.diff(cmd, axis=0) != 0.0, axis=1)] if len(t) else []
        t, cmd = t[new], cmd[new]  # a command held for several steps: when it was new
        if len(t):
            test["max_error_deg"] = float(np.abs(cmd - _shifted(move, t, timestep, cmd)).max())
            test["velocity_commands"] = bool(np.any(np.abs(ctrls[:, len(JOINTS):]) > 1e-6))
        causes, found = move_causes(move, t, cmd, timestep, tol, run["ended"], run["steps"],
                                    last)
        if ctrls.shape[1] > len(JOINTS) and not causes:
            causes = velocity_causes(move, t, ctrls[new][:, len(JOINTS):] * _TO_STUDENT,
                                     timestep)
        test["found"] = found
        test["causes"] = causes
        right = test["max_error_deg"] is not None and test["max_error_deg"] <= tol
        test["status"] = ("ok" if right and run["ended"] == "returned" and not causes
                          else "broken" if not len(t) else "wrong")
        tests.append(test)
    return tests
