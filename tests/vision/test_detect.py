"""One detection path: a tag's pose from a rendered, noisy 640x480 image against the truth.

The issue's acceptance: the tag's pose from a 640x480 image at about 30 cm within 2 mm and
1 deg of the simulator's ground truth, with webcam-like blur and noise on.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from so101_kinematics.constants import CUBE_SIZE
from so101_kinematics.errors import VisionError
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.sim.scene import to_radians
from so101_kinematics.sim.tag_textures import CUBE_TAG, TAG_THICKNESS, TARGET_TAG
from so101_kinematics.vision.camera_model import project_points
from so101_kinematics.vision.detect import detect_tags, find_tag, flat_pose, no_tag_message
from so101_kinematics.vision.sim_camera import WEBCAM, SimCamera
from so101_kinematics.vision.tagged_scene import build_tagged_model, tagged_spec
from so101_kinematics.vision.tags import get_tag_pose_base

CUBE_AT = (0.25, 0.10, 30.0)  # x [m], y [m], yaw [deg]
TARGET_AT = (0.25, -0.12, -20.0)
# Angled cameras 30 cm from each tag, 30 deg off its normal (the "about 30 cm").
PROBE_30CM = {"cube": (CUBE_AT[0] - 0.15, CUBE_AT[1], 0.026 + 0.26),
              "target": (TARGET_AT[0] - 0.15, TARGET_AT[1], 0.26)}
PROBE_AXES = [0, -1, 0, 0.866025, 0, 0.5]  # image right = -y, looking 30 deg off vertical
COVER_AWAY = (1.0, 1.0, -1.0)  # [m] the cover below the table, out of every view


def errors(g, truth) -> tuple[float, float]:
    """Position [mm] and rotation [deg] between two poses."""
    relative = g[:3, :3].T @ truth[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(relative) - 1) / 2, -1.0, 1.0)))
    return float(np.linalg.norm(g[:3, 3] - truth[:3, 3]) * 1000), float(angle)


@pytest.fixture(scope="module")
def tagged():
    """The course's scene with a tagged cube, the target tag, a movable cover, two probes."""
    require_opencv()
    spec = tagged_spec(CUBE_AT, TARGET_AT)
    for name, pos in PROBE_30CM.items():
        spec.worldbody.add_camera(name=f"probe_{name}", pos=list(pos), xyaxes=PROBE_AXES,
                                  fovy=58.0)
    cover = spec.worldbody.add_body(name="cover", mocap=True, pos=list(COVER_AWAY))
    cover.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.04, 0.001], contype=0,
                   conaffinity=0, rgba=[0.3, 0.3, 0.3, 1])
    m = build_tagged_model(spec=spec)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d


def sighting(m, d, camera, tag, effects=WEBCAM):
    with SimCamera(m, d, camera, effects=effects) as cam:
        image = cam.read()
        return find_tag(image, cam.intrinsics(), tag, g_bc=cam.pose()), image, cam.pose()


pytestmark = pytest.mark.vision


@pytest.mark.parametrize("tag", [TARGET_TAG, CUBE_TAG], ids=lambda t: t.name)
def test_a_tags_pose_at_30_cm_is_within_2_mm_and_1_deg(tagged, tag):
    m, d = tagged
    seen, _, _ = sighting(m, d, f"probe_{tag.name}", tag)
    assert seen is not None, "the tag was not found"
    assert abs(np.linalg.norm(seen.g_ct[:3, 3]) - 0.30) < 0.01, "the probe is at about 30 cm"
    position_mm, rotation_deg = errors(seen.g_bt, get_tag_pose_base(m, d, f"{tag.name}_tag"))
    assert position_mm <= 2.0 and rotation_deg <= 1.0, (position_mm, rotation_deg)


def test_the_wrist_camera_over_the_cube_finds_its_pose(tagged):
    """The model's own wrist camera; the arm by IK 6 cm short of the cube, 15 cm up, 60 deg down."""
    m, d = tagged
    cube = np.array(CUBE_AT[:2])
    above = [*(cube - 0.06 * cube / np.linalg.norm(cube)), 0.15]
    qpos = d.qpos.copy()
    try:
        for joint, angle in to_radians(m, get_inverse_kinematics(
                above, approach="pitch", pitch_deg=60.0, yaw_deg=None)).items():
            d.qpos[m.joint(joint).qposadr[0]] = angle
        mujoco.mj_forward(m, d)
        seen, _, _ = sighting(m, d, "wrist", CUBE_TAG)
        truth = get_tag_pose_base(m, d, "cube_tag")
    finally:
        d.qpos[:] = qpos
        mujoco.mj_forward(m, d)
    assert 0.15 < np.linalg.norm(seen.g_ct[:3, 3]) < 0.30
    position_mm, rotation_deg = errors(seen.g_bt, truth)
    assert position_mm <= 2.0 and rotation_deg <= 1.0, (position_mm, rotation_deg)


