"""lerobot's own command-line tools against shell-started virtual arms (issue 14).

Each test starts ``python virtual_so101.py ...`` as a student would, drives its
hand through stdin, and runs lerobot's unmodified tools (lerobot-setup-motors,
lerobot-calibrate, lerobot-teleoperate, lerobot-record) as subprocesses, their
prompts answered through a pipe. Expected values come from the shipped
calibration (calibration/virtual_so101.json) and the issue's acceptance figures.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from so101_kinematics.gravity import feedforward
from so101_kinematics.paths import REPO
from so101_kinematics.servo import KIT_SUPPLY_V, LEROBOT

pytestmark = [pytest.mark.hw, pytest.mark.slow, pytest.mark.newest_lerobot]
BIN = Path(sys.executable).parent
SHIPPED = json.loads((REPO / "calibration" / "virtual_so101.json").read_text())


KIT_FOLLOWER = ("--supply", f"{KIT_SUPPLY_V:g}")
"""The kit's 5 V C001 follower: the sag and lag the teleoperation tests allow are its figures
(the virtual arm's default is the course's 12 V C018 follower)."""


class ShellArm:
    """``python virtual_so101.py ARGS`` with its stdin/stdout as a command line."""

    def __init__(self, *args: str):
        self.process = subprocess.Popen([sys.executable, str(REPO / "virtual_so101.py"), *args],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        text=True, cwd=REPO)
        self.port = self.process.stdout.readline().strip()
        assert self.port.startswith("/dev/"), self.port
        self.cameras = {}  # name -> address: a line each after the port (--camera NAME)
        for _ in range(args.count("--camera")):
            name, address = self.process.stdout.readline().strip().split(": ", 1)
            self.cameras[name.removeprefix("camera ")] = address

    def ask(self, line: str) -> str:
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()
        return self.process.stdout.readline().strip()

    def __call__(self, line: str) -> str:
        answer = self.ask(line)
        assert answer.startswith("ok"), (line, answer)
        return answer

    def pose(self) -> dict[str, float]:
        words = self("where").split()[1:]
        return {w.split("=")[0]: float(w.split("=")[1]) for w in words}

    def close(self) -> None:
        if self.process.poll() is None:
            self("quit")
            assert self.process.wait(timeout=20) == 0


@pytest.fixture
def env(tmp_path):
    pytest.importorskip("lerobot")
    return dict(os.environ, HF_LEROBOT_CALIBRATION=str(tmp_path / "calibration"),
                HF_HUB_OFFLINE="1", HF_LEROBOT_HOME=str(tmp_path / "home"))


class Tool:
    """A lerobot tool as a subprocess, its output drained all along (live tables fill a pipe)."""

    def __init__(self, name: str, *args: str, env: dict):
        self.process = subprocess.Popen([str(BIN / name), *args], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True, env=env)
        self.output: list[str] = []
        self.reader = threading.Thread(target=self._drain, daemon=True)
        self.reader.start()

    def _drain(self) -> None:  # byte by byte: a prompt has no newline
        while chunk := os.read(self.process.stdout.fileno(), 4096):
            self.output.append(chunk.decode(errors="replace"))

    def wait_for(self, text: str, timeout: float = 90) -> None:
        deadline = time.monotonic() + timeout
        while text not in "".join(self.output):
            assert time.monotonic() < deadline and self.poll() is None, "".join(self.output)
            time.sleep(0.2)

    def poll(self):
        return self.process.poll()

    def type(self, text: str) -> None:
        try:
            self.process.stdin.write(text)
            self.process.stdin.flush()
        except BrokenPipeError:  # the tool ended early: say how, with everything it printed
            self.reader.join(timeout=10)
            raise AssertionError(f"the tool exited ({self.process.wait(timeout=10)}) before "
                                 f"reading {text!r}; its output:\n{''.join(self.output)}"
                                 ) from None

    def communicate(self, text: str = "", timeout: float = 120) -> tuple[str, None]:
        if text:
            self.type(text)
        self.process.stdin.close()
        self.process.wait(timeout=timeout)
        self.reader.join(timeout=10)
        return "".join(self.output), None

    def terminate(self) -> None:
        self.process.terminate()

    @property
    def returncode(self):
        return self.process.returncode


def tool(name: str, *args: str, env: dict) -> Tool:
    return Tool(name, *args, env=env)


def install_calibration(env: dict, kind: str, device_id: str) -> None:
    folder = Path(env["HF_LEROBOT_CALIBRATION"]) / kind
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(REPO / "calibration" / "virtual_so101.json", folder / f"{device_id}.json")


def test_setup_motors_on_factory_servos_then_the_follower_connects(env):
    arm = ShellArm("--factory")
    try:
        setup = tool("lerobot-setup-motors", "--robot.type=so101_follower",
                     f"--robot.port={arm.port}", env=env)
        out, _ = setup.communicate("\n" * 6, timeout=180)
        assert setup.returncode == 0, out
        for joint, motor_id in (("gripper", 6), ("shoulder_pan", 1)):
            assert f"'{joint}' motor id set to {motor_id}" in out
        from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig

        robot = SO101Follower(SO101FollowerConfig(port=arm.port, id="fresh"))
        robot.connect(calibrate=False)  # IDs 1..6 at 1 Mbit/s, model 777, same firmware
        assert set(robot.bus.sync_read("Present_Position", normalize=False)) == set(SHIPPED)
        robot.disconnect()
    finally:
        arm.close()


@pytest.mark.alone
def test_calibrate_from_the_shell_agrees_with_the_shipped_calibration(env):
    arm = ShellArm()
    try:
        calibrate = tool("lerobot-calibrate", "--robot.type=so101_follower",
                         f"--robot.port={arm.port}", "--robot.id=vlab", env=env)
        calibrate.wait_for("middle of its range of motion and press ENTER")
        arm("middle")
        calibrate.type("\n")
        calibrate.wait_for("Press ENTER to stop")
        arm("sweep shoulder_pan shoulder_lift elbow_flex wrist_flex gripper")
        out, _ = calibrate.communicate("\n", timeout=120)
        assert calibrate.returncode == 0, out
    finally:
        arm.close()
    written = json.loads(next(Path(env["HF_LEROBOT_CALIBRATION"]).rglob("vlab.json")).read_text())
    for joint, shipped in SHIPPED.items():
        got = written[joint]
        # the same, but for the count a real encoder reads off at times (ENCODER_NOISE) and
        # a count of quantisation; never past a joint limit by more
        assert abs(got["homing_offset"] - shipped["homing_offset"]) <= 2, joint
        assert got["range_min"] >= shipped["range_min"] - 2, joint
        assert got["range_max"] <= shipped["range_max"] + 2, joint
        assert got["range_min"] - shipped["range_min"] <= 30, joint
        assert shipped["range_max"] - got["range_max"] <= 30, joint


def teleop_args(follower: ShellArm, leader: ShellArm) -> list[str]:
    return ["--robot.type=so101_follower", f"--robot.port={follower.port}", "--robot.id=vf",
            "--teleop.type=so101_leader", f"--teleop.port={leader.port}", "--teleop.id=vl"]


def test_teleoperate_the_follower_follows_the_shell_moved_leader(env):
    """lerobot-teleoperate at 60 fps: a hand moves the leader, the follower ends where it is."""
    install_calibration(env, "robots/so_follower", "vf")
    install_calibration(env, "teleoperators/so_leader", "vl")
    follower, leader = ShellArm(*KIT_FOLLOWER), ShellArm("--leader")
    try:
        teleop = tool("lerobot-teleoperate", *teleop_args(follower, leader), "--fps=60",
                      "--display_data=false", env=env)
        teleop.wait_for("Teleop loop time")  # lerobot started and connected both arms
        before = follower.pose()
        assert leader("pose shoulder_pan=25 elbow_flex=70 wrist_flex=45").startswith("ok")
        time.sleep(1.0)  # the follower's servos catch up with the last goal
        lead, follow = leader.pose(), follower.pose()
        teleop.terminate()
        teleop.process.wait(timeout=30)
    finally:
        follower.close()
        leader.close()
    assert abs(follow["shoulder_pan"] - before["shoulder_pan"]) > 20.0  # it really moved
    # lerobot alone has no feed-forward: the follower's STS3215s at P = 16 (5 V) rest below
    # the leader by the sag gravity causes there (the model's masses over the servo's law)
    sag = feedforward(lead, LEROBOT, KIT_SUPPLY_V)
    for joint in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"):
        assert abs(lead[joint] - follow[joint]) < abs(sag[joint]) + 1.0, (
            joint, lead[joint], follow[joint], sag[joint])


@pytest.mark.alone
def test_record_a_short_episode_between_shell_started_arms(env, tmp_path):
    # lerobot 0.6 moved the dataset code into an extra (lerobot[dataset]); 0.4 has it built in
    pytest.importorskip("datasets", reason="lerobot-record needs lerobot[dataset] here")
    install_calibration(env, "robots/so_follower", "vf")
    install_calibration(env, "teleoperators/so_leader", "vl")
    # the follower serves its overhead camera, which lerobot records beside the joints through
    # its own camera class (our type so101_virtual, found by discover_packages_path)
    follower = ShellArm(*KIT_FOLLOWER, "--camera", "overhead", "--camera-fps", "30")
    leader = ShellArm("--leader")
    address = follower.cameras["overhead"]
    cameras = (f"{{overhead: {{type: so101_virtual, address: '{address}', width: 640, "
               "height: 480, fps: 30}}")
    root = tmp_path / "dataset"
    try:
        record = tool("lerobot-record", *teleop_args(follower, leader),
                      f"--robot.cameras={cameras}",
                      "--robot.discover_packages_path=lerobot_camera_so101_virtual",
                      "--dataset.repo_id=local/virtual_lab", f"--dataset.root={root}",
                      "--dataset.num_episodes=1", "--dataset.episode_time_s=6",
                      "--dataset.reset_time_s=0", "--dataset.push_to_hub=false",
                      "--dataset.single_task=rehearse", "--display_data=false",
                      "--dataset.fps=30", "--play_sounds=false", env=env)
        record.wait_for("Recording episode")
        assert leader("demo").startswith("ok")  # a hand moves the leader through the demo
        out, _ = record.communicate(timeout=240)
        assert record.returncode == 0, out[-3000:]
    finally:
        follower.close()
        leader.close()
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 1
    assert info["total_frames"] >= 150  # 6 s at 30 fps, allowing for a slow start
    # the camera's images are in the dataset: a 640x480 RGB video feature, its file written
    image = info["features"]["observation.images.overhead"]
    assert image["dtype"] == "video" and image["shape"][:2] == [480, 640], image
    videos = sorted((root / "videos").rglob("*.mp4"))
    assert videos and all(v.stat().st_size > 10_000 for v in videos), videos
    # The follower tracked the leader: median |action - observation| per joint after 1 s.
    import pandas as pd

    frames = pd.concat(pd.read_parquet(path) for path in sorted((root / "data").rglob("*.parquet")))
    frames = frames[frames["timestamp"] > 1.0]
    action = frames["action"].apply(list).tolist()
    state = frames["observation.state"].apply(list).tolist()
    errors = [statistics.median(abs(a[k] - s[k]) for a, s in zip(action, state, strict=True))
              for k in range(len(info["features"]["action"]["names"]))]
    moved = max(max(a[0] for a in action) - min(a[0] for a in action), 0.0)
    print("follower-leader error medians:",
          dict(zip(info["features"]["action"]["names"], errors, strict=True)))
    assert moved > 20.0  # the demo swung shoulder_pan
    # lerobot alone: the STS3215 at P = 16 on 5 V sags up to 5.3 deg (shoulder) and trails a
    # moving goal by about 0.1 s of its motion; a follower that did not follow is tens off
    assert max(errors) < 6.0, errors
