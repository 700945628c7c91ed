"""The tag follower on the virtual arm: its wrist camera through lerobot, its servos on the bus.

``follow_tag.py --port PORT --camera ADDRESS`` (``lab/follow_tag_arm.py``): the virtual arm
serves its wrist camera with the target tag on the table (``virtual/camera_server.py``), the
tag is moved and hidden through the arm's commands as a hand would, and the truth is the
servos' own read-back: the FK of the joints each control cycle read, the wrist camera's
mount from the model, where its optical axis meets the table, against where the tag was put.

The tolerances, by hand:
- following a tag sliding at 3 cm/s: the follower acts on frames about 0.1 s old (the
  stream's 40 ms, a frame's wait at 20 frames/s, the detection, a cycle's move), so its
  axis trails by up to 3 cm/s x 0.1 s = 3 mm, more as the tag starts (the velocity it feeds
  forward is smoothed over a few frames): 8 mm worst while sliding;
- settled: the tag's position from a 640x480 frame within 1 mm (the virtual arm's frames:
  0.06 to 0.63 mm, ``docs/final_project.md``) and the servo's one tick (360/4096 deg) at
  the wrist camera's 0.35 m from the shoulder: 0.5 mm; the loop's gain of 6/s closes 95 % of
  a step in 0.5 s, after the frames' 0.1 s: settled within 3 mm in 1 s of the tag's stop,
  that is 20 of the follower's frames (about 20 a second here; fewer stretch it), judged
  on the median of 5 cycles in a row, and no cycle after it more than 5 mm off;
- holding: the servos keep their last goal, so the joints stay within their read-back's
  jitter: a reading a count off either way (an STS3215 at rest reads a count or two apart
  from one read to the next, ``virtual/sensor_registers.py``), and the servo's own loop,
  reading the same encoder, hunting a count either way: 4 counts peak to peak, 0.35 deg.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("cv2")
pytestmark = [pytest.mark.hw, pytest.mark.vision]

import follow_tag  # noqa: E402
from so101_kinematics.calibration import load_calibration  # noqa: E402
from so101_kinematics.fast_fk import forward_kinematics  # noqa: E402
from so101_kinematics.frames import ARM_JOINTS  # noqa: E402
from so101_kinematics.hw.run import ending  # noqa: E402
from so101_kinematics.ik.geometry import PAN_AXIS_POINT  # noqa: E402
from so101_kinematics.lab.follow_tag_arm import FOLLOW_STEP, follow_on_arm, wrist_view  # noqa: E402
from so101_kinematics.servo import COUNTS_PER_TURN  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH  # noqa: E402

START = (0.24, 0.0)  # [m] where the follower first looks (lab/follow_tag_arm.LOOK_AT)
SPEED = 0.03  # [m/s] a hand sliding the tag
JITTER_DEG = 4 * 360.0 / (COUNTS_PER_TURN - 1)  # 4 counts (the doc), lerobot's 0..4095 a turn


def axis_on_table(measured, g_tc) -> np.ndarray:
    """(x, y) [m] where the wrist camera's optical axis meets the table, from read-back joints."""
    position, rotation = forward_kinematics({j: measured[j] for j in ARM_JOINTS})
    g_bt = np.eye(4)
    g_bt[:3, :3], g_bt[:3, 3] = rotation, position
    g_bc = g_bt @ g_tc
    axis = g_bc[:3, 2]
    return (g_bc[:3, 3] + axis * -g_bc[2, 3] / axis[2])[:2]


class Watch:
    """Every following cycle's read-back, stamped; an action once the following has begun."""

    def __init__(self, action, after: float = 1.0):
        self.action, self.after = action, after
        self.cycles: list[tuple[float, dict, dict]] = []  # (perf_counter, measured, command)
        self.began: float | None = None

    def __call__(self, session, cycle) -> None:
        if cycle.step != FOLLOW_STEP or cycle.measured is None:
            return
        now = time.perf_counter()
        self.cycles.append((now, dict(cycle.measured), dict(cycle.command)))
        if self.began is None:
            self.began = now
            threading.Thread(target=self._act, daemon=True).start()

    def _act(self) -> None:
        time.sleep(self.after)
        self.action()


def follow(arm, seconds: float, watch: Watch) -> tuple[dict, object]:
    return follow_on_arm(arm.port, arm.camera_addresses["wrist"],
                         load_calibration(DEFAULT_CALIBRATION_PATH), seconds, on_cycle=watch)


