"""The virtual arm's cameras: the emulator's live scene rendered and served as MJPEG over HTTP.

``virtual_so101.py --camera overhead`` (``VirtualSO101(cameras=["overhead"])``) serves each
named camera of the model at ``http://127.0.0.1:PORT/NAME.mjpg``, a
``multipart/x-mixed-replace`` stream of JPEG frames that a student's unchanged
``cv2.VideoCapture(address)`` opens (OpenCV's FFMPEG backend), as an IP webcam is opened;
``/NAME.jpg`` is one frame (a browser, ``curl``).

How it keeps the physics on time: the emulator's loop calls :meth:`CameraServer.tick` between
physics steps; while a client is connected and a frame is due (``fps``) it copies the
positions (``qpos``, a few dozen numbers: a consistent state, taken between two steps) and
wakes the render thread, which draws every watched camera from that copy into its own
``MjData`` (the decimated render meshes, ``sim/render.py``'s ``fast`` quality), encodes JPEG
and hands the frame to the clients' threads. When the render thread is still busy the
frame is skipped, never queued. Nobody watching: nothing is rendered.
"""

from __future__ import annotations

import importlib
import logging
import threading
import time
from collections.abc import Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import mujoco
import numpy as np

from so101_kinematics.errors import OpenCVMissing, RenderSettingError
from so101_kinematics.sim.render import FrameRenderer, check_camera
from so101_kinematics.sim.tag_textures import TARGET_TAG, tag_geom_name

__all__ = ["CAMERA_FPS", "CameraServer", "JPEG_QUALITY", "check_camera_fps", "require_cv2"]

logger = logging.getLogger("virtual_so101")

CAMERA_FPS = 30.0
"""[frames/s] served by default: a USB webcam's rate."""
JPEG_QUALITY = 90
"""cv2.imencode's JPEG quality (0-100): a webcam's MJPG mode looks about like this."""
BOUNDARY = "so101frame"
HIDDEN_DEPTH = 0.5  # [m] a hidden target tag this far under the table: out of every view
STALL_S = 5.0  # [s] a stream with no new frame for this long ends (the emulator stopped)


def check_camera_fps(fps) -> float:
    """The served frame rate [frames/s], 1..60.

    Raises:
        RenderSettingError: one line with the range and the fix.
    """
    if not (isinstance(fps, (int, float)) and 1.0 <= fps <= 60.0):
        raise RenderSettingError(f"camera fps {fps!r}: outside 1..60 frames/s (a webcam's "
                                 "rates). Fix: e.g. --camera-fps 30.")
    return float(fps)


def require_cv2():
    """The ``cv2`` module (it encodes the JPEG frames).

    Raises:
        OpenCVMissing: one line with the fix.
    """
    try:
        return importlib.import_module("cv2")
    except ImportError:
        raise OpenCVMissing("OpenCV (cv2) is not installed; the virtual arm's cameras need it to "
                            "encode their JPEG frames. Fix: pip install -e '.[hw]' (lerobot "
                            "brings OpenCV) or pip install opencv-python-headless.") from None


