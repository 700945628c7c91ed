"""Compare a student's FK (as the probe reported it) with this package, factor by factor.

Reference values: each factor is :func:`so101_kinematics.frames.joint_transform`, the
object frame is :func:`so101_kinematics.fast_fk.forward_kinematics_batch`. The chain up
to frame 5 is judged apart from ``get_g5t`` when the student's ``g_5t`` is this package's
or a known convention (:func:`~so101_kinematics.checker.diagnose.tool_convention`): the
student's FK is then compared with this package's ``g_w5`` times the student's own
``g_5t``. A ``g_5t`` that is neither (the identity: the object frame 107.6 mm off) is a
wrong final pose, and the FK is judged against this package's object frame: the pose
the arm reaches dominates the grade.
"""

from __future__ import annotations

import difflib
import functools

import numpy as np

from so101_kinematics.checker import diagnose, fk_returns
from so101_kinematics.fast_fk import forward_kinematics_batch
from so101_kinematics.frames import ARM_JOINTS, JOINT_LIMITS, joint_transform

__all__ = [
    "ANGLE_FRACTIONS", "FACTORS", "RANDOM_COUNT", "build_request", "compare_all",
    "factor_angles",
]

FACTORS = {"get_gw1": ("w1", "shoulder_pan"), "get_g12": ("12", "shoulder_lift"),
           "get_g23": ("23", "elbow_flex"), "get_g34": ("34", "wrist_flex"),
           "get_g45": ("45", "wrist_roll")}
"""The course's factor functions -> (transform name, joint)."""

ANGLE_FRACTIONS = (0.0, 0.35, -0.6, 0.9, -0.15, 0.7)
"""Test angles of each factor, as fractions of the joint's limit on that side."""

COURSE_CONFIGURATIONS = {
    "the course's starting configuration": (-45.0, 45.0, -45.0, 90.0, 0.0, 50.0),
    "the course's final configuration": (45.0, 45.0, -45.0, 90.0, 0.0, 50.0),
    "the all-zero configuration": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
}
"""Configurations the report names: arm joints [deg] then the gripper [0-100]."""

RANDOM_COUNT = 1000
RANDOM_SEED = 101
PRODUCT_COUNT = 10
"""Random configurations at which the FK is also compared with the product of the factors."""


def factor_angles(joint: str) -> list[float]:
    """Test angles [deg] of one joint, within its limits."""
    low, high = JOINT_LIMITS[joint]
    return [round(fraction * (high if fraction >= 0 else -low), 1)
            for fraction in ANGLE_FRACTIONS]


@functools.lru_cache(maxsize=4)
def configurations(count: int = RANDOM_COUNT, seed: int = RANDOM_SEED) -> np.ndarray:
    """(3 + count, 6): the course's configurations, then random ones within the limits.

    Cached (a class shares them) and read-only.
    """
    rng = np.random.default_rng(seed)
    joints = ARM_JOINTS + ("gripper",)
    low = np.array([JOINT_LIMITS[joint][0] for joint in joints])
    high = np.array([JOINT_LIMITS[joint][1] for joint in joints])
    rows = rng.uniform(low, high, size=(count, len(joints)))
    table = np.vstack([np.array(list(COURSE_CONFIGURATIONS.values())), rows])
    table.flags.writeable = False
    return table


def as_dict(row) -> dict[str, float]:
    """A configuration row as the course's dict (arm joints and the gripper)."""
    return {joint: float(value) for joint, value in zip(ARM_JOINTS + ("gripper",), row,
                                                        strict=True)}


@functools.lru_cache(maxsize=4)
def build_request(count: int = RANDOM_COUNT) -> dict:
    """What the probe evaluates: factor angles, FK configurations, product configurations.

    Cached (a class shares it): callers must not change it.
    """
    rows = configurations(count)
    dicts = [as_dict(row) for row in rows]
    without = {joint: dicts[0][joint] for joint in ARM_JOINTS}
    return {"angles": {name: factor_angles(joint) for name, (_, joint) in FACTORS.items()},
            "configurations": dicts, "without_gripper": without,
            "product_configurations": dicts[:len(COURSE_CONFIGURATIONS) + PRODUCT_COUNT],
            "joints": list(ARM_JOINTS)}


