"""The ``so101_virtual`` camera's configuration, registered with lerobot's camera configs."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.cameras.configs import CameraConfig, ColorMode, Cv2Backends, Cv2Rotation

__all__ = ["SO101VirtualCameraConfig"]


@CameraConfig.register_subclass("so101_virtual")
@dataclass
class SO101VirtualCameraConfig(CameraConfig):
    """A virtual SO-101's served camera.

    Attributes:
        address: what ``virtual_so101.py`` printed: ``http://127.0.0.1:PORT/NAME.mjpg``.
        fps: the rate the arm serves (``--camera-fps``, default 30); not set on the stream.
        width, height: [px] checked against the stream (``--camera-size``); None: the stream's.
        color_mode: frames returned as RGB (lerobot's default) or BGR.
        rotation: as lerobot's OpenCV camera's.
        warmup_s: [s] reading frames in ``connect`` before it returns.
    """

    address: str = ""
    color_mode: ColorMode = ColorMode.RGB
    rotation: Cv2Rotation = Cv2Rotation.NO_ROTATION
    warmup_s: int = 1

    def __post_init__(self) -> None:
        if not self.address.startswith(("http://", "https://")):
            raise ValueError(f"so101_virtual camera address {self.address!r}: not an http:// "
                             "address. Fix: give the line virtual_so101.py --camera NAME printed, "
                             "e.g. address: http://127.0.0.1:PORT/overhead.mjpg.")
        self.color_mode = ColorMode(self.color_mode)
        self.rotation = Cv2Rotation(self.rotation)

    # What lerobot's OpenCVCamera reads from its config (the camera class reuses it).
    @property
    def index_or_path(self) -> str:
        """The stream's address, as OpenCV opens it."""
        return self.address

    fourcc = None
    backend = Cv2Backends.ANY
