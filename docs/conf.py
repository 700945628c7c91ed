"""Sphinx configuration: the docs site from docs/ (MyST Markdown), built by ``./dev.sh docs``.

The API reference lists every module of ``so101_kinematics``; the list is made here by
walking the package, so a module that moves or is added appears without editing a page.
"""

from __future__ import annotations

import os
import pkgutil
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
sys.path.insert(0, str(REPO))
os.environ.setdefault("MUJOCO_GL", "egl")  # importing the sim modules needs no display

project = "so101-kinematics"
author = "so101-kinematics contributors"
copyright = "2026, so101-kinematics contributors"  # noqa: A001 (Sphinx's name)

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build", "_generated_*", "fk_table.md", "Thumbs.db", ".DS_Store"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]
html_theme = "alabaster"
html_title = "so101-kinematics"
# fk_table.md is written by `python test_fk_mujoco.py --table` and included by fk.md.

suppress_warnings: list[str] = []

# Not in the docs environment: the hardware extra (lerobot, PyTorch), Feetech's SDK, pandas.
autodoc_mock_imports = ["lerobot", "torch", "scservo_sdk", "pandas", "serial"]
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "show-inheritance": True}
napoleon_google_docstring = True
napoleon_numpy_docstring = False

# Modules left out of the API page, each with its reason (none today).
API_EXCLUDED: dict[str, str] = {}


def package_modules() -> list[str]:
    """Every module of the package, found by walking it (sorted, packages included)."""
    import so101_kinematics

    names = ["so101_kinematics"]
    for info in pkgutil.walk_packages(so101_kinematics.__path__, "so101_kinematics."):
        names.append(info.name)
    return sorted(n for n in names if n not in API_EXCLUDED and not n.endswith("__main__"))


def write_api_page() -> None:
    """Write docs/_generated_api.md: one automodule per module (read by api.md)."""
    lines = []
    for name in package_modules():
        lines += [f"## `{name}`", "", "```{eval-rst}", f".. automodule:: {name}", "```", ""]
    target = DOCS / "_generated_api.md"
    text = "\n".join(lines)
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


write_api_page()


# --- The measurements page: the newest benchmarks JSON, rendered when the site is built -------
# benchmarks/run.py --json writes {key: {"median", "min", "max"} or a number, "_meta": {...}};
# the newest file of benchmarks/results/ (by its date) becomes docs/_generated_measurements.md,
# which measurements.md includes. The goals are run.py's own GOALS, read from its source.
FIGURES = {
    'fk_seed_style_us': "FK, the assignment's style (np.block per call) [us]",
    'fk_product_us': "`get_forward_kinematics`, the course's product of six factors [us]",
    'fk_single_us': 'the closed form (`fast_fk.forward_kinematics`) per call [us]',
    'mujoco_kinematics_us': 'MuJoCo `mj_kinematics` + site read, from Python [us]',
    'fk_single_vs_mujoco': 'closed form / MuJoCo',
    'fk_batch_ns_per_config': 'batch FK, 1e6 configurations [ns per configuration]',
    'ik_solve_us': 'IK, top-down with yaw, per target [us]',
    'ik_success_rate': 'IK success on reachable samples',
    'sim_realtime_factor': 'headless pick-and-place with the cube, the default servo '
                           '(STS3215 + feed-forward) [x real time]',
    'sim_realtime_factor_half_step': 'the same with a 2 ms step, reference [x real time]',
    'sim_realtime_factor_ideal_servo': 'the same on the ideal servo (`--servo ideal`), '
                                       'reference [x real time]',
    'servo_model_cost': "the servo model's cost: ideal / default",
    'mujoco_arm_step_us': 'reference: one `mj_step` of the arm alone [us]',
    'record_fps': 'recording 640x480 @ 30 fps: frames per wall second',
    'record_wall_over_video_duration': 'recording wall time / video duration',
    'hw_period_p99_error_ms_100hz': 'hardware loop at 100 Hz, p99 period error [ms]',
    'hw_period_p99_error_ms_200hz': 'hardware loop at 200 Hz, p99 period error [ms]',
    'wire_cycle_ms': '6-motor sync_read + sync_write, 1 Mbaud wire timing [ms]',
    'wire_time_ms': 'of which bytes on the wire [ms]',
    'wire_cycle_emulator_added_ms': 'of which the virtual arm adds [ms]',
}


