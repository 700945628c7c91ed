"""The checker's outputs: the student's text report, the JSON, Gradescope's results.json, CSV.

Scoring (Gradescope and CSV): each test scores its points when within the tolerance,
else 0 (no partial credit inside a test). ``get_g5t`` also scores full points when it
differs from this package only by a known convention (a named tool point, axes turned
by a half or quarter turn). A submission that cannot be checked (missing file, crash on
import, time-out) scores 0 on every test, with the reason in each test's output.
The points are :data:`DEFAULT_POINTS`, changed with ``--points NAME=POINTS``.
"""

from __future__ import annotations

import csv
import io
import json

__all__ = [
    "CSV_COLUMNS", "DEFAULT_POINTS", "PASSING", "csv_report", "gradescope_results",
    "json_report", "score", "text_report",
]

DEFAULT_POINTS = {"get_gw1": 10.0, "get_g12": 10.0, "get_g23": 10.0, "get_g34": 10.0,
                  "get_g45": 10.0, "get_g5t": 10.0, "get_forward_kinematics": 40.0}
"""Points per test (100 in all)."""

PASSING = ("ok", "convention")
_LABEL = {"ok": "ok", "convention": "convention", "wrong": "WRONG", "missing": "MISSING",
          "broken": "BROKEN"}


def score(check: dict, points: dict[str, float]) -> list[dict]:
    """One Gradescope-style test per function: name, score, max_score, status, output."""
    tests = []
    for name, max_score in points.items():
        test = next((t for t in check.get("tests", []) if t["function"] == name), None)
        if test is None:
            tests.append({"name": name, "score": 0.0, "max_score": max_score,
                          "status": "failed", "output": f"not checked: {check['reason']}"})
            continue
        passed = test["status"] in PASSING
        tests.append({"name": name, "score": max_score if passed else 0.0,
                      "max_score": max_score, "status": "passed" if passed else "failed",
                      "output": test_text(test)})
    return tests


def _errors(test: dict) -> str:
    if "error_mm" in test and isinstance(test["error_mm"], dict):
        return (f"max {test['max_error_mm']:.2f} mm, {test['max_error_deg']:.2f} deg (median "
                f"{test['error_mm']['median']:.2f} mm over {test['random_count']} random "
                "configurations)")
    if "max_error_mm" in test:
        return f"{test['max_error_mm']:.2f} mm, {test['max_error_deg']:.2f} deg"
    return ""


def test_text(test: dict) -> str:
    """What one test found, for a student: errors, then the causes."""
    lines = [f"{test['function']}: {_LABEL[test['status']]}"
             + (f", {_errors(test)}" if _errors(test) else "")]
    lines += [f"  {cause}" for cause in test.get("causes", [])]
    if test["function"] == "get_forward_kinematics" and "course" in test:
        lines.append("  judged against this package's object frame (your g5t is wrong);"
                     if test.get("judged_against") == "object frame" else
                     "  judged as this package's chain up to frame 5 followed by your g5t;")
        for row in test["course"]:
            lines.append(f"  at {row['name']}: {row['error_mm']:.2f} mm, "
                         f"{row['error_deg']:.2f} deg")
        frame = test["to_package_object_frame_mm"]
        lines.append(f"  to this package's object frame (your g5t included): median "
                     f"{frame['median']:.2f} mm, max {frame['max']:.2f} mm")
        lines.append(f"  gripper key: {test['gripper_key']}")
    return "\n".join(lines)


def text_report(check: dict, points: dict[str, float]) -> str:
    """The short report a student reads."""
    tolerance = check["tolerance"]
    lines = [f"Checking {check['file']} (tolerance {tolerance[0]:g} mm, {tolerance[1]:g} deg)"]
    if check["verdict"] == "error":
        lines.append(f"Cannot check it: {check['reason']}")
    for test in check.get("tests", []):
        lines.append(test_text(test))
    if check.get("note"):
        lines.append(check["note"])
    output = check.get("output") or ""
    if check.get("output_size"):
        shown = " | ".join(output.strip().splitlines()[:3])[:200]
        lines.append(f"(your module printed {check['output_size']} characters: {shown})")
    total = sum(t["score"] for t in score(check, points))
    failed = [t["function"] for t in check.get("tests", []) if t["status"] not in PASSING]
    verdict = {"pass": "within the tolerance",
               "fail": f"outside the tolerance ({', '.join(failed)})",
               "error": "not checked"}[check["verdict"]]
    lines.append(f"Verdict: {verdict}. Score {total:g}/{sum(points.values()):g}.")
    return "\n".join(lines)


def gradescope_results(check: dict, points: dict[str, float]) -> dict:
    """Gradescope's autograder ``results.json`` for one submission."""
    tests = score(check, points)
    summary = text_report(check, points).splitlines()[-1]
    if check["verdict"] == "error":
        summary = f"Could not check your file: {check['reason']}"
    return {"score": sum(t["score"] for t in tests), "execution_time": round(check["seconds"], 2),
            "output": summary, "visibility": "visible", "stdout_visibility": "hidden",
            "tests": tests}


def json_report(checks: list[dict]) -> str:
    """The full comparison: one submission's dict, or a list of them."""
    return json.dumps(checks[0] if len(checks) == 1 else checks, indent=1)


CSV_COLUMNS = ("student", "file", "verdict", "score", "max_score", *DEFAULT_POINTS,
               "fk_max_mm", "fk_median_mm", "fk_max_deg", "object_frame_median_mm",
               "problems", "seconds")


def csv_report(checks: list[dict], points: dict[str, float]) -> str:
    """One row per submission (the folder name is the student)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for check in checks:
        tests = {t["name"]: t["score"] for t in score(check, points)}
        fk = next((t for t in check.get("tests", [])
                   if t["function"] == "get_forward_kinematics" and "course" in t), None)
        problems = [f"{t['function']}: {'; '.join(t['causes'])}" for t in check.get("tests", [])
                    if t["status"] not in PASSING or t["status"] == "convention"]
        if check["verdict"] == "error":
            problems = [check["reason"]]
        writer.writerow({
            "student": check["student"], "file": check["file"], "verdict": check["verdict"],
            "score": sum(tests.values()), "max_score": sum(points.values()),
            **{name: tests.get(name, 0.0) for name in DEFAULT_POINTS},
            "fk_max_mm": _round(fk and fk["max_error_mm"]),
            "fk_median_mm": _round(fk and fk["error_mm"]["median"]),
            "fk_max_deg": _round(fk and fk["max_error_deg"]),
            "object_frame_median_mm": _round(fk and fk["to_package_object_frame_mm"]["median"]),
            "problems": " | ".join(problems), "seconds": round(check["seconds"], 2)})
    return buffer.getvalue()


def _round(value) -> str:
    return "" if value is None else f"{value:.3f}"
