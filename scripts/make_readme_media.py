"""Render the README's pick-and-place picture (docs/pick_place.png) and optionally a short GIF."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
REPO = _HERE.parent
sys.path.insert(0, str(REPO))

import so101_kinematics.display as so101_display  # noqa: E402, F401  (before mujoco: EGL when there is no display)

# isort: split
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import so101_mujoco_utils as utils  # noqa: E402
from pick_place_sim import INITIAL_KEYFRAME, CubeStart, build_model, total_duration  # noqa: E402
from so101_kinematics.errors import OutputPathError  # noqa: E402
from so101_kinematics.outputs import (  # noqa: E402
    PNG,
    add_overwrite_argument,
    atomic_output,
    check_output_path,
    write_png_atomic,
)
from so101_kinematics.planning.motion import run_plan  # noqa: E402
from so101_kinematics.planning.plans import default_plan, pick_and_place_steps  # noqa: E402
from so101_kinematics.sim.render import QUALITY, FrameRenderer, target_cubes  # noqa: E402

PNG_PATH = REPO / "docs" / "pick_place.png"
GIF_PATH = REPO / "docs" / "pick_place.gif"
PNG_SIZE = (640, 480)  # [px]
PNG_TIME = 8.4  # [s] the cube lifted above its start (red); the green target is where it goes
GIF_SIZE = (320, 240)  # [px]
GIF_FPS = 10.0  # [frames/s]
QUALITY_NAME = "shadows"


class Snapshots:
    """A viewer for move_to_pose that renders frames at chosen simulation times."""

    offscreen = True
    sync_every_step = True

    def __init__(self, renderer: FrameRenderer, d: mujoco.MjData, times: list[float]):
        self.renderer, self.d, self.times = renderer, d, sorted(times)
        self.frames: list[np.ndarray] = []

    def is_running(self) -> bool:
        """Always true (no window)."""
        return True

    def sync(self) -> None:
        """Render a frame for each requested time that simulation time has reached."""
        while self.times and self.d.time >= self.times[0]:
            self.times.pop(0)
            self.frames.append(self.renderer.render())


def render_run(times: list[float], size: tuple[int, int], quality: str) -> list[np.ndarray]:
    """Run the default pick-and-place with the cube and render it at ``times`` [s]."""
    plan = default_plan()
    m = build_model(plan, CubeStart(), render_meshes=QUALITY[quality].light_meshes)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(INITIAL_KEYFRAME).id)
    mujoco.mj_forward(m, d)
    initial = utils.get_configuration(m, d)
    pick, place = pick_and_place_steps(plan)
    renderer = FrameRenderer(m, d, size, overlays=target_cubes(pick.configuration,
                                                               place.configuration),
                             quality=QUALITY[quality])
    shots = Snapshots(renderer, d, times)
    try:
        run_plan(plan, lambda cfg, t: utils.move_to_pose(m, d, shots, cfg, t),
                 lambda t: utils.hold_position(m, d, shots, t), initial)
    finally:
        renderer.close()
    return shots.frames


def main() -> int:
    """Write the PNG (and the GIF with --gif); exit 2 on an output it may not replace."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gif", action="store_true", help=f"also write {GIF_PATH.name}")
    parser.add_argument("--quality", choices=sorted(QUALITY), default=QUALITY_NAME)
    add_overwrite_argument(parser)
    args = parser.parse_args()
    import imageio.v2 as imageio

    try:  # the PNG replaces only a PNG of ours; the GIF (no marker) only with --overwrite
        check_output_path(PNG_PATH, "the picture", overwrite=args.overwrite, kind=PNG)
        if args.gif:
            check_output_path(GIF_PATH, "the GIF", overwrite=args.overwrite)
    except OutputPathError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    (frame,) = render_run([PNG_TIME], PNG_SIZE, args.quality)
    write_png_atomic(PNG_PATH, frame, "scripts/make_readme_media.py")
    print(f"Wrote {PNG_PATH.relative_to(REPO)}")
    if args.gif:
        duration = total_duration(default_plan())
        times = list(np.arange(0.0, duration, 1.0 / GIF_FPS))
        frames = render_run(times, GIF_SIZE, args.quality)
        with atomic_output(GIF_PATH) as temporary:
            imageio.mimsave(temporary, frames, format="GIF", duration=1.0 / GIF_FPS, loop=0)
        print(f"Wrote {GIF_PATH.relative_to(REPO)} ({len(frames)} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
