"""The course's scene with the tags: a tagged cube resting on the table and the target tag.

One builder for every program that looks at tags (the tests, the benchmarks, the docs'
picture, the see-and-pick to come), beside ``sim/cube.py``'s ``build_model`` (which it
cannot extend: ``sim/`` does not import the vision layer above it).

Example::

    m = build_tagged_model(cube_at=(0.25, 0.10, 30.0), target_at=(0.25, -0.12, -20.0))
    d = mujoco.MjData(m); mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco

from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sim import actuation
from so101_kinematics.sim.cube import add_cube, cube_on_table
from so101_kinematics.sim.meshes import ensure_meshes
from so101_kinematics.sim.render import use_render_meshes
from so101_kinematics.sim.tag_textures import add_cube_tag, add_target_tag

__all__ = ["build_tagged_model", "tagged_spec"]


def tagged_spec(cube_at: Sequence[float] | None = None,
                target_at: Sequence[float] | None = None, *,
                render_meshes: bool = True) -> mujoco.MjSpec:
    """The course's scene with a tagged cube and the target tag, not yet compiled.

    Args:
        cube_at: the cube resting on the table at (x [m], y [m][, yaw [deg]]) in the base
            frame, its tag on top (``tag_textures.CUBE_TAG``); None: no cube.
        target_at: the target tag on the table at (x [m], y [m][, yaw [deg]]); None: none.
        render_meshes: draw the arm with the decimated render-only meshes (the same
            physics; ``sim/render.py``).

    Returns:
        The spec, for a caller to add to (a test's camera, an obstacle) and compile.
    """
    ensure_meshes()
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    if render_meshes:
        use_render_meshes(spec)
    if cube_at is not None:
        add_cube(spec, *cube_on_table(*cube_at))
        add_cube_tag(spec)
    if target_at is not None:
        add_target_tag(spec, *target_at)
    return spec


def build_tagged_model(cube_at: Sequence[float] | None = None,
                       target_at: Sequence[float] | None = None, *,
                       render_meshes: bool = True,
                       spec: mujoco.MjSpec | None = None) -> mujoco.MjModel:
    """Compile :func:`tagged_spec`'s scene (or ``spec``, one it made and a caller added to).

    Returns:
        The model, with the measured STS3215 servos (``actuation.use_servo``'s defaults, as
        ``sim/cube.py``'s ``build_model``).
    """
    if spec is None:
        spec = tagged_spec(cube_at, target_at, render_meshes=render_meshes)
    m = spec.compile()
    actuation.use_servo(m)
    return m