def pose_error(g_a: np.ndarray, g_b: np.ndarray) -> tuple[float, float]:
    """Distance [mm] and rotation angle [deg] between two 4x4 poses."""
    return (float(np.linalg.norm(g_a[:3, 3] - g_b[:3, 3]) * 1000),
            diagnose.rotation_angle_deg(g_a[:3, :3].T @ g_b[:3, :3]))


def _matrices(calls: list[dict], shape=(4, 4), angles=None):
    """(matrices, problem): the returned arrays if each is ``shape``, else a problem.

    ``angles``: the joint angle [deg] of each call, named with a NaN returned.
    """
    matrices = []
    for index, result in enumerate(calls):
        if "error" in result:
            return None, f"raised {result['error']}"
        if tuple(result["shape"]) != shape:
            return None, (f"returns shape {tuple(result['shape'])} ({result['type']}); "
                          f"expected a {shape[0]}x{shape[1]} array")
        matrix = np.asarray(result["value"], dtype=float)
        if not np.all(np.isfinite(matrix)):
            return None, "returns NaN or infinite numbers" + (
                f" at {angles[index]:g} deg" if angles is not None else "")
        matrices.append(matrix)
    return matrices, ""


def compare_factor(function: str, calls: list[dict] | None, angles, tolerance) -> dict:
    """One factor against ``joint_transform`` at its test angles.

    Args:
        function: e.g. "get_g45".
        calls: the probe's results for it (None: the function is missing).
        angles: the joint angles [deg] it was called with.
        tolerance: (mm, deg).

    Returns:
        A JSON-ready dict: status ("ok", "wrong", "missing", "broken"), errors per angle,
        the largest errors and the causes found.
    """
    name = FACTORS[function][0]
    if calls is None:
        return {"function": function, "status": "missing", "causes": ["not defined"]}
    matrices, problem = _matrices(calls, angles=angles)
    if matrices is None:
        return {"function": function, "status": "broken", "causes": [problem]}
    references = [joint_transform(name, angle) for angle in angles]
    errors = [pose_error(mine, model) for mine, model in zip(matrices, references, strict=True)]
    causes = diagnose.displacement_causes(name, angles, [m[:3, :3] for m in matrices],
                                          [m[:3, 3] for m in matrices])
    causes += diagnose.rotation_causes(name, angles, [m[:3, :3] for m in matrices])
    worst_mm = max(e[0] for e in errors)
    worst_deg = max(e[1] for e in errors)
    ok = worst_mm <= tolerance[0] and worst_deg <= tolerance[1]
    return {"function": function, "status": "ok" if ok else "wrong", "causes": causes,
            "angles_deg": list(angles), "error_mm": [e[0] for e in errors],
            "error_deg": [e[1] for e in errors], "max_error_mm": worst_mm,
            "max_error_deg": worst_deg, "matrices": [m.tolist() for m in matrices]}


def compare_tool(calls: list[dict] | None, tolerance) -> dict:
    """``get_g5t`` against this package's object frame; a known convention is accepted."""
    if calls is None:
        return {"function": "get_g5t", "status": "missing", "causes": ["not defined"]}
    matrices, problem = _matrices(calls)
    if matrices is None:
        return {"function": "get_g5t", "status": "broken", "causes": [problem]}
    matrix = matrices[0]
    error_mm, error_deg = pose_error(matrix, joint_transform("5t", 0.0))
    convention = diagnose.tool_convention(matrix)
    if error_mm <= tolerance[0] and error_deg <= tolerance[1]:
        status, causes = "ok", []
    else:
        status = "convention" if convention["accepted"] else "wrong"
        causes = [convention["text"]]
    return {"function": "get_g5t", "status": status, "causes": causes, "max_error_mm": error_mm,
            "max_error_deg": error_deg, "matrix": matrix.tolist()}


