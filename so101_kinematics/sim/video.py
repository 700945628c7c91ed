"""MP4 video of a simulated run: frames at the video's own times, written beside and renamed."""

from __future__ import annotations

import logging
import os
import queue
import threading
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.errors import RenderError, RenderSettingError
from so101_kinematics.sim.render import (
    DEFAULT_CAMERA,
    DEFAULT_FPS,
    DEFAULT_SIZE,
    QUALITY,
    VIDEO_CODEC,
    VIDEO_PARAMS,
    FrameRenderer,
    Overlay,
    RenderQuality,
    check_fps,
    check_frame_size,
    max_fps,
)

__all__ = ["VideoRecorder"]

log = logging.getLogger(__name__)


class VideoRecorder:
    """Records a simulation to an MP4 file; pass it as the ``viewer`` of move_to_pose.

    A frame is written at the start and then each time simulation time
    crosses the next multiple of ``1 / fps`` [s], so the video plays in real
    time: ``frames_written == 1 + floor(simulated seconds * fps)``. Frames go
    to the encoder (an ffmpeg process) from a background thread, so rendering
    the next frame overlaps with handing over the last one.

    The video is written to a temporary file beside ``path`` and renamed over
    it by ``close()`` (or the end of a ``with`` block without an exception):
    an interrupted or failed recording never replaces an existing video.
    ``close(complete=False)`` discards the recording.

    Args:
        m: the physics model.
        d: its data.
        path: output ``.mp4`` file (its folder is created).
        fps: frames per second of simulation time [1/s], in
            [``MIN_FPS``, :func:`max_fps`]: at most one frame per physics step.
        size: (width, height) [px], both even (H.264 with yuv420p), each in
            ``FRAME_EDGE_RANGE``.
        camera: camera name.
        overlays: boxes drawn into every frame (e.g. :func:`target_cubes`).
        quality: rendering settings.
        render_model: model to draw with (see :class:`FrameRenderer`).
        total_time: expected simulated duration [s], for the progress bar.
        progress: show a progress bar (tqdm, on stderr).
        compose: makes each rendered frame into the one written (e.g. a camera's view
            inset in a corner); it returns a new H x W x 3 uint8 image of the same size.

    Raises:
        RenderSettingError: bad size, fps, path or camera (nothing is written).
    """

    offscreen = True
    sync_every_step = True

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, path: str | Path, *,
                 fps: float = DEFAULT_FPS, size: Sequence[int] = DEFAULT_SIZE,
                 camera: str = DEFAULT_CAMERA, overlays: Iterable[Overlay] = (),
                 quality: RenderQuality = QUALITY["fast"],
                 render_model: mujoco.MjModel | None = None,
                 total_time: float | None = None, progress: bool = True,
                 compose: Callable[[np.ndarray], np.ndarray] | None = None):
        import imageio.v2 as imageio
        from tqdm import tqdm

        from so101_kinematics.errors import OutputPathError
        from so101_kinematics.markers import mp4_params
        from so101_kinematics.outputs import check_output_path, temporary_beside

        path = Path(path)
        if path.suffix.lower() != ".mp4":
            raise RenderSettingError(f"Video path '{path}' must end in .mp4. Fix: e.g. "
                                     f"{path.with_suffix('.mp4')}.")
        fps = check_fps(fps, max_fps(m))
        width, height = check_frame_size(size, "Video size")
        try:
            path = check_output_path(path, "video", overwrite=True)  # the caller decided
        except OutputPathError as error:
            raise RenderSettingError(str(error)) from None
        self.d, self.fps, self.path = d, fps, path
        self.frames_written = 0
        self._compose = compose
        self._half_step = 0.5 * m.opt.timestep
        self._t0 = d.time
        self._frames = FrameRenderer(m, d, (width, height), camera, overlays, quality, render_model)
        self._temporary = temporary_beside(path)
        self._closed = False
        try:
            self._writer = imageio.get_writer(
                str(self._temporary), format="FFMPEG", fps=self.fps, codec=VIDEO_CODEC,
                pixelformat="yuv420p", quality=None, macro_block_size=1,
                ffmpeg_params=[*VIDEO_PARAMS, *mp4_params(f"video of {path.name}")],
                ffmpeg_log_level="error")
        except BaseException:
            self._temporary.unlink(missing_ok=True)
            self._frames.close()
            raise
        self._queue: queue.Queue = queue.Queue(maxsize=8)
        self._write_error: BaseException | None = None
        self._thread = threading.Thread(target=self._write_loop, name="video-writer", daemon=True)
        self._thread.start()
        expected = None if total_time is None else 1 + int(total_time * self.fps + 1e-9)
        self._bar = tqdm(total=expected, unit="frame", desc=f"Recording {path.name}",
                         disable=not progress, leave=False)
        try:
            self.capture()
        except BaseException:
            self.close(complete=False)
            raise

    def set_overlays(self, overlays: Iterable[Overlay]) -> None:
        """Draw these boxes (instead of the ones before) into the frames from now on."""
        self._frames.overlays = tuple(overlays)

    def is_running(self) -> bool:
        """Always true: an offscreen recorder has no window to close."""
        return True

    def sync(self) -> None:
        """Render and write a frame if simulation time reached the next frame time."""
        if self.d.time + self._half_step >= self._t0 + self.frames_written / self.fps:
            self.capture()

    def capture(self) -> None:
        """Render the current state and append it to the video."""
        if self._write_error is not None:
            raise RenderError(f"Writing '{self.path}' failed: {self._write_error}")
        frame = self._frames.render()
        self._queue.put(frame if self._compose is None else self._compose(frame))
        self.frames_written += 1
        self._bar.update(1)

    def _write_loop(self) -> None:
        """Background thread: hand frames to the encoder until the ``None`` sentinel."""
        while (frame := self._queue.get()) is not None:
            if self._write_error is None:
                try:
                    self._writer.append_data(frame)
                except Exception as error:  # reported by capture() / close()
                    self._write_error = error

    def close(self, complete: bool = True) -> None:
        """Finish the MP4 file, rename it over ``path`` and free the renderer.

        Args:
            complete: False discards the recording (after an error or Ctrl-C):
                the temporary file is removed and an existing ``path`` is untouched.

        Raises:
            RenderError: the encoder failed (the temporary file is removed).
        """
        if self._closed:
            return
        self._closed = True
        try:
            self._bar.close()
            self._queue.put(None)
            self._thread.join()
            try:
                self._writer.close()
            except Exception as error:  # ffmpeg gone (e.g. killed by Ctrl-C with us)
                if self._write_error is None:
                    self._write_error = error
            self._frames.close()
            if complete and self._write_error is not None:
                raise RenderError(f"Writing '{self.path}' failed: {self._write_error}. "
                                  f"Nothing was written to '{self.path}'.")
            if complete:
                os.replace(self._temporary, self.path)
                log.info("Wrote %d frames (%.2f s at %g fps) to %s", self.frames_written,
                         self.frames_written / self.fps, self.fps, self.path)
        finally:
            from so101_kinematics.outputs import forget_temporary

            self._temporary.unlink(missing_ok=True)
            forget_temporary(self._temporary)

    def __enter__(self) -> VideoRecorder:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self.close(complete=exc_type is None)

