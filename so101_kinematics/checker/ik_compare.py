"""Judge a student's IK answers with this package's FK, and say where and why they fail.

Each answer is a configuration dict [deg]; its object frame (this package's FK,
:func:`so101_kinematics.fast_fk.forward_kinematics_batch`) is compared with the target:
position error [mm], tilt of the frame's z axis from the vertical [deg], and yaw error
[deg] modulo 90 (a cube looks the same every quarter turn). An answer is right when all
three are within the tolerance and no joint is beyond its limit (``JOINT_LIMITS``, with
:data:`LIMIT_SLACK_DEG`). NaN (the course's way of saying "unreachable"), a raised
exception and a malformed return are counted apart from wrong answers: every target is
reachable. Failures are located (workspace region, joint at or beyond its limit, elbow
branch, reaching backwards) and matched against known mistakes (:func:`causes`).
"""

from __future__ import annotations

import difflib
import functools
import math

import numpy as np

from so101_kinematics.checker import ik_targets
from so101_kinematics.checker.ik_own_fk import own_fk_note
from so101_kinematics.fast_fk import forward_kinematics_batch
from so101_kinematics.frames import (
    ARM_JOINTS,
    FIXED_TRANSFORMS,
    GRIPPER_MOUNT_TILT_DEG,
    JOINT_LIMITS,
    joint_transform,
)
from so101_kinematics.ik.geometry import PAN_AXIS_POINT

__all__ = ["_branches", "build_request", "compare_ik", "count_targets"]

LIMIT_SLACK_DEG = 0.01
"""How far past a joint limit an answer may go before it counts as beyond it [deg]."""

AT_LIMIT_DEG = 0.5
"""An answer within this of a limit [deg] is reported as at the limit (not a failure)."""

MATCH_DEG = 0.3
"""A yaw error agrees with a cause's prediction when within this [deg] (not for grading)."""

MATCH_FRACTION = 0.9
"""Share of the answers that must agree with a cause's prediction for it to be named."""

_SIDEWAYS = (FIXED_TRANSFORMS["12"][0][1] + FIXED_TRANSFORMS["23"][0][2]
             + FIXED_TRANSFORMS["34"][0][2] + FIXED_TRANSFORMS["45"][0][2])  # [m]
_TOOL = np.array(FIXED_TRANSFORMS["5t"][0])
_PAN_X = PAN_AXIS_POINT[0]
_TURNED = (f" (the cube's centre is {math.hypot(*_TOOL[:2]) * 1000:.1f} mm off the roll axis, "
           "so a wrong roll also moves it)")
_LIMIT_HINTS = {
    "wrist_roll": " Fix: a cube looks the same every 90 deg: turn the grasp by 90 deg to bring "
                  "wrist_roll back within its range",
    "shoulder_pan": " Fix: check the limit; the cube's other grasps (yaw + 90 deg) move the "
                    "wrist by a few millimetres and may bring shoulder_pan back within it",
    "elbow": " Fix: check the limits, and try the other elbow branch when a joint is out of "
             "its range"}


@functools.lru_cache(maxsize=4)
def build_request(count: int = ik_targets.TARGET_COUNT) -> dict:
    """What the probe evaluates: the targets, and the fallback FK (cached: do not change it)."""
    _, targets, _ = ik_targets.build_targets(count)
    return {"kind": "ik", "module_name": "so101_inverse_kinematics",
            "targets": targets.tolist() + [list(t) for t in ik_targets.OUT_OF_REACH.values()],
            "fallback_modules": {"so101_forward_kinematics": ik_targets.reference_fk_source()}}


def _wrap(angle, period: float = 360.0):
    """Angle(s) [deg] wrapped into [-period/2, period/2)."""
    return (np.asarray(angle) + period / 2) % period - period / 2


