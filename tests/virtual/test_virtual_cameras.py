"""The virtual arm's cameras (``virtual/camera_server.py``): OpenCV and lerobot open them.

One virtual arm serves ``overhead`` and ``wrist`` for the whole module (a real-time arm
starts in about 2 s); the expected images are the simulator's own renders of the same pose
(``vision/sim_camera.py``), the expected sizes the ones asked for.
"""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("lerobot")
cv2 = pytest.importorskip("cv2")
pytestmark = [pytest.mark.hw, pytest.mark.vision]

import mujoco  # noqa: E402

from so101_kinematics.errors import OpenCVMissing  # noqa: E402
from so101_kinematics.paths import REPO  # noqa: E402
from so101_kinematics.sim.cube import build_model  # noqa: E402
from so101_kinematics.sim.scene import set_initial_pose  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.camera_server import require_cv2  # noqa: E402
from so101_kinematics.vision.sim_camera import SimCamera  # noqa: E402

POSE_A = {"shoulder_pan": 0.0, "shoulder_lift": -60.0, "elbow_flex": 60.0, "wrist_flex": 60.0,
          "wrist_roll": 0.0, "gripper": 20.0}
POSE_B = dict(POSE_A, shoulder_pan=35.0, wrist_flex=30.0)
JPEG_MEAN_ERROR = 3.0  # [grey levels] JPEG at quality 90 of a rendered scene: about 1
MOVED = 5.0  # [grey levels] the arm turned 35 deg changes far more of the overhead image


@pytest.fixture(scope="module")
def arm():
    with VirtualSO101(cameras=["overhead", "wrist"], initial=POSE_A) as virtual:
        yield virtual


def latest_frame(capture, seconds: float = 0.6) -> np.ndarray:
    """The last frame read over ``seconds`` (whatever OpenCV had buffered read past)."""
    frame, end = None, time.monotonic() + seconds
    while time.monotonic() < end or frame is None:
        ok, image = capture.read()
        assert ok, "the stream ended"
        frame = image
    return frame


def frame_moved_from(capture, before: np.ndarray, seconds: float = 5.0) -> np.ndarray:
    """The first frame that differs from ``before`` by more than MOVED (or the last in ``seconds``).

    The stream is a frame behind the arm by up to a few of its periods, more on a loaded
    machine (a frame still being drawn when the next is due is skipped): wait for the change,
    then compare it with the simulator's picture.
    """
    end = time.monotonic() + seconds
    while True:
        ok, frame = capture.read()
        assert ok, "the stream ended"
        if np.abs(frame.astype(int) - before).mean() > MOVED or time.monotonic() > end:
            return latest_frame(capture, 0.2)  # and past the frame being drawn at the change


def sim_render(camera: str, cfg: dict) -> np.ndarray:
    """The simulator's own image of the arm at ``cfg`` (BGR, as OpenCV reads)."""
    m = build_model(render_meshes=True)
    d = mujoco.MjData(m)
    set_initial_pose(d, cfg)
    mujoco.mj_forward(m, d)
    with SimCamera(m, d, camera) as sim:
        return sim.read()[:, :, ::-1]


def test_opencv_opens_each_camera_and_the_image_follows_the_arm(arm):
    assert set(arm.camera_addresses) == {"overhead", "wrist"}
    for name, address in arm.camera_addresses.items():
        assert address.startswith("http://127.0.0.1:") and address.endswith(f"/{name}.mjpg")
    capture = cv2.VideoCapture(arm.camera_addresses["overhead"])
    try:
        assert capture.isOpened()
        start = time.monotonic()
        ok, frame = capture.read()
        assert ok and frame.shape == (480, 640, 3) and frame.dtype == np.uint8
        assert time.monotonic() - start < 5.0
        before = latest_frame(capture)
        truth = sim_render("overhead", arm.joint_positions())
        assert np.abs(before.astype(int) - truth).mean() < JPEG_MEAN_ERROR
        arm.set_pose(POSE_B)
        after = frame_moved_from(capture, before)
        assert np.abs(after.astype(int) - before).mean() > MOVED
        assert np.abs(after.astype(int) - sim_render("overhead", arm.joint_positions())).mean() \
            < JPEG_MEAN_ERROR
    finally:
        capture.release()
        arm.set_pose(POSE_A)


