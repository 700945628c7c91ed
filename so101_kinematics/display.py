"""The display decision and MuJoCo's passive viewer, in one place for every script.

Importing this module before ``mujoco`` chooses the OpenGL backend: without
an X11 or Wayland display, MuJoCo's offscreen renderer needs Mesa's EGL
(``MUJOCO_GL=egl``), and MuJoCo reads that variable once, when it is imported.
So a script starts with::

    import so101_kinematics.display as so101_display  # first: EGL when there is no display

    # isort: split
    import mujoco

The passive viewer (``mujoco.viewer.launch_passive``) draws from its own
thread. MuJoCo registers ``glfw.terminate`` to run at interpreter exit; if
the program (not the user) ends while the window is still open, that call
races the render thread destroying its window: a segmentation fault or a
hang at exit (google-deepmind/mujoco issue 790; here 6 crashes and 1 hang in
10 runs of ``test_fk_mujoco.py`` on a virtual display). :func:`open_viewer`
closes the viewer and waits for its render thread before returning, and
:func:`guard_viewer_exit` makes the interpreter do the same at exit for a
viewer opened by someone else (the course's own scripts).
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import os
import threading
from collections.abc import Callable, Iterator, MutableMapping

__all__ = [
    "choose_gl_backend", "close_viewer", "frame_camera", "guard_viewer_exit", "has_display",
    "launch_viewer", "open_viewer",
]

log = logging.getLogger(__name__)

VIEWER_CAMERA = "pick_place"  # model/scene.xml's camera: the arm and both cube positions
RENDER_THREAD_SUFFIX = "(_launch_internal)"  # mujoco.viewer's render thread, named by threading
CLOSE_TIMEOUT = 10.0  # [s] to wait for a render thread to finish after closing its viewer


def has_display(environ: MutableMapping[str, str] = os.environ) -> bool:
    """Whether an interactive viewer can open (an X11 or Wayland display is set)."""
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def choose_gl_backend(environ: MutableMapping[str, str] = os.environ) -> str | None:
    """Use Mesa's EGL for offscreen rendering when there is no display.

    Keeps a ``MUJOCO_GL`` the user set. Must run before ``mujoco`` is imported
    (importing this module does it).

    Returns:
        The ``MUJOCO_GL`` value now in effect, ``None`` for MuJoCo's default (GLFW).
    """
    if not has_display(environ):
        environ.setdefault("MUJOCO_GL", "egl")
    return environ.get("MUJOCO_GL")


choose_gl_backend()


# --- the passive viewer's exit ---------------------------------------------------------------

_guarded: list[tuple[object, list[threading.Thread]]] = []  # (viewer, its render threads)
_guard_lock = threading.Lock()


def _render_threads() -> list[threading.Thread]:
    """The live render threads of passive viewers (named after mujoco.viewer's target)."""
    return [t for t in threading.enumerate() if t.name.endswith(RENDER_THREAD_SUFFIX)]


def guard_viewer_exit(viewer, render_threads: list[threading.Thread] | None = None) -> None:
    """Make the interpreter close ``viewer`` and wait for its render thread before exiting.

    MuJoCo registers ``glfw.terminate`` with :mod:`atexit` when a viewer
    opens; :mod:`atexit` runs the last registered handler first, so this
    (re-)registers :func:`close_viewers` after it. Calling it again for the
    same viewer does nothing; a later viewer registers the handler again,
    after its own ``glfw.terminate``.

    Args:
        viewer: a handle from ``mujoco.viewer.launch_passive``.
        render_threads: its render thread(s), if known; otherwise the
            running render threads not yet claimed by another viewer.
    """
    with _guard_lock:
        if any(seen is viewer for seen, _ in _guarded):
            return
        if render_threads is None:
            claimed = {id(t) for _, threads in _guarded for t in threads}
            render_threads = [t for t in _render_threads() if id(t) not in claimed]
        _guarded.append((viewer, list(render_threads)))
        atexit.unregister(close_viewers)
        atexit.register(close_viewers)


def close_viewer(viewer, render_threads: list[threading.Thread] | None = None,
                 timeout: float = CLOSE_TIMEOUT) -> bool:
    """Close a passive viewer and wait until its render thread has finished.

    Args:
        viewer: a handle from ``mujoco.viewer.launch_passive``.
        render_threads: its render thread(s); ``None`` for those
            :func:`guard_viewer_exit` recorded.
        timeout: the longest wait [s].

    Returns:
        Whether the render thread finished in time.
    """
    with _guard_lock:
        for i, (seen, threads) in enumerate(_guarded):
            if seen is viewer:
                render_threads = threads if render_threads is None else render_threads
                del _guarded[i]
                break
    viewer.close()
    for thread in render_threads or ():
        if thread is not threading.current_thread():
            thread.join(timeout)
        if thread.is_alive():
            log.warning("The viewer's render thread did not finish within %.0f s.", timeout)
            return False
    return True


def close_viewers() -> None:
    """Close every guarded viewer and wait for its render thread (the :mod:`atexit` handler)."""
    while _guarded:
        close_viewer(_guarded[-1][0])


# --- the camera --------------------------------------------------------------------------------


def frame_camera(cam, m, camera: str = VIEWER_CAMERA) -> None:
    """Point a free camera along a named camera of the model, framing what it frames.

    The free camera (which the user can still turn and zoom) looks from the
    named camera's position along its axis; it turns about the point of that
    axis nearest to the model's centre (``m.stat.center``). The free camera's
    field of view is the model's ``vis.global_.fovy``: where it differs from
    the named camera's, the distance is scaled so that the scene at that
    point spans the same height of the image.

    Args:
        cam: a ``mujoco.MjvCamera`` (e.g. a passive viewer's ``cam``).
        m: the model.
        camera: the name of one of its cameras.
    """
    import mujoco
    import numpy as np

    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_camlight(m, d)
    position = d.camera(camera).xpos
    forward = -d.camera(camera).xmat.reshape(3, 3)[:, 2]  # a camera looks along its -z
    depth = float(np.dot(m.stat.center - position, forward))  # [m] to the turning point
    scale = (math.tan(math.radians(m.camera(camera).fovy[0]) / 2.0)
             / math.tan(math.radians(m.vis.global_.fovy) / 2.0))
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = position + depth * forward
    cam.distance = depth * scale
    cam.azimuth = math.degrees(math.atan2(forward[1], forward[0]))
    cam.elevation = math.degrees(math.asin(max(-1.0, min(1.0, float(forward[2])))))


# --- the viewer's session ----------------------------------------------------------------------


def launch_viewer(m, d, *, camera: str | None = VIEWER_CAMERA, show_ui: bool = False,
                  key_callback: Callable[[int], None] | None = None):
    """Open MuJoCo's passive viewer framed on the work; end it with :func:`close_viewer`.

    The interpreter's exit is guarded (:func:`guard_viewer_exit`) from the start.
    Prefer :func:`open_viewer`, which closes it at the end of a ``with`` block.

    Args:
        m: the model.
        d: the data the viewer shows.
        camera: a camera of the model to start from (see :func:`frame_camera`);
            ``None`` for MuJoCo's default free camera.
        show_ui: show MuJoCo's side panels from the start (they hide the arm
            in a small window); Tab and Shift+Tab toggle them in the window.
        key_callback: called with the GLFW key code of each key pressed.

    Returns:
        The viewer handle.
    """
    import mujoco.viewer

    before = {id(t) for t in _render_threads()}
    viewer = mujoco.viewer.launch_passive(m, d, key_callback=key_callback,
                                          show_left_ui=show_ui, show_right_ui=show_ui)
    guard_viewer_exit(viewer, [t for t in _render_threads() if id(t) not in before])
    if camera is not None:
        with viewer.lock():
            frame_camera(viewer.cam, m, camera)
    return viewer


@contextlib.contextmanager
def open_viewer(m, d, **options) -> Iterator[object]:
    """MuJoCo's passive viewer, closed and its render thread finished when the block ends.

    Args:
        m: the model.
        d: the data the viewer shows.
        **options: as for :func:`launch_viewer` (``camera``, ``show_ui``, ``key_callback``).

    Yields:
        The viewer handle.
    """
    viewer = launch_viewer(m, d, **options)
    try:
        yield viewer
    finally:
        close_viewer(viewer)
