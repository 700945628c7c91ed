"""The servo model against two real SO-101 recordings it was not built from (issue 34).

Each recording's goals are replayed frame by frame through the simulator on the project's
default servo (``so101_kinematics/lab/replay.py``; provenance in tests/data/fidelity/); the
expected values are the recordings' own figures, measured here from their frames by the
same code that measures the replay:

- tracking RMS(goal - state) within 15 % over the arm and 25 % per joint, and the delay
  within one frame, on both recordings;
- record_test episode 0's step from rest: no overshoot beyond 0.3 deg, and the joint stops
  short of its goal as the recorded arm does (within 1 deg).

The quick tests replay record_test whole and pick_place_tape's first 10 episodes (a few
seconds); the slow one replays all 50.
"""

from __future__ import annotations

import numpy as np
import pytest

from so101_kinematics.frames import ARM_JOINTS, JOINT_LIMITS
from so101_kinematics.lab import replay

TRACKING_OVER_ARM = 0.15
TRACKING_PER_JOINT = 0.25
OVERSHOOT_DEG = 0.3
STOP_SHORT_DEG = 1.0


def _subset(recording: replay.Recording, episodes) -> replay.Recording:
    frames = np.concatenate(recording.episodes(episodes))
    return replay.Recording(recording.name, recording.action[frames], recording.state[frames],
                            recording.episode[frames], recording.fps)


@pytest.fixture(scope="module")
def record_test():
    recording = replay.load("record_test")
    return replay.figures(recording), replay.replay(recording)


def _assert_tracks_like(real: dict, model: dict) -> None:
    assert model["rms_arm"] == pytest.approx(real["rms_arm"], rel=TRACKING_OVER_ARM)
    for joint in ARM_JOINTS:
        assert model["rms"][joint] == pytest.approx(real["rms"][joint], rel=TRACKING_PER_JOINT), \
            joint
    assert abs(model["delay"] - real["delay"]) <= 1


def test_record_test_is_tracked_as_the_arm_tracked_it(record_test):
    real, simulated = record_test
    _assert_tracks_like(real, replay.figures(simulated))


def test_pick_place_tape_is_tracked_as_the_arm_tracked_it_first_10_episodes():
    recording = _subset(replay.load("pick_place_tape"), range(10))
    real = replay.figures(recording)
    _assert_tracks_like(real, replay.figures(replay.replay(recording)))


def test_the_shoulder_lags_the_pan_as_on_the_arm_first_10_episodes():
    # pick_place_tape's shoulder_lift trails its goal ~20 ms longer than shoulder_pan (the
    # issue's "shoulder lags the other joints"); the model's does too, from its larger load.
    recording = _subset(replay.load("pick_place_tape"), range(10))
    simulated = replay.replay(recording)
    real = replay.delay_ms(recording, 1) - replay.delay_ms(recording, 0)
    model = replay.delay_ms(simulated, 1) - replay.delay_ms(simulated, 0)
    assert real > 10.0 and model > 10.0
    assert model == pytest.approx(real, abs=10.0)


@pytest.mark.slow
def test_pick_place_tape_is_tracked_as_the_arm_tracked_it_all_50_episodes():
    recording = replay.load("pick_place_tape")
    _assert_tracks_like(replay.figures(recording), replay.figures(replay.replay(recording)))


def test_the_step_from_rest_does_not_overshoot_and_stops_short_as_the_arm_did(record_test):
    real, simulated = record_test
    steps = replay.step_figures(simulated)
    assert set(steps) == set(real["step"]) == {"shoulder_pan", "shoulder_lift", "elbow_flex",
                                               "wrist_flex"}
    frames = simulated.episodes([0])[0][:replay.STEP_FRAMES + 1]
    for joint, (_, overshoot, left) in steps.items():
        j = ARM_JOINTS.index(joint)
        goal, path = simulated.action[frames[0], j], simulated.state[frames, j]
        limit = JOINT_LIMITS[joint][1] if goal > path[0] else JOINT_LIMITS[joint][0]
        if abs(limit - goal) < OVERSHOOT_DEG:
            # elbow_flex: its goal (96.57 deg) is 0.26 deg from the model's limit (96.83) and
            # gravity folds it there with 0.37 N m, 2.8 deg of static sag at P 16 on 12 V;
            # the model rests on its limit. What must stay small is the swing beyond that rest.
            swing = float(np.max((path - path[-1]) * np.sign(goal - path[0])))
            assert abs(path[-1] - limit) < 0.1, joint
            assert swing <= OVERSHOOT_DEG, joint
            continue
        assert overshoot <= OVERSHOOT_DEG, joint
        _, _, real_left = real["step"][joint]
        if joint == "wrist_flex":
            # the recorded wrist stops 2.8 deg short, the model 0.3: the recorded arm's rest
            # pose lies inside the modelled table (docs/servo_model.md, "The rest pose and
            # the table"): it is stopped by its support, which the contact-free replay lacks.
            assert real_left > 2.0 and 0.0 < left < real_left
            continue
        assert left == pytest.approx(real_left, abs=STOP_SHORT_DEG), joint


def test_the_old_damping_overshot_where_the_arm_does_not(record_test, monkeypatch):
    # The D scale before the fit (one 1 ms loop period): the replay's steps overshot the goal
    # by more than 0.3 deg on two joints where the recording overshoots by at most 0.07.
    from so101_kinematics import servo

    real, _ = record_test
    monkeypatch.setattr(servo, "D_SCALE_S", servo.LOOP_PERIOD_S)
    steps = replay.step_figures(replay.replay(replay.load("record_test"), episodes=[0]))
    assert max(over for _, over, _ in real["step"].values()) < 0.1
    assert sum(steps[j][1] > OVERSHOOT_DEG for j in ("shoulder_pan", "shoulder_lift",
                                                      "wrist_flex")) >= 2


@pytest.mark.hw
@pytest.mark.slow
def test_the_virtual_arm_through_lerobots_bus_tracks_the_recording_as_the_simulator_does():
    # record_test episode 0's first 10 s, in real time through lerobot's bus: the virtual arm
    # runs the same servo model, so its figures are the recording's as the simulator's are.
    pytest.importorskip("lerobot")
    recording = replay.load("record_test")
    frames = recording.episodes([0])[0][slice(*replay.VIRTUAL_FRAMES)]
    part = _subset(recording, [0])
    part = replay.Recording(part.name, part.action[:len(frames)], part.state[:len(frames)],
                            part.episode[:len(frames)], part.fps)
    real = replay.figures(part)
    virtual = replay.figures(replay.replay_virtual(recording, frames))
    assert virtual["rms_arm"] == pytest.approx(real["rms_arm"], rel=TRACKING_OVER_ARM)
    assert abs(virtual["delay"] - real["delay"]) <= 1
    for joint in ("shoulder_pan", "shoulder_lift", "wrist_flex"):  # the elbow: see above
        assert virtual["step"][joint][1] <= OVERSHOOT_DEG, joint
