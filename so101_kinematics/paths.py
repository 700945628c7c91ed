"""Where the project's files are: the model, the shipped calibration, the docs (one place)."""

from pathlib import Path

__all__ = ["CALIBRATION_DIR", "DOCS_DIR", "MODEL_DIR", "REPO", "SCENE_PATH"]

REPO = Path(__file__).resolve().parent.parent
"""The project folder (the package lives in it, beside the course's files)."""
MODEL_DIR = REPO / "model"
SCENE_PATH = MODEL_DIR / "scene.xml"
"""The arm on its table with the cube and the targets: what every simulation loads."""
CALIBRATION_DIR = REPO / "calibration"
DOCS_DIR = REPO / "docs"
