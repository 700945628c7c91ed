"""OpenCV, imported where it is used, or one line that says how to install it.

OpenCV comes with the hw extra (lerobot depends on ``opencv-python-headless``); the base
install (the simulated course) has none. The vision modules import it only inside the
functions that need it, through :func:`require_opencv`, so importing them never fails.
The detector needs OpenCV 4.7 or newer (``cv2.aruco.ArucoDetector``; 4.7 moved ArUco into
the main package with that class, 5.0 removed the old free functions).
"""

from __future__ import annotations

import importlib
from types import ModuleType

from so101_kinematics.errors import OpenCVMissing

__all__ = ["MIN_OPENCV", "OPENCV_FIX", "require_opencv"]

MIN_OPENCV = (4, 7)
"""The oldest OpenCV with ``cv2.aruco.ArucoDetector`` in the main package (4.7.0, 2022-12)."""
OPENCV_FIX = ("Fix: pip install -e '.[hw]' (lerobot brings OpenCV) or pip install "
              "opencv-python-headless.")


def require_opencv() -> ModuleType:
    """The ``cv2`` module, checked to have the ArUco detector.

    Raises:
        OpenCVMissing: OpenCV is not installed or older than :data:`MIN_OPENCV`; one line
            ending with the fix.
    """
    try:
        cv2 = importlib.import_module("cv2")
    except ImportError:
        raise OpenCVMissing(f"OpenCV (cv2) is not installed; the vision tools need it. "
                            f"{OPENCV_FIX}") from None
    if not hasattr(getattr(cv2, "aruco", None), "ArucoDetector"):
        raise OpenCVMissing(f"OpenCV {cv2.__version__} has no cv2.aruco.ArucoDetector (needs "
                            f"{MIN_OPENCV[0]}.{MIN_OPENCV[1]} or newer). {OPENCV_FIX}")
    return cv2