def test_one_frame_as_jpeg_and_an_unknown_path_answered_with_the_streams(arm):
    import urllib.error
    import urllib.request

    address = arm.camera_addresses["wrist"]
    with urllib.request.urlopen(address.replace(".mjpg", ".jpg"), timeout=10) as answer:
        assert answer.headers["Content-Type"] == "image/jpeg"
        image = cv2.imdecode(np.frombuffer(answer.read(), np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (480, 640, 3)
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(address.replace("wrist", "gripper_closeup"), timeout=10)
    assert refused.value.code == 404
    assert "/overhead.mjpg" in refused.value.read().decode()


def test_the_physics_keeps_real_time_while_both_cameras_are_read(arm):
    captures = [cv2.VideoCapture(address) for address in arm.camera_addresses.values()]
    try:
        for capture in captures:
            assert capture.read()[0]
        before, frames, start = arm.reply_stats(), 0, time.monotonic()
        while time.monotonic() - start < 2.0:
            frames += sum(capture.read()[0] for capture in captures)
        after, seconds = arm.reply_stats(), time.monotonic() - start
    finally:
        for capture in captures:
            capture.release()
    slip = (after["wall_time_s"] - before["wall_time_s"]) - (after["sim_time_s"]
                                                             - before["sim_time_s"])
    assert slip < 0.1  # [s] of 2 s; the physics drops steps only 25 steps (50 ms) behind
    assert frames / seconds / 2 > 10  # [frames/s] each camera (30 asked for; CI shares the CPU)
    assert arm.camera_stats()["frames"] > 0


def test_lerobot_reads_a_frame_through_its_camera_factory(arm):
    import draccus
    from lerobot.cameras.utils import make_cameras_from_configs
    from lerobot.robots.so_follower.config_so_follower import SOFollowerRobotConfig

    import lerobot_camera_so101_virtual  # noqa: F401 - registers the type
    from lerobot_camera_so101_virtual import SO101VirtualCamera

    address = arm.camera_addresses["wrist"]
    config = draccus.parse(SOFollowerRobotConfig, args=[
        "--port=/dev/null",
        f"--cameras={{front: {{type: so101_virtual, address: '{address}', width: 640, "
        "height: 480, fps: 30}}"])
    assert config.cameras["front"].address == address  # the URL's // survived
    cameras = make_cameras_from_configs(config.cameras)
    camera = cameras["front"]
    assert isinstance(camera, SO101VirtualCamera)
    camera.connect(warmup=False)
    try:
        frame = camera.read()
    finally:
        camera.disconnect()
    assert frame.shape == (480, 640, 3)
    truth = sim_render("wrist", arm.joint_positions())[:, :, ::-1]  # lerobot gives RGB
    assert np.abs(frame.astype(int) - truth).mean() < JPEG_MEAN_ERROR


def test_the_script_prints_one_line_per_camera_and_refuses_an_unknown_one():
    script = str(REPO / "virtual_so101.py")
    refused = subprocess.run([sys.executable, script, "--camera", "nosuch"], cwd=REPO,
                             capture_output=True, text=True, stdin=subprocess.DEVNULL, timeout=60)
    assert refused.returncode == 2
    error = refused.stderr.strip()
    assert "\n" not in error and "'nosuch'" in error
    assert "overhead" in error and "wrist" in error
    with subprocess.Popen([sys.executable, script, "--camera", "wrist", "--camera-size",
                           "320x240"], cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                          stderr=subprocess.DEVNULL, text=True) as served:
        try:
            assert served.stdout.readline().startswith("/dev/pts/")
            line = served.stdout.readline().strip()
            assert line.startswith("camera wrist: http://127.0.0.1:")
            capture = cv2.VideoCapture(line.split(": ", 1)[1])
            ok, frame = capture.read()
            capture.release()
            assert ok and frame.shape == (240, 320, 3)
        finally:
            served.stdin.write("quit\n")
            served.stdin.close()
            served.wait(10)


def test_a_camera_size_without_a_camera_is_refused(capsys):
    import virtual_so101

    assert virtual_so101.main(["--camera-size", "320x240"]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "--camera NAME" in error


def test_without_opencv_one_line_names_the_fix(monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 -> ImportError
    with pytest.raises(OpenCVMissing) as error:
        require_cv2()
    assert "\n" not in str(error.value) and "pip install" in str(error.value)


def test_lerobot_s_command_line_parser_finds_the_type_through_discover_packages_path(monkeypatch):
    """The parser lerobot-record (and every lerobot command) runs its arguments through."""
    from dataclasses import make_dataclass

    from lerobot.configs import parser
    from lerobot.robots.config import RobotConfig
    from lerobot.robots.so_follower.config_so_follower import SOFollowerRobotConfig  # noqa: F401

    # lerobot-record's config has its robot here (a class, not this module's string)
    command = make_dataclass("Command", [("robot", RobotConfig)])
    address = "http://127.0.0.1:8000/overhead.mjpg"
    monkeypatch.setattr(sys, "argv", [
        "lerobot-record", "--robot.type=so101_follower", "--robot.port=/dev/null",
        "--robot.discover_packages_path=lerobot_camera_so101_virtual",
        f"--robot.cameras={{front: {{type: so101_virtual, address: '{address}', width: 640, "
        "height: 480, fps: 30}}"])
    parsed = []

    def record(cfg) -> None:
        parsed.append(cfg)

    record.__annotations__["cfg"] = command
    parser.wrap()(record)()
    camera = parsed[0].robot.cameras["front"]
    assert camera.type == "so101_virtual" and camera.address == address
    assert (camera.width, camera.height, camera.fps) == (640, 480, 30)