@pytest.mark.slow
def test_the_arm_follows_a_sliding_tag_and_settles_where_it_stops():
    _, _, g_tc = wrist_view()
    path: list[tuple[float, float, float]] = []  # (perf_counter, x, y) of the tag

    def slide(arm):
        def run():
            t0 = time.perf_counter()
            path.append((t0, *START))
            while (t := time.perf_counter() - t0) < 1.5:  # 4.5 cm along y at 3 cm/s
                arm.place_target(START[0], SPEED * t, 0.0)
                path.append((time.perf_counter(), START[0], SPEED * t))
                time.sleep(0.02)
            arm.place_target(START[0], SPEED * 1.5, 0.0)
            path.append((time.perf_counter(), START[0], SPEED * 1.5))
        return run

    with VirtualSO101(target=(*START, 0.0), cameras=["wrist"]) as arm:
        watch = Watch(lambda: slide(arm)())
        report, result = follow(arm, 5.0, watch)
    assert result.aborted is None and result.torque_released, result.aborted
    # a frame that comes more than FOLLOW_POSE_AGE late is held (no motion on an old sighting):
    # a loaded host's camera does that now and then
    assert report["refused_frames"] == 0 and report["held_frames"] <= 0.1 * report["frames"]
    times = np.array([p[0] for p in path])
    misses = []
    for now, measured, _ in watch.cycles:
        k = max(0, int(np.searchsorted(times, now)) - 1)
        misses.append((now - path[0][0], 1000 * float(np.linalg.norm(
            axis_on_table(measured, g_tc) - np.array(path[k][1:])))))
    sliding = [m for t, m in misses if 0.3 <= t <= 1.5]
    stopped = [(t, m) for t, m in misses if t > 1.5]
    print(f"sliding at 3 cm/s: mean {np.mean(sliding):.1f} mm, worst {max(sliding):.1f} mm")
    assert max(sliding) <= 8.0
    # settled: from when the median of every 5 cycles in a row (70 ms) stays within 3 mm; the
    # settled servos hunt a tick or two (0.1-0.2 mm at the joints, up to 2.7 mm at the axis's
    # 0.3 m), so one cycle past 3 mm is not a move (CI's slow leg saw the last at 2.35 s)
    window = np.array([np.median([m for _, m in stopped[k:k + 5]])
                       for k in range(len(stopped) - 4)])
    late = np.flatnonzero(window > 3.0)
    settle = 0.0 if late.size == 0 else stopped[late[-1] + 4][0] - 1.5
    after = [m for t, m in stopped if t > 1.5 + settle]
    # 1 s is 20 of the follower's frames (about 20 a second here); a loaded host that gives it
    # fewer frames stretches that, and each of those frames closes more (6/s x its time)
    allowed = 20 / min(report["frame_rate"], 20.0)
    print(f"settled within 3 mm {settle:.2f} s after the tag stopped ({allowed:.2f} s allowed: "
          f"{report['frame_rate']} frames/s); then mean {np.mean(after):.1f} mm, "
          f"worst {max(after):.1f} mm")
    assert settle <= allowed and max(after) <= 5.0
    # the gripper went along: it turned about the pan axis as the tag did (its camera looks out
    # along the arm's plane), within the settled 3 mm at the tag's 20 cm from the axis
    def bearing(xy):
        return math.degrees(math.atan2(xy[1] - PAN_AXIS_POINT[1], xy[0] - PAN_AXIS_POINT[0]))

    first, last = (forward_kinematics({j: c[1][j] for j in ARM_JOINTS})[0] for c in
                   (watch.cycles[0], watch.cycles[-1]))
    turned, wanted = bearing(last) - bearing(first), bearing(path[-1][1:]) - bearing(START)
    print(f"the gripper turned {turned:.2f} deg about the pan axis, the tag {wanted:.2f} deg")
    assert turned == pytest.approx(wanted, abs=math.degrees(0.003 / 0.20))


