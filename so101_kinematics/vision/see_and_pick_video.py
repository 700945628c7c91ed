"""The see-and-pick's video: the run from the front, the fixed camera's live view inset.

The inset is the ``overhead`` camera as the program sees it (rendered live, a third of the
frame's width, top-left), with the tags it found at the start outlined (green the cube's,
orange the target's): the cube leaves its outline when it is picked and comes to rest on
the target's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.planning.motion import Plan
from so101_kinematics.sim.pick_place import total_duration
from so101_kinematics.sim.render import DEFAULT_CAMERA, DEFAULT_FPS, DEFAULT_SIZE, FrameRenderer
from so101_kinematics.sim.video import VideoRecorder
from so101_kinematics.vision.sim_camera import CAMERA_SIZE

__all__ = ["INSET_FRACTION", "inset_recorder"]

INSET_FRACTION = 1 / 3
"""The inset's width as a fraction of the frame's."""
OUTLINE_RGB = {"cube": (40, 220, 40), "target": (255, 150, 0)}
BORDER_PX = 2


class _Inset:
    """Composes a frame: the camera's live view, the tags found outlined, in the corner."""

    def __init__(self, m, d, camera: str, frame_size, corners: dict):
        width = int(frame_size[0] * INSET_FRACTION) // 2 * 2
        height = int(round(width * CAMERA_SIZE[1] / CAMERA_SIZE[0]))
        self.scale = width / CAMERA_SIZE[0]
        self.renderer = FrameRenderer(m, d, (width, height), camera=camera)
        self.corners = corners
        self.label = f"{camera} camera (tags found at the start outlined)"

    def __call__(self, frame: np.ndarray) -> np.ndarray:
        cv2 = require_opencv()
        view = np.ascontiguousarray(self.renderer.render())
        for name, corners in self.corners.items():
            points = np.round(np.asarray(corners) * self.scale).astype(np.int32)
            cv2.polylines(view, [points.reshape(-1, 1, 2)], True, OUTLINE_RGB[name], 1,
                          cv2.LINE_AA)
        cv2.putText(view, self.label, (4, view.shape[0] - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                    (0, 0, 0), 1, cv2.LINE_AA)
        frame = frame.copy()
        height, width = view.shape[:2]
        frame[:height + 2 * BORDER_PX, :width + 2 * BORDER_PX] = 255
        frame[BORDER_PX:BORDER_PX + height, BORDER_PX:BORDER_PX + width] = view
        return frame

    def close(self) -> None:
        self.renderer.close()


class _InsetRecorder(VideoRecorder):
    """A :class:`VideoRecorder` that also frees its inset's renderer when it closes."""

    def __init__(self, *args, inset: _Inset, **kwargs):
        self._inset = inset
        super().__init__(*args, compose=inset, **kwargs)

    def close(self, complete: bool = True) -> None:
        try:
            super().close(complete)
        finally:
            self._inset.close()


def inset_recorder(m, d, path: str | Path, plan: Plan, sighting, progress: bool,
                   camera: str = "overhead", size=DEFAULT_SIZE,
                   fps: float = DEFAULT_FPS) -> VideoRecorder:
    """A recorder of the run from the front camera with ``camera``'s view inset.

    Args:
        m: the tagged scene.
        d: its data (the run's).
        path: the MP4 file (written beside, renamed over it when complete).
        plan: the plan about to run (for the progress bar's length).
        sighting: ``see_and_pick.Sighting``: its tags' corners are outlined.
        progress: a progress bar.
        camera: the inset's camera.
        size: the video's (width, height) [px].
        fps: frames per second of simulated time.
    """
    inset = _Inset(m, d, camera, size, sighting.corners)
    try:
        return _InsetRecorder(m, d, path, fps=fps, size=size, camera=DEFAULT_CAMERA,
                              total_time=total_duration(plan), progress=progress, inset=inset)
    except BaseException:
        inset.close()
        raise