def _fk_arrays(calls: list[dict]):
    """(positions, rotations, problem) from the FK's returns; problem '' for the course's form."""
    positions, rotations, problem = [], [], ""
    for result in calls:
        if "error" in result:
            return None, None, f"raised {result['error']}"
        parts = result.get("parts")
        if parts is None:
            shape = tuple(result.get("shape") or ())
            if shape == (4, 4):
                matrix = np.asarray(result["value"], dtype=float)
                positions.append(matrix[:3, 3])
                rotations.append(matrix[:3, :3])
                problem = fk_returns.FOUR_BY_FOUR
                continue
            return None, None, (f"returns a {result['type']}; expected (position, rotation) "
                                "with shapes (3,) and (3, 3)")
        if len(parts) < 2 or any("error" in part for part in parts[:2]):
            return None, None, (f"returns {len(parts)} value(s); expected (position, rotation) "
                                "with shapes (3,) and (3, 3)")
        position, rotation = (np.asarray(part["value"], dtype=float) for part in parts[:2])
        if position.size != 3 or rotation.shape != (3, 3):
            return None, None, (f"returns shapes {tuple(parts[0]['shape'])} and "
                                f"{tuple(parts[1]['shape'])}; expected (3,) and (3, 3)")
        if len(parts) != 2 or tuple(parts[0]["shape"]) != (3,):
            problem = (f"returns {len(parts)} values with shapes "
                       f"{', '.join(str(tuple(p['shape'])) for p in parts)}; the course's form "
                       "is (position, rotation) with shapes (3,) and (3, 3)")
        positions.append(position.ravel())
        rotations.append(rotation)
    return np.array(positions), np.array(rotations), problem


def _where(rows: np.ndarray, index: int) -> str:
    """Configuration ``index`` of ``rows`` in words: the course's name, or its angles."""
    names = list(COURSE_CONFIGURATIONS)
    return names[index] if index < len(names) else ", ".join(
        f"{joint} {value:.1f}" for joint, value in as_dict(rows[index]).items())


def _stats(values: np.ndarray) -> dict:
    return {"median": float(np.median(values)), "max": float(np.max(values))}


def _batch_errors(positions, rotations, reference_positions, reference_rotations):
    """Position [mm] and orientation [deg] errors of many poses at once."""
    mm = np.linalg.norm(positions - reference_positions, axis=1) * 1000
    traces = np.einsum("nij,nij->n", rotations, reference_rotations)
    deg = np.degrees(np.arccos(np.clip((traces - 1.0) / 2.0, -1.0, 1.0)))
    return mm, deg