@pytest.mark.slow
def test_a_hidden_tag_leaves_the_arm_holding_torqued_where_it_was():
    hidden: list[float] = []

    with VirtualSO101(target=(*START, 0.0), cameras=["wrist"]) as arm:
        def hide():
            arm.hide_target()
            hidden.append(time.perf_counter())
            time.sleep(1.0)
            hidden.append(arm.torque_enabled())

        watch = Watch(hide, after=0.5)
        report, result = follow(arm, 3.5, watch)
    assert result.aborted is None, result.aborted
    assert report["held_frames"] >= 5 and report["refused_frames"] == 0, report
    assert all(hidden[1].values()), f"torque released while holding: {hidden[1]}"
    # from the last sighting's age (0.2 s), the last move and its settling (0.3 s) on, nothing
    # commanded moved, and the servos' read-back stayed within their jitter
    held = [(m, c) for t, m, c in watch.cycles if t > hidden[0] + 0.7]
    assert len(held) >= 30
    for joint in ARM_JOINTS:
        commands = [c[joint] for _, c in held]
        readings = [m[joint] for m, _ in held]
        assert max(commands) - min(commands) == 0.0, joint
        assert max(readings) - min(readings) <= JITTER_DEG + 1e-9, joint
    assert ending(result, "R") == "Done: back at the starting pose, torque off."


@pytest.mark.slow
def test_a_tag_out_of_reach_is_refused_and_the_arm_holds():
    # [m] 14 cm from the pan axis, nearer than the follower's 16 cm (the camera would have to
    # fold back past the wrist's range), still in view: at the top of the image
    out = (0.18, 0.0)
    moved = []

    with VirtualSO101(target=(*START, 0.0), cameras=["wrist"]) as arm:
        watch = Watch(lambda: (arm.place_target(*out, 0.0), moved.append(time.perf_counter())),
                      after=0.5)
        report, result = follow(arm, 3.0, watch)
    assert result.aborted is None, result.aborted
    # refused, not held: a frame that came more than FOLLOW_POSE_AGE late is held instead (no
    # motion either); CI's loaded quick tier gave the camera 8 frames/s and one such frame
    assert report["refused_frames"] >= 5, report
    assert report["held_frames"] < report["refused_frames"] / 4, report
    assert "shoulder_pan axis" in report["refused"] and "holds" in report["refused"]
    assert math.hypot(*(np.array(out) - PAN_AXIS_POINT[:2])) < report["reach_m"][0]
    held = [c for t, _, c in watch.cycles if t > moved[0] + 0.4]
    assert len(held) >= 30
    for joint in ARM_JOINTS:
        assert max(c[joint] for c in held) - min(c[joint] for c in held) == 0.0, joint


@pytest.mark.parametrize(("argv", "says"), [
    (["--camera-calibration", "wrist.json"], "--port PORT --camera ADDRESS"),
    (["--seconds", "5"], "--duration"),
    (["--port", "/dev/null"], "Fix: give both"),
    (["--camera", "http://x/wrist.mjpg"], "Fix: give both"),
    (["--port", "/dev/null", "--camera", "0", "--hide", "1", "2"], "--hide is the simulator's"),
])
def test_options_that_do_not_go_together_are_one_line_and_exit_2(argv, says, capsys):
    assert follow_tag.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err, err


@pytest.mark.slow
def test_ctrl_c_while_following_ends_as_every_run_back_at_the_start_and_released(capsys):
    import os
    import signal

    with VirtualSO101(target=(*START, 0.0), cameras=["wrist"]) as arm:
        # the look step takes about 5 s (the camera, the reach, the move): by 8 s it follows
        timer = threading.Timer(8.0, os.kill, (os.getpid(), signal.SIGINT))
        timer.start()
        t0 = time.perf_counter()
        try:
            code = follow_tag.main(["--port", arm.port, "--camera", arm.camera_addresses["wrist"],
                                    "--seconds", "30"])
        finally:
            timer.cancel()
        took = time.perf_counter() - t0
        torque = arm.torque_enabled()
    err = capsys.readouterr().err
    assert code == 1 and took < 20.0, err
    assert "Stopping (Ctrl-C)" in err
    assert err.strip().splitlines()[-1] == "Back at the starting pose, torque off."
    assert not any(torque.values()), torque


def test_the_target_tag_moves_only_on_an_arm_that_draws_it():
    with VirtualSO101() as arm, pytest.raises(ValueError) as error:
        arm.place_target(0.24, 0.02)
    message = str(error.value)
    assert "\n" not in message and "Fix: start it with --camera NAME --target X Y" in message
