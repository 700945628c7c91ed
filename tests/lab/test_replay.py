"""The servo model against two real SO-101 recordings it was not built from (issue 34).

Each recording's goals are replayed frame by frame through the simulator on the project's
default servo (``so101_kinematics/lab/replay.py``; provenance in tests/data/fidelity/); the
expected values are the recordings' own figures, measured here from their frames by the
same code that measures the replay:

- tracking RMS(goal - state) within 15 % over the arm and 25 % per joint, and the delay
  within one frame, on both recordings;
- record_test episode 0's step from rest: no overshoot beyond 0.3 deg, and the joint stops
  short of its goal as the recorded arm does (within 1 deg), the elbow in the model's degrees
  (its stop, ``replay.estimated_offsets``);
- the recorded rests against the table: inside the model's by 16-32 mm, still inside with
  the calibration's slack or the lab's 15 mm mount, clear with the table 35 mm below the base.

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
            # In the model's degrees (--offsets estimated) the goal lies past the model's stop,
            # as the arm's lay past its own: test_with_the_estimated_offsets_every_step_...
            swing = float(np.max((path - path[-1]) * np.sign(goal - path[0])))
            assert abs(path[-1] - limit) < 0.1, joint
            assert swing <= OVERSHOOT_DEG, joint
            continue
        assert overshoot <= OVERSHOOT_DEG, joint
        _, _, real_left = real["step"][joint]
        if joint == "wrist_flex":
            # the recorded wrist stops 2.8 deg short, the model 0.3; its jaw then lies 10 mm
            # above the table the recording's deepest reading gives, so not on it: the cause is
            # open (docs/servo_model.md, "The rest pose and the table").
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
    shift = replay.estimated_offsets(recording)  # the model's degrees, as the default replay
    virtual = replay.figures(replay.replay_virtual(recording, frames, offsets=shift))
    assert virtual["rms_arm"] == pytest.approx(real["rms_arm"], rel=TRACKING_OVER_ARM)
    assert abs(virtual["delay"] - real["delay"]) <= 1
    for joint in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex"):
        assert virtual["step"][joint][1] <= OVERSHOOT_DEG, joint


# --- issue 34's last gaps: the elbow's stop and the rests inside the modelled table -----------
# The figures are the recordings' (measured with lab/replay.py on tests/data/fidelity/,
# docs/servo_model.md, "The rest pose and the table").

@pytest.fixture(scope="module")
def recordings():
    return {name: replay.load(name) for name in replay.RECORDINGS}


def test_the_elbows_offset_is_its_limit_less_its_largest_reading(recordings):
    # record_test's elbow never reads past 96.48 deg (goals to 96.92), pick_place_tape's past
    # 96.18 (goals to 96.70): their stops; the model's stop is its limit, 1.69 rad = 96.83 deg.
    assert replay.estimated_offsets(recordings["record_test"]) == {
        "elbow_flex": pytest.approx(96.83 - 96.48, abs=0.01)}
    assert replay.estimated_offsets(recordings["pick_place_tape"]) == {
        "elbow_flex": pytest.approx(96.83 - 96.18, abs=0.01)}
    # not fitted to the step it corrects: episodes 1-3 alone give the same offset
    assert replay.estimated_offsets(_subset(recordings["record_test"], [1, 2, 3])) == \
        replay.estimated_offsets(recordings["record_test"])


def test_with_the_estimated_offsets_every_step_stops_short_as_the_arm_did(recordings):
    # The recorded elbow steps to 96.57 deg and stops 0.27 short, on its stop; replayed in the
    # model's degrees (+0.35) its goal lies past the model's stop too: it rests there, within
    # 0.3 deg of the goal, short of it as the arm was, instead of folding 0.46 past it.
    recording = recordings["record_test"]
    real = replay.figures(recording)
    simulated = replay.figures(replay.replay(recording,
                                             offsets=replay.estimated_offsets(recording)))
    _assert_tracks_like(real, simulated)
    assert set(simulated["step"]) == set(real["step"])
    for joint, (_, overshoot, left) in simulated["step"].items():
        _, _, real_left = real["step"][joint]
        assert overshoot <= OVERSHOOT_DEG, joint
        if joint == "wrist_flex":  # stops 2.8 deg short, the model 0.3: see above
            assert real_left > 2.0 and 0.0 < left < real_left
            continue
        assert left == pytest.approx(real_left, abs=STOP_SHORT_DEG), joint
    assert 0.0 < simulated["step"]["elbow_flex"][2] < 0.3  # short of the goal, the arm +0.27


def test_with_the_estimated_offsets_pick_place_tape_tracks_as_before_first_10_episodes(
        recordings):
    recording = _subset(recordings["pick_place_tape"], range(10))
    offsets = replay.estimated_offsets(recordings["pick_place_tape"])
    _assert_tracks_like(replay.figures(recording),
                        replay.figures(replay.replay(recording, offsets=offsets)))


def test_the_recorded_rests_lie_16_to_32_mm_inside_the_modelled_table(recordings):
    rests = {name: replay.rest_heights(r) * 1000.0 for name, r in recordings.items()}
    assert len(rests["record_test"]) == 3  # episode 0 starts away from the rest
    assert len(rests["pick_place_tape"]) == 50
    assert rests["record_test"].min() == pytest.approx(-31.5, abs=0.3)
    assert rests["record_test"].max() == pytest.approx(-26.1, abs=0.3)
    assert rests["pick_place_tape"].min() == pytest.approx(-25.7, abs=0.3)
    assert rests["pick_place_tape"].max() == pytest.approx(-16.2, abs=0.3)


def test_neither_calibration_nor_the_lab_mount_lifts_the_rests_onto_the_table(recordings):
    for name, recording in recordings.items():
        plain = replay.rest_heights(recording)
        # the elbow's estimated offset folds it 0.35-0.65 deg more: 1-2 mm lower
        assert np.all(replay.rest_heights(recording, replay.estimated_offsets(recording))
                      < plain), name
        # the most the calibrated ranges allow (each zero within half the difference of the
        # swept range and the model's) lifts them 5-8 mm: still at least 7 mm inside
        slack = replay.calibration_slack(name)
        lifted = replay.rest_heights(recording, replay.most_lifting_offsets(recording, slack))
        assert np.all(lifted > plain), name
        assert lifted.max() < -0.007, name
        # the course's 15 mm mount: still inside, by 1-17 mm
        assert replay.rest_heights(recording, base_height=0.015).max() < 0.0, name


def test_a_table_35_mm_below_the_base_holds_every_rest(recordings):
    # The option that closes the gap: the table below the base frame by the depth the
    # recordings' deepest readings give (31.6 and 29.8 mm), with room for the boxes.
    for name, recording in recordings.items():
        assert replay.rest_heights(recording, base_height=replay.RECORDED_BASE_HEIGHT).min() \
            >= 0.003, name
    record_test = recordings["record_test"]
    every = replay.heights(record_test.state)
    assert every.min() == pytest.approx(-0.0316, abs=0.0003)  # episode 3's rest
    assert every.min() + replay.RECORDED_BASE_HEIGHT > 0.0
    # where episode 0's wrist stopped 2.8 deg short (1.2 s): 10 mm above that table's depth,
    # so not held by the table
    stopped = record_test.state[record_test.episodes([0])[0][replay.STEP_FRAMES]]
    assert replay.heights(stopped[None])[0] == pytest.approx(-0.0216, abs=0.0003)


@pytest.mark.slow
def test_pick_place_tapes_forward_reach_dips_as_deep_as_its_rests():
    # the deepest of its 14 954 readings is a pick reaching forward (shoulder_lift +30 deg),
    # not a rest: a lower table explains both poses where joint offsets would move them apart
    recording = replay.load("pick_place_tape")
    every = replay.heights(recording.state)
    k = int(np.argmin(every))
    assert every[k] == pytest.approx(-0.0298, abs=0.0003)
    assert recording.state[k, ARM_JOINTS.index("shoulder_lift")] > 20.0
    assert every.min() + replay.RECORDED_BASE_HEIGHT > 0.0


def test_a_wrong_offsets_choice_is_refused_in_one_line(capsys):
    with pytest.raises(SystemExit) as exit_:
        replay.main(["--offsets", "guess"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--offsets" in err and "estimated" in err