def _read_answers(calls: list[dict]):
    """(angles (n, 5) [deg] with NaN rows, kinds, problems) from the probe's results.

    Kinds: "answer", "nan", "raised", "broken"; problems: a text for the last two.
    """
    angles = np.full((len(calls), len(ARM_JOINTS)), np.nan)
    kinds, problems = [], []
    for i, call in enumerate(calls):
        if "error" in call:
            kinds.append("broken" if call["error"].startswith("returns a") else "raised")
            problems.append(call["error"])
            continue
        value = call["value"]
        missing = [joint for joint in ARM_JOINTS if joint not in value]
        odd = [joint for joint in call.get("not_numbers", []) if joint in ARM_JOINTS]
        if missing or odd:
            kinds.append("broken")
            problems.append((f"missing the joint(s) {', '.join(missing)}" if missing else
                             f"not numbers: {', '.join(odd)}") +
                            f"; got keys {sorted(value) + call.get('not_numbers', [])}")
            continue
        angles[i] = [value[joint] for joint in ARM_JOINTS]
        finite = bool(np.all(np.isfinite(angles[i])))
        kinds.append("answer" if finite else "nan")
        problems.append("" if finite else "NaN")
    return angles, kinds, problems


def _errors(targets: np.ndarray, angles: np.ndarray):
    """Position [mm], tilt [deg], yaw error mod 90 [deg] of each row (NaN rows give NaN)."""
    positions, rotations = forward_kinematics_batch(np.nan_to_num(angles))
    mm = np.linalg.norm(positions - targets[:, :3], axis=1) * 1000
    tilt = np.degrees(np.arccos(np.clip(rotations[:, 2, 2], -1.0, 1.0)))
    reached = np.degrees(np.arctan2(rotations[:, 1, 0], rotations[:, 0, 0]))
    yaw = _wrap(reached - np.degrees(targets[:, 3]), 90.0)
    bad = ~np.all(np.isfinite(angles), axis=1)
    for values in (mm, tilt, yaw):
        values[bad] = np.nan
    return mm, tilt, yaw


def _limits(angles: np.ndarray):
    """(beyond, at): (n, 5) booleans: beyond a limit by LIMIT_SLACK_DEG, within AT_LIMIT_DEG."""
    low = np.array([JOINT_LIMITS[joint][0] for joint in ARM_JOINTS])
    high = np.array([JOINT_LIMITS[joint][1] for joint in ARM_JOINTS])
    with np.errstate(invalid="ignore"):
        beyond = (angles < low - LIMIT_SLACK_DEG) | (angles > high + LIMIT_SLACK_DEG)
        at = ~beyond & ((angles < low + AT_LIMIT_DEG) | (angles > high - AT_LIMIT_DEG))
    return beyond, at


def _branches(targets: np.ndarray, angles: np.ndarray) -> list[str]:
    """"elbow up" / "elbow down", plus ", reaching backwards", of each answer ("" if none).

    Elbow up: the elbow lies above the line from the shoulder_lift axis to the wrist_flex
    axis. Reaching backwards: the target lies behind the pan axis in the arm's forward
    direction (the arm folded back over its base).
    """
    names = []
    for target, row in zip(targets, angles, strict=True):
        if not np.all(np.isfinite(row)):
            names.append("")
            continue
        g = np.eye(4)
        points = []
        for name, angle in zip(("w1", "12", "23", "34"), row[:4], strict=True):
            g = g @ joint_transform(name, float(angle))
            points.append(g[:3, 3])
        shoulder, elbow, wrist = points[1], points[2], points[3]
        line = wrist - shoulder
        along = float((elbow - shoulder) @ line / max(line @ line, 1e-12))
        up = elbow[2] > shoulder[2] + along * line[2]
        pan = math.radians(row[0])
        forward = (math.cos(pan) * (target[0] - _PAN_X) - math.sin(pan) * target[1])
        names.append(("elbow up" if up else "elbow down")
                     + (", reaching backwards" if forward < 0 else ""))
    return names