def test_the_overhead_camera_finds_the_target_tag(tagged):
    """From 55 cm straight above: looser (a head-on tag's tilt is the least certain)."""
    m, d = tagged
    seen, _, _ = sighting(m, d, "overhead", TARGET_TAG)
    position_mm, rotation_deg = errors(seen.g_bt, get_tag_pose_base(m, d, "target_tag"))
    assert position_mm <= 3.0 and rotation_deg <= 1.5, (position_mm, rotation_deg)


@pytest.mark.parametrize(("tag", "height", "yaw_deg"), [
    (CUBE_TAG, CUBE_SIZE + TAG_THICKNESS, 3.0), (TARGET_TAG, TAG_THICKNESS, 1.0)],
    ids=["cube", "target"])
def test_a_flat_tags_pose_from_the_overhead_camera_at_640x480(tagged, tag, height, yaw_deg):
    """Known to lie flat: from 55 cm, 16 px of cube tag still place it within 2 mm."""
    m, d = tagged
    with SimCamera(m, d, "overhead", effects=WEBCAM) as camera:
        K, g_bc = camera.intrinsics(), camera.pose()
        seen = find_tag(camera.read(), K, tag, g_bc=g_bc)
    position_mm, rotation_deg = errors(flat_pose(seen, K, g_bc, height),
                                       get_tag_pose_base(m, d, f"{tag.name}_tag"))
    assert position_mm <= 2.0 and rotation_deg <= yaw_deg, (position_mm, rotation_deg)
    with pytest.raises(VisionError, match="do not look down onto the plane.*Fix"):
        flat_pose(seen, K, g_bc, 1.0)  # a plane above the camera


def test_the_corners_come_in_the_tags_order(tagged):
    """Corner 0 is the tag's top-left (-x, +y in its frame), then clockwise as seen."""
    m, d = tagged
    seen, _, g_bc = sighting(m, d, "probe_target", TARGET_TAG, effects=None)
    half = TARGET_TAG.size / 2
    g_bt = get_tag_pose_base(m, d, "target_tag")
    corners_b = [(g_bt @ [x, y, 0.0, 1.0])[:3] for x, y in
                 ((-half, half), (half, half), (half, -half), (-half, -half))]
    K = SimCamera(m, d, "probe_target").intrinsics()
    assert np.abs(project_points(K, g_bc, corners_b) - seen.corners).max() < 0.3


def test_no_tag_in_view_is_none_and_one_line(tagged):
    m, d = tagged
    seen, image, _ = sighting(m, d, "wrist", TARGET_TAG)  # folded at home: no tag in view
    assert seen is None
    assert detect_tags(image, np.eye(3)) == []
    message = no_tag_message(TARGET_TAG, "wrist")
    assert "\n" not in message and "id 1" in message and message.endswith(".")
    assert "Fix:" in message


def test_a_half_hidden_tag_gives_no_pose(tagged):
    m, d = tagged
    x, y, _ = TARGET_AT
    cover = m.body("cover").mocapid[0]
    d.mocap_pos[cover] = (x - 0.02, y, 0.002)  # over the tag's -x half
    mujoco.mj_forward(m, d)
    try:
        seen, _, _ = sighting(m, d, "probe_target", TARGET_TAG)
        visible, _, _ = sighting(m, d, "probe_cube", CUBE_TAG)
    finally:
        d.mocap_pos[cover] = COVER_AWAY
        mujoco.mj_forward(m, d)
    assert seen is None, "a half-hidden tag must not give a pose"
    assert visible is not None, "the other tag is still seen"


def test_an_image_of_the_wrong_kind_is_refused():
    with pytest.raises(VisionError, match="H x W x 3 uint8 RGB.*Fix"):
        detect_tags(np.zeros((480, 640, 3)), np.eye(3))
