"""A real USB camera (or a recorded video) as a ``interfaces.Camera``, through lerobot.

``Webcam`` opens lerobot's ``OpenCVCamera`` (lerobot 0.4.4 and 0.6.1 both have a
``fourcc`` setting: a device is asked for MJPG; a video file keeps its own codec); a virtual
arm's served camera (``http://...``) through its subclass ``so101_virtual``
(``lerobot_camera_so101_virtual``), whose size is checked, not set. The
colour order is handled once, by lerobot (``color_mode=RGB``): :meth:`Webcam.read`
returns lerobot's image as it is. lerobot is imported only when a Webcam is made.

A video file ends: lerobot's read thread then fails 11 times, logs each, and raises, and
Python prints that thread's traceback. On a file, a failed read is the end: the thread
stops as on a disconnect (lerobot's ``DeviceNotConnectedError``, which its loop treats as
the end), and :meth:`Webcam.read` says "a stale frame ... the video at its end?" in one line.

The calibration is the report that ``calibrate_camera.py --photos DIR --json PATH`` writes
(:func:`so101_kinematics.vision.calibration_photos.calibrate_from_photos`): its
``intrinsics`` hold ``K`` (the camera matrix [px]), ``distortion`` (OpenCV's coefficients)
and ``image_size`` (width, height [px]) that the pictures had.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from so101_kinematics.errors import VisionError

__all__ = ["Webcam", "load_calibration", "load_camera_in_base",
           "load_camera_in_gripper", "open_camera"]

LEROBOT_FIX = "install the hardware extra (pip install -e '.[hw]')"


def load_calibration(path: str | Path, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """``(K, dist)`` from calibrate_camera.py's report, made at ``width`` x ``height``.

    Raises:
        VisionError: a missing or malformed file, or one for another camera size.
    """
    try:
        intrinsics = json.loads(Path(path).read_text())["intrinsics"]
        K = np.asarray(intrinsics["K"], dtype=float).reshape(3, 3)
        dist = np.asarray(intrinsics["distortion"], dtype=float).ravel()
        size = tuple(int(v) for v in intrinsics["image_size"])
    except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
        raise VisionError(f"calibration {path}: cannot read it ({exc!s}); it needs the "
                          f"intrinsics (K, distortion, image_size) that calibrate_camera.py "
                          f"--photos DIR --json PATH writes") from None
    if size != (width, height):
        raise VisionError(f"calibration {path}: a calibration file for another camera "
                          f"({size[0]}x{size[1]}, this camera gives {width}x{height}); "
                          f"calibrate this camera at this size")
    return K, dist


def _load_mount_pose(path: str | Path, mount: str, key: str, where: str) -> np.ndarray:
    """The 4x4 pose ``hand_eye.<mount>.<key>`` [m] of calibrate_camera.py's report."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise VisionError(f"camera calibration {path}: cannot read it ({exc!s}); give the "
                          f"report calibrate_camera.py --photos DIR --json PATH wrote") from None
    try:
        g = np.asarray(data["hand_eye"][mount][key], dtype=float)
    except (KeyError, TypeError, ValueError):
        g = None
    if g is None or g.shape != (4, 4) or not np.all(np.isfinite(g)):
        raise VisionError(f"camera calibration {path}: no {where} in it; calibrate the "
                          f"camera with calibrate_camera.py --photos DIR --mount {mount} --json "
                          f"PATH (poses.csv beside the pictures)")
    return g


def load_camera_in_base(path: str | Path) -> np.ndarray:
    """The fixed camera's pose in the base frame ``g_bc`` (4x4 [m]) from a calibration report.

    The report is calibrate_camera.py's of the eye-to-hand calibration (``--mount fixed``,
    with poses.csv).

    Raises:
        VisionError: a missing or malformed file, or one without the fixed camera's pose.
    """
    return _load_mount_pose(path, "fixed", "camera_in_base",
                            "fixed camera's pose in the base frame")


def load_camera_in_gripper(path: str | Path) -> np.ndarray:
    """The wrist camera's pose in the gripper frame (frame 5) ``g_gc`` (4x4 [m]).

    The report is calibrate_camera.py's of the hand-eye calibration (``--mount wrist``,
    with poses.csv).

    Raises:
        VisionError: a missing or malformed file, or one without the wrist camera's pose.
    """
    return _load_mount_pose(path, "wrist", "camera_in_gripper",
                            "wrist camera's pose in the gripper frame")


def _is_stream(source) -> bool:
    return isinstance(source, str) and source.startswith(("http://", "https://"))


def open_camera(address: str, width: int = 640, height: int = 480,
                calibration: str | Path | None = None, max_age: float = 0.5) -> Webcam:
    """The camera at ``address`` opened by lerobot's camera class, as a :class:`Webcam`.

    ``address``: an index, ``/dev/videoN``, a virtual arm's ``http://`` stream, a video file.
    """
    source = int(address) if address.isdigit() else address
    return Webcam(source, width, height, calibration=calibration, max_age=max_age)


def _video_file_camera(camera_class):
    """The camera class (lerobot's), made to stop its read thread quietly at a video's end."""
    from lerobot.utils.errors import DeviceNotConnectedError

    class VideoFileCamera(camera_class):
        def _read_from_hardware(self):
            try:
                return super()._read_from_hardware()
            except RuntimeError as error:  # lerobot's "read failed": no frame left
                raise DeviceNotConnectedError(f"{self}: the video's end") from error

    return VideoFileCamera


