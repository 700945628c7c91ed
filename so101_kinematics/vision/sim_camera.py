"""The simulator's cameras as ``interfaces.Camera``: a rendered image, optionally made webcam-like.

:class:`SimCamera` renders one of the model's cameras (``overhead``, ``wrist``, or any
other) headless through ``sim/render.py``'s :class:`FrameRenderer` (``MUJOCO_GL=egl`` when
there is no display: ``display.py``), and returns what a real camera would: an RGB image,
its camera matrix and (what only the simulator knows) its pose in the base frame.

:class:`ImageEffects` makes the image look like a webcam's, so the detector meets soft
edges and grain rather than perfect pixels: a Gaussian blur (defocus and motion), an
exposure gain, and Gaussian sensor noise, seeded so a test sees the same noise each run.
They use numpy only.

Example::

    m = build_model(cube=CubeStart(), render_meshes=True); d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    with SimCamera(m, d, "overhead", effects=WEBCAM) as camera:
        image = camera.read()          # 480 x 640 x 3 uint8 RGB
        K = camera.intrinsics()        # [px]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics.errors import VisionError
from so101_kinematics.sim.render import QUALITY, FrameRenderer, RenderQuality
from so101_kinematics.vision.camera_model import camera_intrinsics, get_camera_pose_base

__all__ = ["CAMERA_SIZE", "ImageEffects", "SimCamera", "WEBCAM", "apply_effects"]

CAMERA_SIZE = (640, 480)
"""(width, height) [px]: a USB webcam's VGA mode, the issue's 640x480."""


@dataclass(frozen=True)
class ImageEffects:
    """What turns a rendered image into a webcam-like one.

    Attributes:
        blur_px: standard deviation of the Gaussian blur [px] (0: none).
        noise_levels: standard deviation of the sensor noise [8-bit grey levels] (0: none).
        exposure: gain on the brightness (1: as rendered; 0.7 darker, 1.3 brighter).
        seed: the noise's random seed (the same images each run).
    """

    blur_px: float = 0.0
    noise_levels: float = 0.0
    exposure: float = 1.0
    seed: int = 0

    def __post_init__(self):
        for name, low in (("blur_px", 0.0), ("noise_levels", 0.0), ("exposure", 1e-3)):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= low):
                raise VisionError(f"ImageEffects {name}={value!r} must be a number >= {low:g}. "
                                  f"Fix: e.g. {name}={getattr(WEBCAM, name, 1.0)!r}.")


WEBCAM = ImageEffects(blur_px=0.7, noise_levels=3.0, exposure=1.0, seed=0)
"""A plain USB webcam at VGA in a lit room: slight softness, a few grey levels of noise."""


def _gaussian_kernel(sigma: float) -> np.ndarray:
    radius = max(1, int(math.ceil(3.0 * sigma)))
    x = np.arange(-radius, radius + 1, dtype=float)
    kernel = np.exp(-0.5 * (x / sigma) ** 2)
    return kernel / kernel.sum()


def _blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur of an H x W x 3 float32 image, edges repeated."""
    kernel = _gaussian_kernel(sigma).astype(np.float32)
    radius = len(kernel) // 2
    height, width = image.shape[:2]
    padded = np.pad(image, ((radius, radius), (0, 0), (0, 0)), mode="edge")
    image = sum(weight * padded[i:i + height] for i, weight in enumerate(kernel))
    padded = np.pad(image, ((0, 0), (radius, radius), (0, 0)), mode="edge")
    return sum(weight * padded[:, i:i + width] for i, weight in enumerate(kernel))


def apply_effects(image: np.ndarray, effects: ImageEffects,
                  rng: np.random.Generator) -> np.ndarray:
    """The image as a webcam would give it: blurred, exposed, with noise.

    Args:
        image: H x W x 3 uint8 RGB.
        effects: what to apply.
        rng: the noise's generator (advanced by one image's noise).

    Returns:
        A new H x W x 3 uint8 RGB image.
    """
    out = image.astype(np.float32)
    if effects.blur_px > 0.0:
        out = _blur(out, effects.blur_px)
    out *= np.float32(effects.exposure)
    if effects.noise_levels > 0.0:
        noise = rng.standard_normal(out.shape, dtype=np.float32)
        noise *= np.float32(effects.noise_levels)
        out += noise
    np.rint(out, out=out)
    return np.clip(out, 0, 255, out=out).astype(np.uint8)


class SimCamera:
    """One of the model's cameras, read as a real camera is (``interfaces.Camera``).

    Args:
        m: the simulated model (a camera ``camera`` in it).
        d: its data, read at each :meth:`read` (call ``mj_forward`` or step it first).
        camera: the camera's name in the model (``"overhead"``, ``"wrist"``).
        size: (width, height) [px].
        effects: webcam-like effects (None: the image as rendered).
        quality: rendering settings (``sim/render.py``'s presets; ``fast`` by default).
        render_model: a model to draw with (e.g. one with the decimated meshes).

    Raises:
        RenderSettingError: an unknown camera or a size out of range.
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, camera: str,
                 size: Sequence[int] = CAMERA_SIZE, effects: ImageEffects | None = None,
                 quality: RenderQuality = QUALITY["fast"],
                 render_model: mujoco.MjModel | None = None):
        self._renderer = FrameRenderer(m, d, size, camera=camera, quality=quality,
                                       render_model=render_model)
        self.m, self.d, self.name = m, d, camera
        self.width, self.height = int(size[0]), int(size[1])
        self.effects = effects
        self._rng = np.random.default_rng(effects.seed if effects else 0)
        self._K = camera_intrinsics(m, camera, self.width, self.height)

    def read(self) -> np.ndarray:
        """The image now: ``height`` x ``width`` x 3 uint8 RGB."""
        image = self._renderer.render()
        return image if self.effects is None else apply_effects(image, self.effects, self._rng)

    def intrinsics(self) -> np.ndarray:
        """The camera matrix [px] (exact: from the model's fovy and the size)."""
        return self._K.copy()

    def pose(self) -> np.ndarray:
        """``g_bc``: the camera (OpenCV axes) in the base frame [m], the simulator's truth."""
        return get_camera_pose_base(self.m, self.d, self.name)

    def close(self) -> None:
        """Free the renderer's OpenGL context."""
        self._renderer.close()

    def __enter__(self) -> SimCamera:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
