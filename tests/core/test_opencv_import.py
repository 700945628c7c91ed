"""OpenCV missing is one line that names the fix, never a traceback (no OpenCV needed here)."""

from __future__ import annotations

import sys

import pytest

from so101_kinematics.errors import OpenCVMissing
from so101_kinematics.opencv_import import require_opencv


def test_no_opencv_is_one_line_naming_the_fix(monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 raises ImportError
    with pytest.raises(OpenCVMissing) as error:
        require_opencv()
    assert "\n" not in str(error.value)
    assert "pip install -e '.[hw]'" in str(error.value)
    assert "opencv-python-headless" in str(error.value)


def test_an_opencv_without_the_detector_is_named(monkeypatch):
    class Old:
        __version__ = "4.5.0"
        aruco = object()

    monkeypatch.setitem(sys.modules, "cv2", Old())
    with pytest.raises(OpenCVMissing, match=r"OpenCV 4\.5\.0 has no cv2\.aruco\.ArucoDetector "
                                            r"\(needs 4\.7 or newer\)\. Fix: "):
        require_opencv()
