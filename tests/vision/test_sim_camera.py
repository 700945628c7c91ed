"""The simulator's cameras read as real ones: the Camera seam, and seeded webcam-like effects.

No OpenCV needed.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from so101_kinematics.errors import VisionError
from so101_kinematics.interfaces import Camera
from so101_kinematics.vision.sim_camera import WEBCAM, ImageEffects, SimCamera, apply_effects


@pytest.fixture(scope="module")
def scene(model):
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
    mujoco.mj_forward(model, d)
    return model, d


@pytest.mark.parametrize("name", ["overhead", "wrist"])
def test_each_model_camera_is_a_camera_of_the_seam(scene, name):
    m, d = scene
    with SimCamera(m, d, name, size=(320, 240)) as camera:
        assert isinstance(camera, Camera) and camera.name == name
        image = camera.read()
        assert image.shape == (240, 320, 3) and image.dtype == np.uint8
        assert image.std() > 5.0, "a blank image"
        assert camera.intrinsics()[1, 1] > 0 and camera.pose().shape == (4, 4)


def test_effects_are_seeded_and_change_the_image():
    image = np.full((40, 60, 3), 128, dtype=np.uint8)
    image[10:30, 20:40] = 20
    noisy = [apply_effects(image, WEBCAM, np.random.default_rng(WEBCAM.seed)) for _ in range(2)]
    assert np.array_equal(noisy[0], noisy[1]), "the same seed, the same image"
    assert not np.array_equal(noisy[0], image)
    assert abs(float(noisy[0].mean()) - float(image.mean())) < 1.0  # noise and blur keep the level
    darker = apply_effects(image, ImageEffects(exposure=0.5), np.random.default_rng(0))
    assert darker[0, 0, 0] == 64
    blurred = apply_effects(image, ImageEffects(blur_px=2.0), np.random.default_rng(0))
    assert 20 < blurred[20, 20, 0] < 128, "the square's edge is soft"


def test_a_camera_with_effects_gives_the_same_frames_each_run(scene):
    m, d = scene
    frames = []
    for _ in range(2):
        with SimCamera(m, d, "overhead", size=(160, 120), effects=WEBCAM) as camera:
            frames.append(camera.read())
    assert np.array_equal(*frames)


@pytest.mark.parametrize("bad", [{"blur_px": -1.0}, {"noise_levels": float("nan")},
                                 {"exposure": 0.0}])
def test_a_wrong_effect_is_one_line_with_the_fix(bad):
    with pytest.raises(VisionError, match=r"^ImageEffects .* Fix: e\.g\. .*\.$"):
        ImageEffects(**bad)
