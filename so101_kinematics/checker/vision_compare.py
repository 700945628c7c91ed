"""``so101-check-vision``'s judgement: a student's camera-to-base answers against the truth.

The assignment (``docs/checkers.md``): in one file,

- ``camera_to_base(cam_pos, cam_xmat, p_cam) -> p_base``: ``cam_pos`` (3,) and ``cam_xmat``
  (9,) are MuJoCo's ``d.cam_xpos`` / ``d.cam_xmat`` of a camera (MuJoCo's camera axes: x
  right, y up, looking along -z; the base frame is the world's), ``p_cam`` (3,) a point in
  OpenCV's camera frame (x right, y down, z forward) [m], e.g. ``solvePnP``'s ``tvec``;
  returns the point in the base frame (3,) [m];
- ``tag_pose_in_base(corners, K, cam_pos, cam_xmat) -> g_base_tag``: ``corners`` (4, 2) the
  target tag's corners [px] in ``cv2.aruco``'s order (top-left, top-right, bottom-right,
  bottom-left), ``K`` the camera matrix [px]; the target tag is the course's: a 40 mm black
  marker printed on a 52 mm white square; returns the tag's pose (4, 4) [m] in the base frame.

Each answer is compared with the simulator's truth over several camera poses, and, when it
is wrong, with the answers of the usual mistakes (:func:`camera_variants`,
:func:`tag_variants`): an answer that matches one names it. Numpy only (no MuJoCo): the
cases come from ``vision/vision_cases.py``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "FLIP", "MISTAKES", "VISION_POINTS", "VISION_TOLERANCE", "build_request", "camera_variants",
    "judge_vision", "tag_variants",
]

FLIP = np.diag([1.0, -1.0, -1.0])
"""OpenCV's camera frame in MuJoCo's: the turn of 180 deg about x."""

VISION_TOLERANCE = {"camera_to_base": (1.0, None), "tag_pose_in_base": (5.0, 3.0)}
"""[mm], [deg] per function: a transform is exact; a pose from 4 corners of a 40 mm tag 25 to
35 cm away is within a few millimetres and a degree or two (the reference's own error)."""

VISION_POINTS = {"camera_to_base": 50.0, "tag_pose_in_base": 50.0}
"""Gradescope points per function (100 in all)."""

MARKER, FACE = 0.040, 0.052
"""[m] The target tag's black marker and its printed white square."""

MISTAKES = {
    "axes": "OpenCV's camera axes taken as MuJoCo's (the 180 deg turn about x missed): use "
            "R = cam_xmat @ diag(1, -1, -1), OpenCV's frame in MuJoCo's",
    "transposed": "the rotation transposed (R.T used for R): cam_xmat, reshaped to 3x3 "
                  "row by row (numpy's order), has the camera's axes in the base frame as its "
                  "columns; use it as it is, not transposed or reshaped column by column",
    "axes+transposed": "both: the 180 deg turn about x missed and the rotation transposed",
    "inverse": "the inverse transform (base to camera, R.T @ (p - c)) used for camera to base",
    "no_translation": "the camera's position left out (p_base = R @ p_cam, no + cam_pos)",
    "mm": "millimetres returned: the base frame's unit is the metre",
    "size_mm": "the tag's size in millimetres (40) given to solvePnP: every distance comes out "
               "1000x; use 0.040 m",
    "size_face": "the printed square's size (52 mm, the white border included) used as the "
                 "marker's: distances come out 1.3x; the black marker is 40 mm",
    "size_half": "half the marker's size used as its edge (corners at +-size, not +-size/2): "
                 "distances come out 2x",
    "pixels": "pixels used as metres: the tag's position is its image point (u, v) [px]; "
              "solvePnP turns the corners into metres",
    "corner_order": "the tag's corners matched in another order: its position is right, its "
                    "rotation turned by a multiple of 90 deg about its z; use the detector's "
                    "order TL, TR, BR, BL with the square's corners (-s/2, s/2), (s/2, s/2), "
                    "(s/2, -s/2), (-s/2, -s/2)",
}
"""A mistake's name -> how the report names it (what to do)."""


def _rotation(cam_xmat) -> np.ndarray:
    return np.asarray(cam_xmat, dtype=float).reshape(3, 3)


def camera_variants(cam_pos, cam_xmat, p_cam) -> dict[str, np.ndarray]:
    """The right answer (``"ok"``) and each mistake's answer for one point [m].

    A key ``name:form`` is another form of the mistake ``name`` (:data:`MISTAKES`).
    """
    c, r, p = np.asarray(cam_pos, dtype=float), _rotation(cam_xmat), np.asarray(p_cam, float)
    right = r @ FLIP
    return {"ok": right @ p + c, "axes": r @ p + c, "transposed": r.T @ FLIP @ p + c,
            "transposed:whole": right.T @ p + c, "axes+transposed": r.T @ p + c,
            "inverse": right.T @ (p - c), "inverse:axes": r.T @ (p - c),
            "no_translation": right @ p, "mm": 1000.0 * (right @ p + c)}


def tag_variants(cam_pos, cam_xmat, t_cam, corners) -> dict[str, np.ndarray]:
    """The tag's position [m] right and as each mistake gives it.

    From the reference's ``solvePnP`` translation ``t_cam`` (OpenCV frame, the true 40 mm).
    """
    out = camera_variants(cam_pos, cam_xmat, t_cam)
    for name, size in (("size_mm", 40.0), ("size_face", FACE), ("size_half", 2 * MARKER)):
        out[name] = camera_variants(cam_pos, cam_xmat, np.asarray(t_cam) * size / MARKER)["ok"]
    u, v = np.mean(np.asarray(corners, dtype=float), axis=0)
    out["pixels"] = np.array([u, v, math.nan])  # x, y compared
    return out


def build_request(cases: list[dict], module_name: str = "student_vision") -> dict:
    """The probe's request: the inputs of every call (``probe.probe_vision``)."""
    return {"kind": "vision", "module_name": module_name, "cases": [
        {"cam_pos": case["cam_pos"], "cam_xmat": case["cam_xmat"], "K": case["K"],
         "corners": case["corners"], "points": case["points"]} for case in cases]}


def _vector(answer: dict, size: int) -> np.ndarray | None:
    if "value" not in answer:
        return None
    value = np.asarray(answer["value"], dtype=float)
    return value.reshape(-1)[:size] if value.size >= size else None


def _pose(answer: dict) -> tuple[np.ndarray | None, np.ndarray | None, str]:
    """(position, rotation, problem) of a ``tag_pose_in_base`` answer (4x4, or (p, R))."""
    if "error" in answer:
        return None, None, answer["error"]
    if answer.get("parts"):
        parts = [np.asarray(p.get("value"), dtype=float) for p in answer["parts"]]
        shapes = [p.shape for p in parts]
        if len(parts) == 2 and shapes == [(3,), (3, 3)]:
            return parts[0], parts[1], ""
        return None, None, f"returns a tuple of shapes {shapes}; expected a 4x4 pose"
    value = np.asarray(answer.get("value"), dtype=float)
    if value.shape != (4, 4):
        return None, None, f"returns shape {tuple(value.shape)}; expected a 4x4 pose"
    return value[:3, 3], value[:3, :3], ""


def _matches(answers, variants_per_case, tolerance_m: float) -> list[str]:
    """The mistakes whose answers every one of the student's is within tolerance of."""
    names = [n for n in variants_per_case[0] if n != "ok"]
    found = []
    for name in names:
        ok = True
        for answer, variants in zip(answers, variants_per_case, strict=True):
            want = variants[name]
            keep = np.isfinite(want)
            scale = max(tolerance_m, 0.01 * float(np.linalg.norm(want[keep])))
            if answer is None or np.linalg.norm(answer[keep] - want[keep]) > scale:
                ok = False
                break
        if ok and name.split(":")[0] not in found:
            found.append(name.split(":")[0])
    return found


def _test(function: str, errors_mm: list, errors_deg: list, problems: list, causes: list,
          tolerance) -> dict:
    worst_mm = max(errors_mm) if errors_mm else None
    worst_deg = max(errors_deg) if errors_deg else None
    good = (not problems and worst_mm is not None and worst_mm <= tolerance[0]
            and (tolerance[1] is None or worst_deg <= tolerance[1]))
    return {"function": function, "status": "ok" if good else "wrong",
            "max_error_mm": worst_mm, "max_error_deg": worst_deg, "causes": causes + problems,
            "count": len(errors_mm)}


def _judge_camera(answers: list, cases: list[dict], tolerance) -> dict:
    flat, variants, errors, problems = [], [], [], []
    for case, per_case in zip(cases, answers, strict=True):
        for point, truth, answer in zip(case["points"], case["truth_points"], per_case,
                                        strict=True):
            value = _vector(answer, 3)
            if value is None or not np.all(np.isfinite(value)):
                problem = answer.get("error") or f"returns {answer.get('shape')}; expected (3,)"
                problems.append(f"at p_cam {np.round(point, 3).tolist()}: {problem}")
            flat.append(value)
            variants.append(camera_variants(case["cam_pos"], case["cam_xmat"], point))
            if value is not None:
                errors.append(1000.0 * float(np.linalg.norm(value - np.asarray(truth))))
    test = _test("camera_to_base", errors, [], problems[:1], [], tolerance)
    if test["status"] != "ok" and not problems:
        test["causes"] = [MISTAKES[n] for n in _matches(flat, variants, 1e-3)] or [
            "matches none of the usual mistakes: check p_base = R @ diag(1, -1, -1) @ p_cam + c, "
            "R = cam_xmat as 3x3, c = cam_pos"]
    return test


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    cosine = (np.trace(a.T @ b) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cosine))))


