"""A virtual X display for the viewer tests: start Xvfb, find, screenshot and close windows.

Needs Debian's ``xvfb``, ``xdotool`` and ``x11-apps`` (``xwd``); ``.ci/run``
installs them when they are missing. :func:`missing_tools` names what is
missing, so that the tests can skip with that reason.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import shutil
import subprocess
import time
from dataclasses import dataclass

import numpy as np

TOOLS = {"Xvfb": "xvfb", "xdotool": "xdotool", "xwd": "x11-apps"}  # program: Debian package
SCREEN = (1280, 1024)  # [px] the virtual screen


def missing_tools() -> list[str]:
    """The Debian packages to install for the virtual display, if any."""
    missing = [package for program, package in TOOLS.items() if shutil.which(program) is None]
    if ctypes.util.find_library("X11") is None:
        missing.append("libx11-6")
    return missing


class VirtualDisplay:
    """An Xvfb server on a free display number; ``name`` is the ``DISPLAY`` value.

    ``-noreset``: an X server resets when its last client disconnects, and a program that
    connects during the reset fails with "Failed to open display" (CI's loaded slow leg: the
    second viewer test's program, started just after the first test's window and the
    ``xdotool`` polls had all closed). One module's tests share the server, so it must not
    reset between them.
    """

    def __init__(self, size=SCREEN) -> None:
        read, write = os.pipe()
        self.process = subprocess.Popen(
            ["Xvfb", "-displayfd", str(write), "-screen", "0", f"{size[0]}x{size[1]}x24",
             "-nolisten", "tcp", "-noreset"], pass_fds=(write,), stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        os.close(write)
        with os.fdopen(read) as pipe:
            number = pipe.readline().strip()  # Xvfb writes it once it accepts connections
        if not number:
            self.process.kill()
            raise RuntimeError("Xvfb did not start")
        self.name = f":{number}"

    def env(self, **extra) -> dict[str, str]:
        """The environment for a program on this display (GLFW, not EGL)."""
        env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "WAYLAND_DISPLAY")}
        env.update(DISPLAY=self.name, **extra)
        return env

    def run(self, *args: str) -> str:
        return subprocess.run(args, env=self.env(), capture_output=True, text=True,
                              timeout=20).stdout

    def find_window(self, name: str, process: subprocess.Popen | None = None,
                    timeout: float = 90.0) -> int:
        """The id of the first visible window whose title contains ``name``.

        With ``process``, a program that exits before its window shows fails at once with its
        output (rather than a timeout that says nothing of why). The timeout is generous: on a
        loaded 2-core machine, starting Python, MuJoCo and llvmpipe has taken over 30 s.
        """
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            ids = self.run("xdotool", "search", "--onlyvisible", "--name", name).split()
            if ids:
                return int(ids[0])
            if process is not None and process.poll() is not None:
                out, err = process.communicate()
                raise RuntimeError(f"exited with {process.returncode} before a window named "
                                   f"'{name}' showed:\n{out}{err}")
            time.sleep(0.2)
        raise TimeoutError(f"no window named '{name}' within {timeout} s")

    def geometry(self, window: int) -> Geometry:
        """Position and size of a window on the screen [px]."""
        values = dict(line.split("=") for line in
                      self.run("xdotool", "getwindowgeometry", "--shell", str(window)).split())
        return Geometry(int(values["X"]), int(values["Y"]), int(values["WIDTH"]),
                        int(values["HEIGHT"]))

    def screenshot(self) -> np.ndarray:
        """The whole screen as a (height, width, 3) uint8 RGB image (through ``xwd``)."""
        raw = subprocess.run(["xwd", "-root", "-silent", "-display", self.name],
                             capture_output=True, timeout=20, check=True).stdout
        return parse_xwd(raw)

    def close_window(self, window: int) -> None:
        """Ask a window to close as a window manager's close button does (WM_DELETE_WINDOW)."""
        send_delete_window(self.name, window)

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(10)


@dataclass(frozen=True)
class Geometry:
    """A window's rectangle on the screen [px]."""

    x: int
    y: int
    width: int
    height: int

    def crop(self, image: np.ndarray) -> np.ndarray:
        return image[self.y:self.y + self.height, self.x:self.x + self.width]


def parse_xwd(raw: bytes) -> np.ndarray:
    """Decode an ``xwd`` dump of a 24-bit TrueColor screen (24 or 32 bits per pixel) to RGB."""
    header = np.frombuffer(raw[:100], dtype=">u4")
    header_size, width, height = int(header[0]), int(header[4]), int(header[5])
    byte_order, bits_per_pixel, bytes_per_line = int(header[7]), int(header[11]), int(header[12])
    ncolors = int(header[19])
    if bits_per_pixel not in (24, 32):
        raise ValueError(f"expected 24 or 32 bits per pixel, got {bits_per_pixel}")
    size = bits_per_pixel // 8  # [bytes] per pixel
    start = header_size + 12 * ncolors
    pixels = np.frombuffer(raw[start:start + height * bytes_per_line], dtype=np.uint8)
    pixels = pixels.reshape(height, bytes_per_line)[:, :size * width].reshape(height, width, size)
    # LSBFirst (0): each pixel is B, G, R (, X) in memory; MSBFirst: (X,) R, G, B.
    return pixels[..., 2::-1].copy() if byte_order == 0 else pixels[..., size - 3:].copy()


class _ClientMessage(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("serial", ctypes.c_ulong), ("send_event", ctypes.c_int),
                ("display", ctypes.c_void_p), ("window", ctypes.c_ulong),
                ("message_type", ctypes.c_ulong), ("format", ctypes.c_int),
                ("data", ctypes.c_long * 5)]


class _XEvent(ctypes.Union):
    _fields_ = [("xclient", _ClientMessage), ("pad", ctypes.c_long * 24)]


def send_delete_window(display_name: str, window: int) -> None:
    """Send WM_PROTOCOLS / WM_DELETE_WINDOW to a window (what a close button does)."""
    x11 = ctypes.CDLL(ctypes.util.find_library("X11"))
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XInternAtom.restype = ctypes.c_ulong
    x11.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    x11.XSendEvent.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_long,
                               ctypes.POINTER(_XEvent)]
    x11.XFlush.argtypes = x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    display = x11.XOpenDisplay(display_name.encode())
    if not display:
        raise RuntimeError(f"cannot open display {display_name}")
    try:
        event = _XEvent()
        event.xclient.type = 33  # ClientMessage
        event.xclient.window = window
        event.xclient.message_type = x11.XInternAtom(display, b"WM_PROTOCOLS", False)
        event.xclient.format = 32
        event.xclient.data[0] = x11.XInternAtom(display, b"WM_DELETE_WINDOW", False)
        event.xclient.data[1] = 0  # CurrentTime
        x11.XSendEvent(display, window, False, 0, ctypes.byref(event))
        x11.XFlush(display)
    finally:
        x11.XCloseDisplay(display)