class Webcam:
    """A USB camera (index, ``/dev/videoN``) or a video file, read through lerobot.

    Args:
        source: a device index, a device path, a video file or a virtual arm's stream
            (``http://127.0.0.1:PORT/NAME.mjpg``).
        width, height: the size asked for [px]; a camera giving another size is refused.
        fps: frames per second asked of a device (a file keeps its own).
        calibration: a calibration JSON (None: no intrinsics).
        max_age: [s] :meth:`read` raises when no new frame arrives within this.

    Raises:
        VisionError: no camera there, a busy camera, a wrong resolution, a bad calibration.
    """

    def __init__(self, source: int | str | Path, width: int = 640, height: int = 480,
                 fps: int = 30, calibration: str | Path | None = None, max_age: float = 0.5):
        try:
            from lerobot.cameras.configs import ColorMode
            from lerobot.cameras.opencv.camera_opencv import OpenCVCamera
            from lerobot.cameras.opencv.configuration_opencv import OpenCVCameraConfig
        except ImportError:
            raise VisionError(f"Webcam needs lerobot: {LEROBOT_FIX}") from None
        self.name, self.width, self.height, self.max_age = str(source), width, height, max_age
        self._K, self.dist = (load_calibration(calibration, width, height)
                              if calibration is not None else (None, None))
        if _is_stream(source):
            from lerobot_camera_so101_virtual import SO101VirtualCamera, SO101VirtualCameraConfig

            self._camera = SO101VirtualCamera(SO101VirtualCameraConfig(
                address=source, width=width, height=height, fps=fps))
            self._connect(source, warmup=True)  # the stream's first frames (1 s)
            return
        is_file = isinstance(source, (str, Path)) and Path(source).is_file() \
            and not str(source).startswith("/dev/")
        where = source if isinstance(source, int) else Path(source)
        if not is_file and not isinstance(source, int) and not Path(source).exists():
            raise VisionError(f"camera {source}: no camera or video there; list them with "
                              f"lerobot-find-cameras opencv")
        config = OpenCVCameraConfig(index_or_path=where, color_mode=ColorMode.RGB,
                                    fps=None if is_file else fps,
                                    width=None if is_file else width,
                                    height=None if is_file else height,
                                    fourcc=None if is_file else "MJPG")
        self._camera = (_video_file_camera(OpenCVCamera) if is_file else OpenCVCamera)(config)
        self._connect(source)

    def _connect(self, source, warmup: bool = False) -> None:
        try:
            self._camera.connect(warmup=warmup)
        except ConnectionError:
            busy = " (is another program using it?)" if not isinstance(source, int) else ""
            raise VisionError(f"camera {source}: cannot open it{busy}; list the cameras with "
                              f"lerobot-find-cameras opencv") from None
        except RuntimeError as exc:
            raise VisionError(f"camera {source}: a wrong resolution or format "
                              f"({str(exc).splitlines()[0]}); ask for a size it gives "
                              f"(lerobot-find-cameras opencv lists them)") from None
        got = (int(self._camera.width), int(self._camera.height))
        if got != (self.width, self.height):
            self.close()
            raise VisionError(f"camera {source}: a wrong resolution: it gives {got[0]}x{got[1]}, "
                              f"{self.width}x{self.height} was asked; ask for {got[0]}x{got[1]}")

    def read(self) -> np.ndarray:
        """The newest frame, ``height`` x ``width`` x 3 uint8 RGB (lerobot's RGB, as is).

        The age is lerobot's capture timestamp (``latest_timestamp``, ``perf_counter``;
        0.4.4 and 0.6.1 alike): a frame older than ``max_age`` is never returned.

        Raises:
            VisionError: no frame younger than ``max_age`` within ``max_age`` (a stale frame).
        """
        return self.read_stamped()[0]

    def read_stamped(self, newer_than: float | None = None) -> tuple[np.ndarray, float]:
        """The newest frame (as :meth:`read`) and its capture time [s] (``perf_counter``).

        Args:
            newer_than: wait for a frame captured after this time [s] (the last one used).

        Raises:
            VisionError: no such frame younger than ``max_age`` within ``max_age``.
        """
        cam, start = self._camera, time.perf_counter()
        while True:
            with cam.frame_lock:
                frame, stamp = cam.latest_frame, cam.latest_timestamp
            now = time.perf_counter()
            if frame is not None and stamp is not None and now - stamp <= self.max_age and (
                    newer_than is None or stamp > newer_than):
                return np.ascontiguousarray(frame, dtype=np.uint8), float(stamp)
            if now - start > self.max_age:
                age = "none yet" if stamp is None else f"the newest is {now - stamp:.2f} s old"
                raise VisionError(f"camera {self.name}: a stale frame ({age}, max_age "
                                  f"{self.max_age} s); is it unplugged, or the video at its end?")
            time.sleep(0.002)

    def intrinsics(self) -> np.ndarray:
        """The calibrated camera matrix [px].

        Raises:
            VisionError: no calibration was given.
        """
        if self._K is None:
            raise VisionError(f"camera {self.name}: no calibration; pass calibration=PATH "
                              f"(a JSON from calibrate_camera.py)")
        return self._K.copy()

    def close(self) -> None:
        """Release the camera (twice is fine)."""
        if self._camera.is_connected:
            self._camera.disconnect()

    def __enter__(self) -> Webcam:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