def compare_fk(results: dict, tool: dict, tolerance, rows: np.ndarray) -> dict:
    """``get_forward_kinematics`` at the course's and the random configurations.

    The judged error is against this package's chain up to frame 5 followed by the
    student's own ``g_5t`` (this package's if theirs is unusable); the error against this
    package's object frame is reported too.
    """
    calls = results.get("functions", {}).get("get_forward_kinematics")
    if calls is None:
        return {"function": "get_forward_kinematics", "status": "missing",
                "causes": ["not defined"]}
    positions, rotations, problem = _fk_arrays(calls)
    if positions is None:
        return {"function": "get_forward_kinematics", "status": "broken", "causes": [problem]}
    nan = fk_returns.nan_cause(positions, rotations, lambda i: _where(rows, i))
    if nan:
        return {"function": "get_forward_kinematics", "status": "broken", "causes": [nan]}
    package_p, package_r = forward_kinematics_batch(rows[:, :5])
    g_5t = joint_transform("5t", 0.0)
    student_tool = np.asarray(tool["matrix"]) if "matrix" in tool else g_5t
    # g_w5 = g_wt g_5t^-1, then the student's tool: g_wt' = g_w5 g_5t^-1 g_5t'.
    change = np.linalg.inv(g_5t) @ student_tool
    chain_r = package_r @ change[:3, :3]
    chain_p = package_p + package_r @ change[:3, 3]
    chain_mm, chain_deg = _batch_errors(positions, rotations, chain_p, chain_r)
    raw_mm, raw_deg = _batch_errors(positions, rotations, package_p, package_r)
    course = len(COURSE_CONFIGURATIONS)
    changed = fk_returns.changed_cause(calls)
    if problem == fk_returns.FOUR_BY_FOUR:
        problem = fk_returns.form_cause(chain_mm, chain_deg)
    causes = [problem] if problem else []
    causes += [changed] if changed else []
    causes += _fk_causes(results, positions, rotations, chain_p, chain_r, student_tool,
                         check_product=not changed)  # a changed input: not the product's fault
    judged = "chain"
    if tool.get("status") not in ("ok", "convention") and np.median(raw_mm) > tolerance[0]:
        chain_mm, chain_deg = raw_mm, raw_deg  # a wrong object frame: the final pose is judged
        judged = "object frame"
        causes.append(f"the object frame is {np.median(raw_mm):.1f} mm from this package's "
                      "(median): your get_g5t is wrong and is not a known convention, so the "
                      "pose the arm reaches is wrong; judged against this package's object "
                      "frame")
    ok = (not problem and not changed and chain_mm.max() <= tolerance[0]
          and chain_deg.max() <= tolerance[1])
    return {
        "function": "get_forward_kinematics",
        "status": ("ok" if ok else "broken" if problem.startswith(fk_returns.FOUR_BY_FOUR)
                   else "wrong"),
        "causes": causes, "judged_against": judged,
        "course": [{"name": name, "error_mm": float(chain_mm[i]), "error_deg": float(chain_deg[i]),
                    "position_m": positions[i].tolist(),
                    "package_position_m": package_p[i].tolist(),
                    "error_to_package_object_frame_mm": float(raw_mm[i])}
                   for i, name in enumerate(COURSE_CONFIGURATIONS)],
        "random_count": int(len(rows) - course),
        "error_mm": _stats(chain_mm[course:]), "error_deg": _stats(chain_deg[course:]),
        "max_error_mm": float(chain_mm.max()), "max_error_deg": float(chain_deg.max()),
        "to_package_object_frame_mm": _stats(raw_mm), "to_package_object_frame_deg":
            _stats(raw_deg), "gripper_key": _gripper_note(results)}


def _fk_causes(results, positions, rotations, chain_p, chain_r, student_tool,
               check_product: bool = True) -> list[str]:
    """Mistakes visible only in the whole FK: units, a transposed rotation, the product.

    The product is judged with ``check_product`` only (not when the FK changed its input:
    that explains a product apart).
    """
    causes = []
    if np.allclose(positions, chain_p * 1000, rtol=1e-3, atol=1e-3):
        return ["the position is in millimetres; the FK returns metres"]
    if np.allclose(rotations, np.transpose(chain_r, (0, 2, 1)), atol=1e-4) and \
            not np.allclose(rotations, chain_r, atol=1e-4):
        causes.append("the rotation is transposed (R.T): return gwt[0:3, 0:3]")
    products = results.get("products") or []
    worst = star = 0.0
    wrong_part = _position_part(positions, chain_p, chain_r)
    for index, row in enumerate(products):
        matrices = [row[name] for name in FACTORS]
        if any("error" in m or tuple(m["shape"]) != (4, 4) for m in matrices):
            return causes
        factors = [np.asarray(matrix["value"], dtype=float) for matrix in matrices]
        product = functools.reduce(np.matmul, factors) @ student_tool
        elementwise = functools.reduce(np.multiply, factors) * student_tool
        mine = np.eye(4)
        mine[:3, :3], mine[:3, 3] = rotations[index], positions[index]
        worst = max(worst, _apart(mine, product))
        star = max(star, _apart(mine, elementwise))
    if worst > 0.01 and star <= 1e-6:
        causes.append("get_forward_kinematics multiplies the factors element by element (*): "
                      "numpy's * is not the matrix product. Fix: gwt = gw1 @ g12 @ g23 @ g34 @ "
                      "g45 @ g5t")
    elif wrong_part:
        causes.append(f"the position is {wrong_part}, not gwt's last column. Fix: position = "
                      "gwt[0:3, 3] (rows 0-2 of column 3)")
    elif worst > 0.01 and check_product:
        causes.append("get_forward_kinematics is not the product gw1 @ g12 @ g23 @ g34 @ g45 @ "
                      f"g5t of your own factors (up to {worst:.2f} mm/deg apart): check the "
                      "order of the product and which joint goes to which factor")
    return causes


