"""Offscreen rendering of the SO-101 scene: frames, MP4 videos and the course's target cubes.

:class:`so101_kinematics.sim.video.VideoRecorder` is a duck-typed "viewer" for
``so101_mujoco_utils.move_to_pose`` / ``hold_position``: it has ``sync()`` and
``is_running()``, ``offscreen = True`` (no real-time pacing) and
``sync_every_step = True`` (it sees every physics step and renders a frame each
time simulation time crosses the next frame time, so a 30 fps video shows the
simulation at exactly 1/30 s intervals, whatever the physics timestep).

Speed on a CPU-only machine (Mesa llvmpipe through ``MUJOCO_GL=egl``): the
upstream meshes (399k triangles drawn), MuJoCo's default 4096 shadow map, 4x
multisampling and the floor reflection render at about 2 frames/s at 640x480.
Measured here (CPU time per 640x480 frame, so it does not depend on what
else runs): shadows cost about 3x (an extra depth pass and shadow-tested
lighting), multisampling and the 4096 shadow map about 3x more, the upstream
meshes 2x-3x over render-only copies decimated at install time
(``so101_kinematics.sim.meshes.install_render_meshes``, 2 mm vertex clustering, 14x fewer
triangles; 1 mm clustering renders 25 % slower and looks the same), the
skybox and the floor texture 10-20 % each. Extra llvmpipe threads do not
help: the frame time goes into single-threaded vertex work. The ``fast``
quality (the default for videos) therefore draws the decimated meshes
without shadows, multisampling, reflection or skybox, keeping the floor's
1 cm grid; ``shadows`` adds the shadows back, ``high`` is MuJoCo's default
look with the upstream meshes.

Example::

    m = build_model(); d = mujoco.MjData(m)
    with VideoRecorder(m, d, "out/clip.mp4", overlays=target_cubes(start, final)) as video:
        move_to_pose(m, d, video, final, 2.0)
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import RenderError, RenderSettingError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.sim.meshes import ensure_render_meshes

__all__ = [
    "DEFAULT_CAMERA", "DEFAULT_FPS", "DEFAULT_SIZE", "FINAL_RGBA", "FRAME_EDGE_RANGE",
    "FrameRenderer", "MIN_FPS", "Overlay", "QUALITY", "RenderQuality", "START_RGBA",
    "VIDEO_CODEC", "VIDEO_PARAMS", "add_overlays", "check_camera", "check_fps",
    "check_frame_size", "max_fps",
    "target_cubes", "use_render_meshes",
]

DEFAULT_CAMERA = "pick_place"
DEFAULT_SIZE = (640, 480)  # [px] width, height
DEFAULT_FPS = 30.0  # [frames/s]
MIN_FPS = 1.0  # [frames/s]; the most is one frame per physics step (see max_fps)
# Each frame is drawn into MuJoCo's offscreen buffer of exactly the frame's
# size (FrameRenderer sets offwidth/offheight), colour and depth, 8 bytes a
# pixel before multisampling: 4096 x 4096 is 134 MB and minutes per frame on
# a CPU renderer; 10000 x 10000 would be 800 MB. 4096 px also stays within
# the renderbuffer size of the OpenGL drivers we target (llvmpipe 16384).
FRAME_EDGE_RANGE = (16, 4096)  # [px] width and height of a video frame or picture
CUBE_HALFWIDTH = CUBE_HALF_SIZE  # [m] the course's cubes (constants.py)
START_RGBA = (1.0, 0.0, 0.0, 0.2)  # translucent red: where the cube is picked
FINAL_RGBA = (0.0, 1.0, 0.0, 0.2)  # translucent green: where it is placed
VIDEO_CODEC = "libx264"
# x264's fastest preset: half the encoder CPU of "veryfast", larger files.
VIDEO_PARAMS = ("-preset", "ultrafast", "-crf", "26")

log = logging.getLogger(__name__)


def max_fps(m: mujoco.MjModel) -> float:
    """Highest video frame rate [frames/s] the simulation can sample: one frame per physics step."""
    return 1.0 / m.opt.timestep


def check_fps(fps, highest: float, name: str = "fps") -> float:
    """A frame rate [frames/s] in [``MIN_FPS``, ``highest``] as a float.

    Args:
        fps: the frame rate.
        highest: the most the simulation can sample (:func:`max_fps`).
        name: what the user calls it, for the message.

    Raises:
        RenderSettingError: naming the value, the range and why the maximum.
    """
    from so101_kinematics.inputs import check_number

    return check_number(fps, name, MIN_FPS, highest, "frames/s", error=RenderSettingError,
                        fix=f"give at most {highest:g} (the simulation steps every "
                            f"{1000.0 / highest:g} ms, so a higher rate would repeat states and "
                            "shorten the video).")


def check_frame_size(size, name: str = "size", even: bool = True) -> tuple[int, int]:
    """A frame size (width, height) [px], each edge a whole number in ``FRAME_EDGE_RANGE``.

    Args:
        size: (width, height).
        name: what the user calls it, for the message.
        even: both edges even (H.264 with yuv420p needs it).

    Raises:
        RenderSettingError: naming the size, the range and the fix.
    """
    low, high = FRAME_EDGE_RANGE
    allowed = f"whole numbers in [{low}, {high}] px{', both even' if even else ''}"
    try:
        width, height = size
        ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))
                 for v in (width, height))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise RenderSettingError(f"{name} must be (width, height), {allowed}; got {size!r}. "
                                 "Fix: e.g. 640x480.")
    width, height = int(width), int(height)
    if not (low <= width <= high and low <= height <= high):
        raise RenderSettingError(
            f"{name} {width}x{height}: each edge must be in [{low}, {high}] px (MuJoCo renders "
            f"into an offscreen buffer of the frame's size; {high} px is the largest allowed). "
            "Fix: e.g. 1920x1080 or smaller.")
    if even and (width % 2 or height % 2):
        raise RenderSettingError(f"{name} {width}x{height}: width and height must be even "
                                 "(H.264, yuv420p). Fix: e.g. "
                                 f"{width + width % 2}x{height + height % 2}.")
    return width, height


@dataclass(frozen=True)
class Overlay:
    """A translucent box drawn into a scene (not part of the physics).

    Attributes:
        position: centre in the world [m].
        rotation: 3x3 orientation in the world.
        halfwidth: half of the edge [m].
        rgba: colour and opacity, each in [0, 1].
    """

    position: np.ndarray
    rotation: np.ndarray
    halfwidth: float = CUBE_HALFWIDTH
    rgba: tuple[float, float, float, float] = START_RGBA


def target_cubes(start: Mapping[str, float], final: Mapping[str, float],
                 halfwidth: float = CUBE_HALFWIDTH) -> tuple[Overlay, Overlay]:
    """The course's two target cubes: red at the FK start position, green at the FK final one.

    Args:
        start: configuration where the cube is picked ([deg]; the gripper is ignored).
        final: configuration where it is placed.
        halfwidth: half the cube's edge [m].

    Returns:
        (red, green) overlays posed as the object frame of each configuration.
    """
    cubes = []
    for cfg, rgba in ((start, START_RGBA), (final, FINAL_RGBA)):
        position, rotation = forward_kinematics(cfg)
        cubes.append(Overlay(position, rotation, halfwidth, rgba))
    return cubes[0], cubes[1]


def add_overlays(scene: mujoco.MjvScene, overlays: Iterable[Overlay]) -> None:
    """Append overlay boxes after the geoms already in ``scene``.

    Works for a renderer's scene after ``update_scene`` and for a passive
    viewer's ``user_scn`` (reset its ``ngeom`` to 0 first to replace them).

    Raises:
        RenderError: the scene has no room left (``maxgeom``).
    """
    for overlay in overlays:
        if scene.ngeom >= scene.maxgeom:
            raise RenderError(f"The scene is full ({scene.maxgeom} geoms); cannot add overlays.")
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=np.full(3, overlay.halfwidth),
            pos=np.asarray(overlay.position, dtype=float),
            mat=np.asarray(overlay.rotation, dtype=float).flatten(),
            rgba=np.asarray(overlay.rgba, dtype=np.float32),
        )
        scene.ngeom += 1


@dataclass(frozen=True)
class RenderQuality:
    """Rendering settings that trade looks for speed.

    Attributes:
        shadow_size: shadow map edge [px] (MuJoCo's default 4096).
        multisamples: multisampling (anti-aliasing) samples (default 4).
        shadows: draw shadows.
        reflection: draw reflections of reflective materials.
        skybox: draw the skybox (else a plain background).
        light_meshes: use the decimated render-only meshes.
    """

    shadow_size: int = 1024
    multisamples: int = 0
    shadows: bool = False
    reflection: bool = False
    skybox: bool = False
    light_meshes: bool = True


QUALITY = {
    "fast": RenderQuality(),
    "shadows": RenderQuality(shadows=True, skybox=True),
    "high": RenderQuality(shadow_size=4096, multisamples=4, shadows=True, reflection=True,
                          skybox=True, light_meshes=False),
}
"""Named presets; ``fast`` is the default for videos."""


def use_render_meshes(spec: mujoco.MjSpec) -> mujoco.MjSpec:
    """Point every mesh of an SO-101 spec at its render-only decimated copy.

    The visual geoms change shape by less than the 2 mm clustering cell;
    masses and contacts do not change (visual geoms have no density and no
    contact), so the physics is the same.

    Args:
        spec: an uncompiled scene (e.g. ``mujoco.MjSpec.from_file(scene.xml)``).

    Returns:
        The same spec, modified.
    """
    directory = ensure_render_meshes()
    for mesh in spec.meshes:
        mesh.file = str(directory / Path(mesh.file).name)
    return spec


def check_camera(m: mujoco.MjModel, camera) -> str:
    """The camera's name if the model has it.

    Raises:
        RenderSettingError: naming the cameras the model has.
    """
    names = [m.camera(i).name for i in range(m.ncam)]
    if not isinstance(camera, str) or camera not in names:
        raise RenderSettingError(f"Unknown camera {camera!r}; the model has: {', '.join(names)}. "
                                 "Fix: choose one of those.")
    return camera


def _scene_option() -> mujoco.MjvOption:
    """Visual groups as the viewer shows them: world, arm meshes; no collision boxes or sites."""
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
    option.sitegroup[:] = [0] * len(option.sitegroup)
    return option


class FrameRenderer:
    """Renders the state of a simulation from a named camera, with overlays.

    Args:
        m: the physics model.
        d: its data (read only).
        size: (width, height) [px].
        camera: camera name in the model.
        overlays: boxes drawn into every frame.
        quality: rendering settings.
        render_model: a model with the same joints to draw with (e.g. one
            built with :func:`use_render_meshes`); default ``m``.

    Raises:
        RenderSettingError: unknown camera, a size outside ``FRAME_EDGE_RANGE``.
        RenderError: a render model that does not match.
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, size: Sequence[int] = DEFAULT_SIZE,
                 camera: str = DEFAULT_CAMERA, overlays: Iterable[Overlay] = (),
                 quality: RenderQuality = QUALITY["fast"],
                 render_model: mujoco.MjModel | None = None):
        width, height = check_frame_size(size, "Frame size", even=False)
        check_camera(m, camera)
        self.m, self.d = m, d
        self.m_render = render_model if render_model is not None else m
        if self.m_render.nq != m.nq:
            raise RenderError(f"The render model has {self.m_render.nq} position coordinates, "
                              f"the simulated one {m.nq}: build both from the same scene.")
        self.d_render = d if self.m_render is m else mujoco.MjData(self.m_render)
        self.camera, self.quality, self.overlays = camera, quality, tuple(overlays)
        vis = self.m_render.vis
        # The offscreen buffer exactly the frame's size: the scene's 1280x960
        # buffer would be cleared whole for every 640x480 frame (15 % of the
        # frame's CPU time on llvmpipe).
        vis.global_.offwidth, vis.global_.offheight = width, height
        vis.quality.shadowsize = quality.shadow_size
        vis.quality.offsamples = quality.multisamples
        self._option = _scene_option()
        self._renderer = mujoco.Renderer(self.m_render, height, width)

    def render(self) -> np.ndarray:
        """Render the current state of ``d``.

        Returns:
            (height, width, 3) uint8 RGB image (a new array).
        """
        if self.d_render is not self.d:
            self.d_render.qpos[:] = self.d.qpos
            mujoco.mj_kinematics(self.m_render, self.d_render)
            mujoco.mj_camlight(self.m_render, self.d_render)
        self._renderer.update_scene(self.d_render, self.camera, scene_option=self._option)
        flags = self._renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.quality.shadows
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = self.quality.reflection
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = self.quality.skybox
        add_overlays(self._renderer.scene, self.overlays)
        return self._renderer.render()

    def close(self) -> None:
        """Free the OpenGL context."""
        self._renderer.close()
