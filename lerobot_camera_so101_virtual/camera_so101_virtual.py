"""The ``so101_virtual`` camera: lerobot's OpenCV camera reading a virtual SO-101's MJPEG stream."""

from __future__ import annotations

import cv2
from lerobot.cameras.opencv.camera_opencv import OpenCVCamera

from lerobot_camera_so101_virtual.configuration_so101_virtual import SO101VirtualCameraConfig

__all__ = ["SO101VirtualCamera"]


class SO101VirtualCamera(OpenCVCamera):
    """lerobot's ``OpenCVCamera`` on the stream: its reader thread, colour order, rotation.

    Only the settings differ: the size is checked, not set, and the rate is the server's.
    """

    def __init__(self, config: SO101VirtualCameraConfig):
        super().__init__(config)

    def __str__(self) -> str:
        return f"{self.__class__.__name__}({self.config.address})"

    def _configure_capture_settings(self) -> None:
        capture = self.videocapture
        width = int(round(capture.get(cv2.CAP_PROP_FRAME_WIDTH)))
        height = int(round(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if self.width is None or self.height is None:
            self.capture_width, self.capture_height = width, height
            turned = self.rotation in (cv2.ROTATE_90_CLOCKWISE, cv2.ROTATE_90_COUNTERCLOCKWISE)
            self.width, self.height = (height, width) if turned else (width, height)
        elif (self.capture_width, self.capture_height) != (width, height):
            raise RuntimeError(f"{self}: the stream is {width}x{height}, the config asks for "
                               f"{self.capture_width}x{self.capture_height}. Fix: start the arm "
                               f"with --camera-size {self.capture_width}x{self.capture_height} "
                               f"or set width: {width}, height: {height}.")
        if self.fps is None:
            self.fps = round(capture.get(cv2.CAP_PROP_FPS)) or 30

    @staticmethod
    def find_cameras() -> list[dict]:
        """A virtual arm's cameras are the lines ``virtual_so101.py --camera`` printed."""
        return []