class CameraServer:
    """Renders the named cameras of a live simulation and serves them over HTTP (module doc).

    Args:
        m: the simulated model (the emulator's).
        render_model: the same scene with the render meshes (same ``nq``).
        cameras: camera names in ``m``.
        size: (width, height) [px].
        fps: frames per second served while a client watches.
        host: address to listen on (the machine itself by default).

    Raises:
        RenderSettingError: an unknown camera (the message lists the model's), a bad size.
        OpenCVMissing: no OpenCV.
    """

    def __init__(self, m: mujoco.MjModel, render_model: mujoco.MjModel, cameras: Sequence[str],
                 size: Sequence[int] = (640, 480), fps: float = CAMERA_FPS,
                 host: str = "127.0.0.1"):
        for name in cameras:
            check_camera(m, name)
        check_camera_fps(fps)
        self._cv2 = require_cv2()
        self.m, self.render_model = m, render_model
        self.names, self.size, self.period = list(dict.fromkeys(cameras)), tuple(size), 1.0 / fps
        self._snapshot = mujoco.MjData(m)  # the render thread's copy of the state
        self._qpos = None
        self._due = 0.0
        self._wake = threading.Event()
        self._busy = threading.Event()
        self._stop = threading.Event()
        self._cond = threading.Condition()
        self._watchers = dict.fromkeys(self.names, 0)
        self._frames: dict[str, tuple[int, bytes]] = {}  # name -> (number, JPEG)
        self.stats = {"frames": 0, "render_s": 0.0, "skipped": 0, "latency_s": 0.0}
        self._ready: list = []
        self._table_z: float | None = None  # the target tag's height (place_target)
        self._renderer_thread = threading.Thread(target=self._render_loop, name="cameras",
                                                 daemon=True)
        self._renderer_thread.start()
        while not self._ready:
            time.sleep(0.01)
        if isinstance(self._ready[0], BaseException):
            raise self._ready[0]
        self._httpd = ThreadingHTTPServer((host, 0), _handler(self))
        self._httpd.daemon_threads = True
        self.port = self._httpd.server_address[1]
        self.addresses = {name: f"http://{host}:{self.port}/{name}.mjpg" for name in self.names}
        threading.Thread(target=self._httpd.serve_forever, name="camera-http", daemon=True).start()

    # --- the emulator's side ---------------------------------------------------------------
    def tick(self, d: mujoco.MjData, now: float) -> None:
        """Between physics steps: copy the state for the next frame when one is due and wanted."""
        if now < self._due or not any(self._watchers.values()):
            return
        self._due = max(self._due + self.period, now)
        if self._busy.is_set():  # still drawing the last one: skip, never queue
            self.stats["skipped"] += 1
            return
        self._qpos = (d.qpos.copy(), now)
        self._busy.set()
        self._wake.set()

    def close(self) -> None:
        """Stop serving and rendering."""
        self._stop.set()
        self._wake.set()
        self._httpd.shutdown()
        self._httpd.server_close()
        with self._cond:
            self._cond.notify_all()
        self._renderer_thread.join(5)

    def place_target(self, x: float, y: float, yaw_deg: float = 0.0, hidden: bool = False) -> None:
        """Lay the target tag (drawn in the cameras only) at (x, y) [m], turned ``yaw_deg`` [deg].

        ``hidden``: under the table, out of every camera's view (a hand over the tag).

        Raises:
            ValueError: the arm was started without the target tag (one line, the fix).
        """
        name = tag_geom_name(TARGET_TAG)
        body = mujoco.mj_name2id(self.render_model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body < 0:
            raise ValueError("This virtual arm has no target tag. Fix: start it with --target X "
                             "Y (and --camera NAME: the tag is drawn in its cameras).")
        if self._table_z is None:
            self._table_z = float(self.render_model.body_pos[body, 2])
        half = np.radians(yaw_deg) / 2
        self.render_model.body_quat[body] = [np.cos(half), 0.0, 0.0, np.sin(half)]
        self.render_model.body_pos[body] = [x, y, self._table_z - (HIDDEN_DEPTH if hidden else 0)]

    def camera_stats(self) -> dict[str, float]:
        """Frames drawn and skipped, mean render + encode time and state-to-frame latency [ms]."""
        frames = max(1, self.stats["frames"])
        return {"frames": self.stats["frames"], "skipped": self.stats["skipped"],
                "render_ms": 1000.0 * self.stats["render_s"] / frames,
                "latency_ms": 1000.0 * self.stats["latency_s"] / frames}

    # --- the render thread -----------------------------------------------------------------
    def _render_loop(self) -> None:
        try:  # the OpenGL contexts belong to this thread
            renderers = {name: FrameRenderer(self.m, self._snapshot, self.size, camera=name,
                                             render_model=self.render_model)
                         for name in self.names}
        except Exception as exc:  # noqa: BLE001 - handed to the constructor
            self._ready.append(exc)
            return
        self._ready.append(True)
        cv2, params = self._cv2, [self._cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]
        try:
            while not self._stop.is_set():
                self._wake.wait()
                self._wake.clear()
                if self._stop.is_set() or self._qpos is None:
                    self._busy.clear()
                    continue
                try:
                    self._draw(renderers, *self._qpos, cv2, params)
                except Exception:  # noqa: BLE001 - logged; the clients' streams then end
                    logger.exception("the virtual arm's cameras stopped drawing")
                    return
                finally:
                    self._busy.clear()
        finally:
            for renderer in renderers.values():
                renderer.close()

    def _draw(self, renderers: dict, qpos, taken: float, cv2, params) -> None:
        """Draw and encode every watched camera at ``qpos``; publish the frames."""
        start = time.perf_counter()
        self._snapshot.qpos[:] = qpos
        for name in [n for n in self.names if self._watchers[n]]:
            rgb = renderers[name].render()
            _, jpeg = cv2.imencode(".jpg", rgb[:, :, ::-1], params)
            with self._cond:
                number = self._frames.get(name, (0, b""))[0] + 1
                self._frames[name] = (number, jpeg.tobytes())
                self._cond.notify_all()
        done = time.perf_counter()
        self.stats["frames"] += 1
        self.stats["render_s"] += done - start
        self.stats["latency_s"] += done - taken

    # --- the clients' threads --------------------------------------------------------------
    def next_frame(self, name: str, after: int) -> tuple[int, bytes] | None:
        """The first frame of ``name`` numbered above ``after`` (None: none came in time)."""
        with self._cond:
            ok = self._cond.wait_for(
                lambda: self._stop.is_set() or self._frames.get(name, (0,))[0] > after, STALL_S)
            return self._frames[name] if ok and not self._stop.is_set() else None

    def watch(self, name: str, delta: int) -> None:
        """Count a client of ``name`` in (+1) or out (-1)."""
        with self._cond:
            self._watchers[name] += delta


def _handler(server: CameraServer) -> type[BaseHTTPRequestHandler]:
    """The request handler class serving ``server``'s cameras."""

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args) -> None:  # the emulator's stderr stays quiet
            logger.debug("camera http: " + args[0], *args[1:])

        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            name, _, kind = self.path.lstrip("/").partition(".")
            if name not in server.names or kind not in ("mjpg", "jpg"):
                links = ", ".join(f"/{n}.mjpg" for n in server.names)
                self.send_error(404, f"No such camera stream; served: {links}")
                return
            server.watch(name, +1)
            try:
                if kind == "jpg":
                    self._one(name)
                else:
                    self._stream(name)
            except (BrokenPipeError, ConnectionResetError, TimeoutError):
                pass  # the client went away
            finally:
                server.watch(name, -1)

        def _one(self, name: str) -> None:
            frame = server.next_frame(name, server._frames.get(name, (0,))[0])
            if frame is None:
                self.send_error(503, "No frame rendered in time")
                return
            self.send_response(200)
            self.send_header("Content-Type", "image/jpeg")
            self.send_header("Content-Length", str(len(frame[1])))
            self.end_headers()
            self.wfile.write(frame[1])

        def _stream(self, name: str) -> None:
            self.send_response(200)
            self.send_header("Content-Type", f"multipart/x-mixed-replace;boundary={BOUNDARY}")
            self.send_header("Cache-Control", "no-cache")
            self.end_headers()
            number = server._frames.get(name, (0,))[0]  # from the next frame on
            while (frame := server.next_frame(name, number)) is not None:
                number, jpeg = frame
                self.wfile.write(f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\n"
                                 f"Content-Length: {len(jpeg)}\r\n\r\n".encode() + jpeg + b"\r\n")
                self.wfile.flush()

    return Handler
