"""Offscreen rendering: render-only meshes, target-cube overlays, the video recorder's inputs."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import so101_kinematics.sim.meshes as so101_meshes
from pick_place_sim import CubeStart, build_model
from so101_forward_kinematics import get_forward_kinematics
from so101_kinematics.errors import MeshError, RenderError
from so101_kinematics.planning.plans import FINAL_CONFIGURATION, STARTING_CONFIGURATION
from so101_kinematics.sim.render import (
    FINAL_RGBA,
    QUALITY,
    START_RGBA,
    FrameRenderer,
    add_overlays,
    target_cubes,
)
from so101_kinematics.sim.video import VideoRecorder


def test_decimated_mesh_stays_within_one_cell_of_the_original(tmp_path):
    cell = so101_meshes.RENDER_CELL_SIZE
    source = so101_meshes.ensure_meshes() / "moving_jaw_so101_v1.stl"
    vertices, faces = so101_meshes.read_stl(source)
    light_vertices, light_faces = so101_meshes.decimate_mesh(vertices, faces, cell)
    assert len(light_faces) < len(faces) / 3
    # Every new vertex is the mean of original vertices sharing a cell, so an
    # original vertex lies within a cell diagonal of it.
    nearest = np.concatenate([
        np.min(np.linalg.norm(chunk[:, None] - vertices[None], axis=2), axis=1)
        for chunk in np.array_split(light_vertices, 20)])
    assert nearest.max() <= np.sqrt(3) * cell
    np.testing.assert_allclose(light_vertices.min(0), vertices.min(0), atol=cell)
    np.testing.assert_allclose(light_vertices.max(0), vertices.max(0), atol=cell)
    # Round trip through the STL writer/reader.
    path = tmp_path / "jaw.stl"
    so101_meshes.write_stl(path, light_vertices, light_faces)
    again_vertices, again_faces = so101_meshes.read_stl(path)
    assert len(again_faces) == len(light_faces)
    np.testing.assert_allclose(np.sort(again_vertices, axis=0), np.sort(
        np.unique(light_vertices[light_faces].reshape(-1, 3).astype(np.float32), axis=0),
        axis=0), atol=1e-9)


def test_read_stl_rejects_a_non_stl_file(tmp_path):
    path = tmp_path / "x.stl"
    path.write_text("solid ascii\nendsolid\n")
    with pytest.raises(MeshError, match="not a binary STL"):
        so101_meshes.read_stl(path)


def test_render_meshes_change_neither_masses_nor_contacts():
    full = build_model(cube=CubeStart())
    light = build_model(cube=CubeStart(), render_meshes=True)
    assert light.nq == full.nq and light.ngeom == full.ngeom
    np.testing.assert_array_equal(light.body_mass, full.body_mass)
    np.testing.assert_array_equal(light.body_inertia, full.body_inertia)
    assert light.nmeshface < full.nmeshface / 5
    visual = full.geom_contype == 0
    np.testing.assert_array_equal(light.geom_size[~visual], full.geom_size[~visual])


def test_target_cubes_are_the_fk_poses_in_red_and_green():
    red, green = target_cubes(STARTING_CONFIGURATION, FINAL_CONFIGURATION)
    for cube, cfg, rgba in ((red, STARTING_CONFIGURATION, START_RGBA),
                            (green, FINAL_CONFIGURATION, FINAL_RGBA)):
        position, rotation = get_forward_kinematics(cfg)
        np.testing.assert_allclose(cube.position, position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(cube.rotation, rotation, rtol=0, atol=1e-12)
        assert cube.rgba == rgba and cube.halfwidth == 0.013


def test_add_overlays_appends_boxes_and_refuses_a_full_scene(model):
    scene = mujoco.MjvScene(model, maxgeom=3)
    add_overlays(scene, target_cubes(STARTING_CONFIGURATION, FINAL_CONFIGURATION))
    assert scene.ngeom == 2
    assert scene.geoms[0].type == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(scene.geoms[1].rgba, FINAL_RGBA)
    with pytest.raises(RenderError, match="full"):
        add_overlays(scene, target_cubes(STARTING_CONFIGURATION, FINAL_CONFIGURATION))


@pytest.fixture(scope="module")
def light_scene():
    m = build_model(render_meshes=True)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d


def test_overlays_show_in_the_rendered_frame(light_scene):
    m, d = light_scene
    images = []
    for overlays in ((), target_cubes(STARTING_CONFIGURATION, FINAL_CONFIGURATION)):
        renderer = FrameRenderer(m, d, (160, 120), overlays=overlays, quality=QUALITY["fast"])
        images.append(renderer.render().astype(int))
        renderer.close()
    changed = np.abs(images[1] - images[0]).sum(axis=2) > 30
    assert 10 < changed.sum() < 0.05 * changed.size  # two small cubes, nothing else


@pytest.mark.parametrize("kwargs, message", [
    ({"size": (641, 480)}, "must be even"),
    ({"fps": 0.0}, r"fps = 0 frames/s is not in \[1, 250\] frames/s"),
    ({"camera": "nope"}, "Unknown camera 'nope'; the model has: pick_place"),
])
def test_recorder_refuses_bad_settings(light_scene, tmp_path, kwargs, message):
    m, d = light_scene
    with pytest.raises(RenderError, match=message):
        VideoRecorder(m, d, tmp_path / "v.mp4", progress=False, **kwargs)


def test_recorder_wants_an_mp4_path(light_scene, tmp_path):
    m, d = light_scene
    with pytest.raises(RenderError, match=r"must end in \.mp4"):
        VideoRecorder(m, d, tmp_path / "v.avi", progress=False)
    assert not (tmp_path / "v.avi").exists()


def test_frame_renderer_refuses_a_render_model_with_other_joints(light_scene):
    m, d = light_scene
    with pytest.raises(RenderError, match="position coordinates"):
        FrameRenderer(m, d, render_model=build_model(cube=CubeStart(), render_meshes=True))