def _plane_pans(targets: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """The pan [deg] that puts each target in the arm's plane, given the answer's own roll.

    The branch (forwards or backwards) nearest the answer's pan; NaN rows give NaN.
    """
    pans = np.full(len(targets), np.nan)
    for i, (target, row) in enumerate(zip(targets, angles, strict=True)):
        if not np.all(np.isfinite(row)):
            continue
        pan = row[0]
        for _ in range(4):  # the tool's 5.1 mm offset turns with yaw = roll - pan + tilt
            yaw = math.radians(row[4] - pan + GRIPPER_MOUNT_TILT_DEG)
            c, s = math.cos(yaw), math.sin(yaw)
            x = target[0] - (c * _TOOL[0] - s * _TOOL[1]) - _PAN_X
            y = target[1] - (s * _TOOL[0] + c * _TOOL[1])
            radius = max(math.hypot(x, y), abs(_SIDEWAYS) + 1e-9)
            side, azimuth = math.asin(_SIDEWAYS / radius), math.atan2(y, x)
            options = np.degrees([side - azimuth, math.pi - side - azimuth])
            pan = options[np.argmin(np.abs(_wrap(options - row[0])))]
        pans[i] = pan
    return pans


def _agree(error: np.ndarray, prediction: np.ndarray, period: float, slack) -> float:
    """Share of the rows where ``error`` agrees with ``prediction`` within ``slack`` [deg]."""
    return float(np.mean(np.abs(_wrap(error - prediction, period)) <= slack))


def causes(targets, angles, yaw_error, ok, tolerance) -> list[str]:
    """Known mistakes recognised in the answers (rows with numbers only).

    Args:
        targets: (n, 4) x, y, z [m], yaw [rad].
        angles: (n, 5) answers [deg].
        yaw_error: (n,) yaw error mod 90 [deg].
        ok: (n,) which answers are right.
        tolerance: (mm, deg).

    Returns:
        Sentences naming each cause found and its fix.
    """
    if ok.all() or len(ok) == 0:
        return []
    found = []
    if np.all(np.abs(angles) <= 2 * math.pi + 1e-6):
        mm, tilt, yaw = _errors(targets, np.degrees(angles))
        if np.mean((mm <= tolerance[0]) & (tilt <= tolerance[1])
                   & (np.abs(yaw) <= tolerance[1])) >= MATCH_FRACTION:
            return ["the angles are in radians; the course's configuration dict is in degrees "
                    "(convert with np.degrees before returning)"]
    pans = _plane_pans(targets, angles)
    offset = _wrap(np.degrees(np.arctan2(targets[:, 1], targets[:, 0] - _PAN_X)
                              - np.arctan2(targets[:, 1], targets[:, 0])))
    if np.mean(np.abs(offset) > 1.0) >= 0.3 and _agree(
            angles[:, 0], pans + offset, 360.0, np.maximum(1.0, 0.3 * np.abs(offset))) >= 0.8:
        found.append(
            f"shoulder_pan is measured from the base origin, not from the pan axis "
            f"{_PAN_X * 1000:.1f} mm in front of it (the course's warning in 1b): the arm "
            "misses sideways, most near the base. Fix: theta1 from (x - "
            f"{_PAN_X:.4f}, y)")
    tilt = GRIPPER_MOUNT_TILT_DEG
    yaw_causes = [
        ("wrist_roll has the wrong sign relative to shoulder_pan (wrist_roll = -shoulder_pan "
         "+ ...): the yaw is off by -2 x shoulder_pan" + _TURNED + ". Fix: wrist_roll = "
         f"shoulder_pan + yaw + {-tilt:.2f} deg", -2.0 * angles[:, 0]),
        ("the yaw is read from the transposed rotation (atan2(R[0, 1], R[0, 0]) is minus the "
         "yaw): the yaw is off by -2 x the asked yaw" + _TURNED + ". Fix: yaw = "
         "atan2(R[1, 0], R[0, 0]) (row 1, column 0)", -2.0 * np.degrees(targets[:, 3])),
        ("the asked orientation is ignored (always yaw 0): the yaw is off by the asked yaw"
         + _TURNED + ". Fix: read the yaw from target_orientation (atan2(R[1, 0], R[0, 0])) "
         "and add it to wrist_roll", -np.degrees(targets[:, 3])),
        (f"the gripper mount's tilt is added with the wrong sign: the yaw is off by "
         f"{2 * tilt:.2f} deg everywhere. Fix: wrist_roll = shoulder_pan + yaw - "
         f"({tilt:.2f} deg)", np.full(len(ok), 2.0 * tilt)),
    ]
    mount = (f"the gripper mount's {tilt:.2f} deg tilt is left out (GRIPPER_MOUNT_TILT_DEG, "
             f"in g45): the yaw is off by {tilt:.2f} deg everywhere. Fix: wrist_roll = "
             f"shoulder_pan + yaw + {-tilt:.2f} deg")
    if np.mean(np.abs(yaw_error) > tolerance[1]) > 0:
        for text, prediction in yaw_causes:
            if np.mean(np.abs(_wrap(prediction, 90.0)) > tolerance[1]) < 0.3:
                continue  # not told apart from a right answer at these targets
            if _agree(yaw_error, prediction, 90.0, MATCH_DEG) >= MATCH_FRACTION:
                found.append(text)
                break
            if _agree(yaw_error, prediction + tilt, 90.0, MATCH_DEG) >= MATCH_FRACTION:
                found += [text, mount]
                break
        else:
            if _agree(yaw_error, np.full(len(ok), tilt), 90.0, MATCH_DEG) >= MATCH_FRACTION:
                found.append(mount)
    return found


def close_name(names: list[str], wanted: str = "get_inverse_kinematics") -> str:
    """A defined name that looks like ``wanted`` (a typo, another case), or ""."""
    lowered = {n.lower().replace("_", ""): n for n in names}
    if wanted.replace("_", "") in lowered:
        return lowered[wanted.replace("_", "")]
    close = difflib.get_close_matches(wanted, names, n=1, cutoff=0.75)
    return close[0] if close else ""


def _tally(labels: list[str], failing: np.ndarray) -> list[dict]:
    """[{name, targets, failing}] per label, in first-seen order."""
    rows = {}
    for label, bad in zip(labels, failing, strict=True):
        row = rows.setdefault(label, {"name": label, "targets": 0, "failing": 0})
        row["targets"] += 1
        row["failing"] += int(bad)
    return list(rows.values())


def _stats(values: np.ndarray) -> dict:
    values = values[np.isfinite(values)]
    if values.size == 0:
        return {"median": None, "max": None}
    return {"median": float(np.median(values)), "max": float(np.max(values))}


def _limit_causes(angles, hits_by_joint, branches) -> list[str]:
    """One cause per joint some answers put beyond its limit: how far, on which branch mostly."""
    found = []
    for joint_index, joint in enumerate(ARM_JOINTS):
        hits = hits_by_joint[:, joint_index]
        if hits.any():
            low, high = JOINT_LIMITS[joint]
            worst = np.nanmax(np.maximum(low - angles[hits, joint_index],
                                         angles[hits, joint_index] - high))
            common = max(set(b for b, h in zip(branches, hits, strict=True) if h),
                         key=[b for b, h in zip(branches, hits, strict=True) if h].count)
            hint = _LIMIT_HINTS.get(joint, _LIMIT_HINTS["elbow"])
            found.append(f"{joint} is beyond its limit [{low:.1f}, {high:.1f}] deg in "
                         f"{int(hits.sum())} answers (up to {worst:.1f} deg past it; mostly "
                         f"{common}).{hint}")
    return found


def _examples(wrong, kinds, mm, example) -> list[dict]:
    """At most four examples: the two worst wrong answers, then one of each non-answer kind."""
    picked = list(wrong[np.argsort(-mm[wrong])][:2])
    for kind in ("nan", "raised", "broken"):
        picked += [i for i, k in enumerate(kinds) if k == kind][:1]
    return [example(i) for i in picked[:4]]


def compare_ik(results: dict, tolerance, count: int = ik_targets.TARGET_COUNT) -> dict:
    """The IK test of one submission: every answer judged, failures located and explained.

    Args:
        results: the probe's results.
        tolerance: (position [mm], angle [deg]).
        count: targets asked (see :func:`build_request`).

    Returns:
        A JSON-ready dict: function, status ("ok", "wrong", "missing", "broken"), causes,
        counts per kind, error statistics, failures by region, limit and branch, examples.
    """
    calls = results.get("functions", {}).get("get_inverse_kinematics")
    if calls is None:
        close = close_name(results.get("names", []))
        return {"function": "get_inverse_kinematics", "status": "missing", "causes": [
            f"not defined; {close!r} looks like it: name it get_inverse_kinematics (the "
            "course's name)" if close else "not defined"]}
    names, targets, _ = ik_targets.build_targets(count)
    out_of_reach = ik_targets.out_of_reach_answers(calls[len(targets):])
    calls = calls[:len(targets)]
    targets, names = targets[:len(calls)], names[:len(calls)]
    angles, kinds, problems = _read_answers(calls)
    mm, tilt, yaw = _errors(targets, angles)
    beyond, at = _limits(angles)
    answered = np.array([kind == "answer" for kind in kinds], dtype=bool)
    within = (mm <= tolerance[0]) & (tilt <= tolerance[1]) & (np.abs(yaw) <= tolerance[1])
    ok = answered & within & ~beyond.any(axis=1)
    failing = ~ok
    branches = _branches(targets, angles)
    regions = [ik_targets.region(*target[:3]) for target in targets]
    found = causes(targets[answered], angles[answered], yaw[answered], ok[answered], tolerance)
    note = own_fk_note(results, targets, angles, failing & answered, tolerance, MATCH_FRACTION)
    found += [note] if note else []
    found += _limit_causes(angles, beyond & answered[:, None], branches)
    if (answered & ~ok).any() and not found:
        found.append("no known mistake recognised in the wrong answers: see where they fail "
                     "below, and compare one example with your own FK")
    counts = {kind: kinds.count(kind) for kind in ("answer", "nan", "raised", "broken")}
    counts["right"] = int(ok.sum())
    counts["wrong"] = int((answered & ~ok).sum())
    if counts["raised"] or counts["broken"]:
        first = next(p for p, k in zip(problems, kinds, strict=True) if k in ("raised", "broken"))
        found.append(f"{counts['raised'] + counts['broken']} calls gave no configuration; the "
                     f"first: {first}")
    if counts["nan"]:
        nan_regions = _tally([r[0] for r in regions], np.array([k == "nan" for k in kinds]))
        found.append(f"NaN (unreachable) returned at {counts['nan']} reachable targets ("
                     + ", ".join(f"{row['name']} {row['failing']}" for row in nan_regions
                                 if row["failing"]) + ")")
    examples = _examples(np.flatnonzero(answered & ~ok), kinds, mm, lambda i: {
        "target": [round(float(v), 4) for v in targets[i, :3]],
        "yaw_deg": round(math.degrees(targets[i, 3]), 2), "name": names[i],
        "kind": kinds[i], "problem": problems[i],
        "answer_deg": {j: round(float(v), 2) for j, v in zip(ARM_JOINTS, angles[i], strict=True)},
        "error_mm": None if np.isnan(mm[i]) else round(float(mm[i]), 2),
        "tilt_deg": None if np.isnan(tilt[i]) else round(float(tilt[i]), 2),
        "yaw_error_deg": None if np.isnan(yaw[i]) else round(float(yaw[i]), 2),
        "beyond": [j for j, b in zip(ARM_JOINTS, beyond[i], strict=True) if b]})
    status = "ok" if ok.all() and len(ok) == count_targets(count) else "wrong"
    return {
        "function": "get_inverse_kinematics", "status": status, "causes": found,
        "targets": len(ok), "counts": counts,
        "error_mm": _stats(mm), "tilt_deg": _stats(tilt), "yaw_error_deg": _stats(np.abs(yaw)),
        "max_error_mm": _stats(mm)["max"], "max_error_deg": max(
            _stats(tilt)["max"] or 0.0, _stats(np.abs(yaw))["max"] or 0.0),
        "named": [{"name": n, "right": bool(k)} for n, k in zip(names, ok, strict=True) if n],
        "by_reach": _tally([r[0] for r in regions], failing),
        "by_side": _tally([r[1] for r in regions], failing),
        "by_height": _tally([r[2] for r in regions], failing),
        "by_branch": _tally([b or "no answer" for b in branches], failing),
        "beyond_limit": {j: int(beyond[:, k].sum()) for k, j in enumerate(ARM_JOINTS)
                         if beyond[:, k].any()},
        "at_limit": {j: int(at[:, k].sum()) for k, j in enumerate(ARM_JOINTS) if at[:, k].any()},
        "fk_module": results.get("fk_module", ""), "examples": examples,
        "out_of_reach": out_of_reach}


def count_targets(count: int = ik_targets.TARGET_COUNT) -> int:
    """How many targets a check asks (the named ones and ``count`` random ones)."""
    return len(ik_targets.build_targets(count)[1])
