"""The tags: one image for the simulator's texture and the printed page, and no physics changed."""

from __future__ import annotations

import re

import mujoco
import numpy as np
import pytest

from so101_kinematics.constants import CUBE_SIZE
from so101_kinematics.markers import pdf_ours
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sim.cube import add_cube, cube_on_table
from so101_kinematics.sim.tag_textures import (
    CUBE_TAG,
    MARKER_CELLS,
    TAGS,
    TARGET_TAG,
    add_cube_tag,
    add_target_tag,
    tag_face_image,
)
from so101_kinematics.vision.tags import tag_page, write_tag_sheet

pytestmark = pytest.mark.vision


def test_the_tag_facts_fit_the_cube():
    assert CUBE_TAG.face == CUBE_SIZE
    for tag in TAGS.values():
        cell = tag.size / MARKER_CELLS
        margin = (tag.face - tag.size) / 2
        assert 0.8 * cell <= margin <= 1.5 * cell, f"{tag.name}: about one cell of white"
    assert len({tag.tag_id for tag in TAGS.values()}) == len(TAGS)


@pytest.mark.parametrize("tag", [CUBE_TAG, TARGET_TAG], ids=lambda t: t.name)
def test_the_face_image_is_the_marker_at_its_size_in_white(tag):
    face = tag_face_image(tag, px_per_cell=30)
    marker_px = MARKER_CELLS * 30
    assert face.shape[0] == face.shape[1]
    assert marker_px / face.shape[0] == pytest.approx(tag.size / tag.face, abs=0.5 / face.shape[0])
    margin = (face.shape[0] - marker_px) // 2
    assert np.all(face[:margin] == 255) and np.all(face[:, -margin:] == 255)  # the quiet zone
    assert np.all(face[margin, margin:-margin] == 0)  # the marker's black border


def test_the_printed_sheet_is_an_a4_pdf_of_ours(tmp_path):
    path = write_tag_sheet(tmp_path / "tags.pdf")
    assert pdf_ours(path)
    box = re.search(rb"/MediaBox \[\s*0 0 ([\d.]+) ([\d.]+)\s*\]", path.read_bytes())
    assert (float(box[1]), float(box[2])) == pytest.approx((595.28, 841.89), abs=0.01)


def test_the_printed_tags_are_true_to_size_and_readable(tmp_path):
    """The page rastered at 10 px/mm: each black square is its size, and the detector reads it."""
    import cv2

    from so101_kinematics.vision.detect import detect_tags

    tag_page().savefig(tmp_path / "page.png", dpi=254)  # 254 dpi = 10 px/mm
    page = cv2.imread(str(tmp_path / "page.png"))[:, :, ::-1].copy()
    seen = detect_tags(page, np.eye(3))
    assert sorted(s.tag.tag_id for s in seen) == sorted(TAGS)
    for s in seen:
        side_mm = np.linalg.norm(s.corners[1] - s.corners[0]) / 10.0
        assert side_mm == pytest.approx(s.tag.size * 1000, abs=0.2), s.tag.name


def _run(with_tags: bool) -> np.ndarray:
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    add_cube(spec, *cube_on_table(0.22, 0.0, 10.0))
    if with_tags:
        add_cube_tag(spec)
        add_target_tag(spec, 0.25, -0.12)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.ctrl[m.actuator("shoulder_pan").id] = 0.5
    for _ in range(250):
        mujoco.mj_step(m, d)
    return np.concatenate([d.qpos, d.qvel, [m.body("cube").mass[0]]])


def test_tags_change_nothing_in_the_physics():
    """Paper-thin, massless, no contact: a second of motion is the same bit for bit."""
    assert np.array_equal(_run(False), _run(True))
