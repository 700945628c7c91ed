"""The cameras' numbers: intrinsics from fovy by hand, and the axes flip checked against MuJoCo.

No OpenCV needed: these run in every leg (the base one too).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from conftest import assert_transforms_close

from so101_kinematics.errors import RenderSettingError, VisionError
from so101_kinematics.vision.camera_model import (
    R_MUJOCO_OPENCV,
    camera_intrinsics,
    get_camera_pose_base,
    intrinsics_from_fovy,
    project_points,
)

DOTS = {"red": ((0.10, 0.05, 0.0), (1, 0, 0)), "green": ((-0.12, -0.03, 0.02), (0, 1, 0)),
        "blue": ((0.03, 0.16, -0.01), (0, 0, 1))}
"""Small spheres (centre [m], colour) the renderer draws and the projection must find."""


def dots_scene(camera: str) -> mujoco.MjModel:
    """Three coloured dots, a base body turned and moved (so base != world), one camera."""
    geoms = "".join(f'<geom type="sphere" size="0.003" pos="{" ".join(map(str, p))}" '
                    f'rgba="{" ".join(map(str, c))} 1"/>' for p, c in DOTS.values())
    return mujoco.MjModel.from_xml_string(f"""
<mujoco><visual><global offwidth="640" offheight="480"/>
<headlight ambient="1 1 1" diffuse="0 0 0" specular="0 0 0"/></visual>
<worldbody><body name="base" pos="0.05 -0.02 0.01" euler="0 0 0.4"/>{geoms}{camera}</worldbody>
</mujoco>""")


def test_intrinsics_are_the_hand_calculation_from_fovy():
    K = intrinsics_from_fovy(58.0, 640, 480)
    fy = (480 / 2) / math.tan(math.radians(58.0) / 2)  # 432.99 px
    assert K[1, 1] == pytest.approx(fy, rel=1e-12) and K[0, 0] == pytest.approx(fy, rel=1e-12)
    assert (K[0, 2], K[1, 2]) == (319.5, 239.5)  # pixel centres at integers: the middle
    assert K[0, 1] == 0.0 and list(K[2]) == [0.0, 0.0, 1.0]


def test_the_models_cameras_have_their_fovy(model):
    for name, fovy in (("overhead", 58.0), ("wrist", 60.0)):
        K = camera_intrinsics(model, name, 640, 480)
        assert K[1, 1] == pytest.approx(240 / math.tan(math.radians(fovy) / 2))


def test_an_unknown_camera_names_those_there_are(model):
    with pytest.raises(RenderSettingError, match="overhead.*Fix"):
        camera_intrinsics(model, "webcam", 640, 480)
    with pytest.raises(VisionError, match="Fix"):
        intrinsics_from_fovy(0.0, 640, 480)


def test_opencv_frame_is_mujocos_turned_half_a_turn_about_x():
    assert np.array_equal(R_MUJOCO_OPENCV @ R_MUJOCO_OPENCV, np.eye(3))
    assert np.linalg.det(R_MUJOCO_OPENCV) == 1.0  # a rotation, not a mirror
    # MuJoCo looks along its -z with y up; OpenCV along +z with y down:
    assert np.array_equal(R_MUJOCO_OPENCV @ [0, 0, 1], [0, 0, -1])
    assert np.array_equal(R_MUJOCO_OPENCV @ [0, 1, 0], [0, -1, 0])


@pytest.mark.parametrize("camera", [
    '<camera name="c" pos="0.02 -0.01 0.5" xyaxes="0.9 0.1 0 -0.1 0.9 0.3" fovy="58"/>',
    '<camera name="c" pos="-0.2 0.1 0.3" xyaxes="0 -1 0 0.8 0 0.6" fovy="45"/>',
])
def test_a_projected_point_lands_where_mujoco_draws_it(camera):
    """Each dot's centroid in the rendered image is its projection through K and g_bc."""
    m = dots_scene(camera)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    with mujoco.Renderer(m, 480, 640) as renderer:
        renderer.update_scene(d, "c")
        image = renderer.render().astype(float)
    g_wb = np.eye(4)
    g_wb[:3, :3], g_wb[:3, 3] = d.body("base").xmat.reshape(3, 3), d.body("base").xpos
    K, g_bc = camera_intrinsics(m, "c", 640, 480), get_camera_pose_base(m, d, "c")
    for name, (p_w, colour) in DOTS.items():
        p_b = (np.linalg.inv(g_wb) @ [*p_w, 1.0])[:3]
        mask = np.all((image > 128) == (np.array(colour) > 0), axis=2)
        v, u = np.nonzero(mask)
        assert len(u) > 10, f"{name} dot not drawn"
        drawn = np.array([u.mean(), v.mean()])
        projected = project_points(K, g_bc, p_b)[0]
        assert np.linalg.norm(drawn - projected) < 0.15, (name, drawn, projected)


def test_a_point_behind_the_camera_projects_to_nothing():
    uv = project_points(np.eye(3), np.eye(4), [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    assert np.all(np.isnan(uv[0])) and np.allclose(uv[1], 0.0)


def test_the_wrist_camera_rides_on_the_gripper(model):
    """Its pose in the gripper body is the mount's, whatever the arm's configuration."""
    d = mujoco.MjData(model)
    mounts = []
    for seed in range(3):
        rng = np.random.default_rng(seed)
        for name in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"):
            d.qpos[model.joint(name).qposadr[0]] = rng.uniform(-1.0, 1.0)
        mujoco.mj_forward(model, d)
        g_bg = np.eye(4)
        g_bg[:3, :3] = d.body("gripper").xmat.reshape(3, 3)
        g_bg[:3, 3] = d.body("gripper").xpos
        mounts.append(np.linalg.inv(g_bg) @ get_camera_pose_base(model, d, "wrist"))
    for mount in mounts[1:]:
        assert_transforms_close(mount, mounts[0], 1e-9, 1e-9, "wrist mount")
    assert np.allclose(mounts[0][:3, 3], [-0.05, 0.0, -0.04])
