"""Run a course-style script unchanged, with MuJoCo's passive viewer replaced by a headless one.

Usage: ``python tests/course_scripts/run_headless.py SCRIPT [ARGS...]`` from the
repository root. ``mujoco.viewer.launch_passive(m, d)`` returns a
:class:`HeadlessViewer`: the same calls a course script makes (``sync``,
``is_running``, ``user_scn``, ``lock``, ``close``, the ``with`` block), no
window, and not paced to real time (``offscreen``). With
``COURSE_VIEWER_CLOSES_AFTER=N`` in the environment the "window" is closed
after N syncs, as a student closing it. Everything else (imports, exit
status, tracebacks, exit hooks) is the script's own: it runs as ``__main__``.
"""

from __future__ import annotations

import contextlib
import os
import runpy
import sys

import mujoco
import mujoco.viewer


class HeadlessViewer:
    """A stand-in for MuJoCo's passive viewer handle: no window, closed after N syncs if asked."""

    offscreen = True  # the project's moves need not pace it to real time

    def __init__(self, m, d, closes_after: int | None):
        self.m, self.d = m, d
        self.user_scn = mujoco.MjvScene(m, maxgeom=1000)
        self.cam, self.opt = mujoco.MjvCamera(), mujoco.MjvOption()
        self.syncs, self.closes_after, self.closed = 0, closes_after, False

    def is_running(self) -> bool:
        return not self.closed

    def sync(self) -> None:
        if self.closed:
            return  # MuJoCo's handle ignores a sync once the window is gone
        self.syncs += 1
        if self.closes_after is not None and self.syncs >= self.closes_after:
            self.closed = True

    def lock(self):
        return contextlib.nullcontext()

    def close(self) -> None:
        self.closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def launch_passive(m, d, **_options) -> HeadlessViewer:
    """``mujoco.viewer.launch_passive`` without a window."""
    closes_after = os.environ.get("COURSE_VIEWER_CLOSES_AFTER")
    return HeadlessViewer(m, d, int(closes_after) if closes_after else None)


def main() -> None:
    mujoco.viewer.launch_passive = launch_passive
    script = sys.argv[1]
    sys.argv = sys.argv[1:]
    sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
    runpy.run_path(script, run_name="__main__")


if __name__ == "__main__":
    main()