def _judge_tag(answers: list, cases: list[dict], tolerance) -> dict:
    positions, variants, errors_mm, errors_deg, problems, turned = [], [], [], [], [], []
    for case, answer in zip(cases, answers, strict=True):
        position, rotation, problem = _pose(answer)
        truth = np.asarray(case["truth_tag"], dtype=float)
        if problem or not np.all(np.isfinite(position)) or not np.all(np.isfinite(rotation)):
            problems.append(problem or "returns NaN")
            position = None
        else:
            errors_mm.append(1000.0 * float(np.linalg.norm(position - truth[:3, 3])))
            errors_deg.append(_angle_deg(truth[:3, :3], rotation))
            about_z = truth[:3, :3].T @ rotation  # the answer in the tag's own frame
            yaw = math.degrees(math.atan2(about_z[1, 0], about_z[0, 0]))
            turned.append(errors_deg[-1] > tolerance[1] and abs(about_z[2, 2]) > 0.99
                          and min(abs(yaw - k) for k in (-180, -90, 90, 180)) < tolerance[1])
        positions.append(position)
        variants.append(tag_variants(case["cam_pos"], case["cam_xmat"], case["t_cam"],
                                     case["corners"]))
    test = _test("tag_pose_in_base", errors_mm, errors_deg, problems[:1], [], tolerance)
    if test["status"] != "ok" and not problems:
        position_ok = max(errors_mm) <= tolerance[0]
        names = ["corner_order"] if position_ok and all(turned) else [] if position_ok else \
            _matches(positions, variants, tolerance[0] / 1000.0)
        test["causes"] = [MISTAKES[n] for n in names] or [
            "the position is right, the rotation is not: g_base_tag's rotation is "
            "R_base_cam @ Rodrigues(rvec), with R_base_cam = cam_xmat @ diag(1, -1, -1)"
            if position_ok else "matches none of the usual mistakes: check solvePnP's inputs "
            "(the corners' order and the marker's size in metres) and the transform"]
    return test


def judge_vision(results: dict, cases: list[dict], tolerance: dict | None = None) -> list[dict]:
    """One test per function of the assignment.

    Each: ``status`` ok, wrong or missing, the worst errors [mm, deg] against the
    simulator's truth, and ``causes`` (the mistakes named).
    """
    tolerance = dict(VISION_TOLERANCE, **(tolerance or {}))
    functions = results.get("functions", {})
    tests = []
    for name, judge_one in (("camera_to_base", _judge_camera), ("tag_pose_in_base", _judge_tag)):
        if name not in functions:
            tests.append({"function": name, "status": "missing", "max_error_mm": None,
                          "max_error_deg": None, "causes": [f"no function {name}"], "count": 0})
            continue
        tests.append(judge_one(functions[name], cases, tolerance[name]))
    return tests