def _apart(a: np.ndarray, b: np.ndarray) -> float:
    """How far two 4x4 matrices are apart: [mm] for the position, [deg]-like for the 3x3.

    Element by element (not as poses): either may not be a rigid transform.
    """
    return float(max(np.linalg.norm(a[:3, 3] - b[:3, 3]) * 1000,
                     np.degrees(np.abs(a[:3, :3] - b[:3, :3]).max())))


def _position_part(positions, chain_p, chain_r) -> str:
    """Which other part of gwt the FK returned as its position ('' if none matches)."""
    if len(positions) == 0 or np.allclose(positions, chain_p, atol=1e-4):
        return ""
    if np.allclose(positions, 0.0, atol=1e-9):
        return "gwt's bottom row, gwt[3, 0:3] (always 0, 0, 0)"
    for index in range(3):
        if np.allclose(positions, chain_r[:, index, :], atol=1e-6):
            return f"a row of the rotation, gwt[{index}, 0:3]"
        if np.allclose(positions, chain_r[:, :, index], atol=1e-6):
            return f"a column of the rotation, gwt[0:3, {index}] (the tool's {'xyz'[index]} axis)"
    return ""


def _gripper_note(results: dict) -> str:
    without = results.get("without_gripper")
    if without is None:
        return "not tried"
    if "error" in without:
        return ("needs a 'gripper' key it does not use (without one: "
                f"{without['error']}); the course's dicts have it, so this is only a note")
    return "works with or without a 'gripper' key"


def compare_all(results: dict, tolerance, count: int = RANDOM_COUNT) -> dict:
    """Every test of one submission: the five factors, ``get_g5t``, the whole FK."""
    functions = results.get("functions", {})
    tests = [compare_factor(function, functions.get(function),
                            factor_angles(joint), tolerance)
             for function, (_, joint) in FACTORS.items()]
    tool = compare_tool(functions.get("get_g5t"), tolerance)
    tests.append(tool)
    tests.append(compare_fk(results, tool, tolerance, configurations(count)))
    names = results.get("names", [])
    for test in tests:
        if test["status"] == "missing":
            close = _close_names(test["function"], names)
            if close:
                test["causes"] = [f"not defined; {close!r} looks like it: name it "
                                  f"{test['function']} (the course's name)"]
    causes = {FACTORS[t["function"]][0]: t["causes"] for t in tests if t["function"] in FACTORS}
    return {"tests": tests, "note": diagnose.diagram_note(causes) or diagnose.units_note(causes)}


def _close_names(wanted: str, names: list[str]) -> str:
    candidates = [n for n in names if n not in FACTORS and n not in ("get_g5t",
                                                                        "get_forward_kinematics")]
    lowered = {n.lower().replace("_", ""): n for n in candidates}
    key = wanted.lower().replace("_", "")
    if key in lowered:
        return lowered[key]
    close = difflib.get_close_matches(wanted, candidates, n=1, cutoff=0.8)
    return close[0] if close else ""

