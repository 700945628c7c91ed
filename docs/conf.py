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