def _goals() -> dict[str, tuple[str, float]]:
    """benchmarks/run.py's GOALS (comparison, bound) per key, read without importing it."""
    import ast

    tree = ast.parse((REPO / "benchmarks" / "run.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "GOALS":
            goals = ast.literal_eval(node.value)
            return {key: (op, bound) for key, (op, bound, _) in goals.items()}
    return {}


def write_measurements_page() -> None:
    """Render the newest benchmarks/results/*.json as a dated table with its machine."""
    import json

    runs = sorted((REPO / "benchmarks" / "results").glob("*.json"),
                  key=lambda p: json.loads(p.read_text())["_meta"]["date"])
    if not runs:
        text = "No benchmark results are committed (`benchmarks/results/*.json`).\n"
    else:
        results = json.loads(runs[-1].read_text())
        meta, goals = results["_meta"], _goals()
        lines = [f"Run of {meta['date']} on {meta['machine']}, Python {meta['python']}"
                 f"{' (--quick)' if meta.get('quick') else ''}, {meta['wall_s']:.0f} s in all"
                 f" (`benchmarks/results/{runs[-1].name}`"
                 + (f"; {meta['note']}" if meta.get("note") else "") + ").", "",
                 "| figure | median | spread (min - max) | goal |", "|---|---|---|---|"]
        for key, entry in results.items():
            if key.startswith("_") or key == "generator":
                continue
            what = FIGURES.get(key, key)
            if isinstance(entry, dict):
                value = f"{entry['median']:.3g}"
                spread = f"{entry['min']:.3g} - {entry['max']:.3g}"
                median = entry["median"]
            else:
                value, spread, median = f"{entry:.3g}", "", entry
            goal = ""
            if key in goals:
                op, bound = goals[key]
                met = {"<=": median <= bound, "<": median < bound, ">=": median >= bound}[op]
                goal = f"{op} {bound:g}" + ("" if met else " **missed**")
            lines.append(f"| {what} (`{key}`) | {value} | {spread} | {goal} |")
        text = "\n".join(lines) + "\n"
    target = DOCS / "_generated_measurements.md"
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


write_measurements_page()


# --- Docstrings written for a reader of the source, made valid reStructuredText ----------------
# Two habits of the package's docstrings that are fine as plain text but not as RST; they are
# adapted here, when the page is built, rather than in every module:
# - ``|x - y|`` (an absolute value) reads as an RST substitution: the bars are escaped;
# - a list straight under the line that introduces it ("Rules:\n- ..."): a blank line is put
#   between them, as RST needs.
_ABS = re.compile(r"(?<![\\|`])\|(?=[^\s|])([^|`\n]*?[^\s|\\])\|(?![|_])")
_ITEM = re.compile(r"^\s*[-*] ")


def _rst_docstring(app, what, name, obj, options, lines):
    """Escape absolute-value bars and open a blank line before an introduced list."""
    fixed: list[str] = []
    for line in lines:
        stripped = line.lstrip()
        table_row = stripped.startswith("+-") or (stripped.startswith("|")
                                                   and stripped.rstrip().endswith("|"))
        if not table_row:
            line = _ABS.sub(r"\\|\1\\|", line)
        if _ITEM.match(line) and fixed and fixed[-1].rstrip().endswith(":") \
                and not _ITEM.match(fixed[-1]):
            fixed.append("")
        fixed.append(line)
    lines[:] = fixed


def setup(app):
    """Connect the docstring adapter (after napoleon's, which registered first)."""
    app.connect("autodoc-process-docstring", _rst_docstring)
