"""Real SO-101 recordings replayed through the servo model: does the model track as the arms do?

Two public lerobot recordings of a follower teleoperated from a leader
(``tests/data/fidelity/``, provenance in its ``SOURCES.md``) hold, frame by frame at
30 fps, the goal lerobot wrote (``action``) and the position it read (``state``), in
degrees from the calibrated mid-range. Each episode is replayed here as lerobot's record
loop ran it: the simulated arm starts at rest at the episode's first reading; at frame k
its position is read (rounded to whole encoder counts, as the servo reports it), then
the frame's goal is written and the physics runs one frame. Contacts are off (the
recordings' tables and objects are unknown) and the gravity feed-forward too (lerobot
writes the goal as it is), so the figures are the servo's and the arm's inertia.

Figures, the same for the recording and the replay (:func:`figures`):

- tracking: RMS(goal - state) per arm joint and over the five [deg];
- delay: the shift [frames] of the goal that best matches the state (least RMS);
- the step (``record_test`` episode 0: the leader's pose held 1.2 s while the follower
  starts 12-42 deg away on four joints): per joint moved, time to 90 % [ms], overshoot
  beyond the goal [deg], and the error left at 1.2 s [deg] (positive: short of the goal).

Usage::

    python -m so101_kinematics.lab.replay [--quick] [--offsets {none,estimated}] [--virtual]

prints both recordings beside the model on the project's default servo and the
alternatives (C001 on 5 V and 7.4 V, C018 on 12 V), then where the recorded rests lie
against the table (:func:`rest_report`). The recordings are replayed in the model's degrees
where they show the difference (:func:`estimated_offsets`, ``--offsets estimated``, the
default); ``--offsets none`` takes the recording's degrees as the model's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics import clearance, servo
from so101_kinematics.cli import ArgumentParser
from so101_kinematics.frames import ARM_JOINTS, JOINT_LIMITS, JOINTS
from so101_kinematics.paths import REPO
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import load_model, set_initial_pose, to_radians

__all__ = [
    "RECORDED_BASE_HEIGHT", "Recording", "STEP_FRAMES", "VIRTUAL_FRAMES", "calibration_slack",
    "delay_ms", "estimated_offsets", "figures", "heights", "load", "most_lifting_offsets",
    "replay", "replay_virtual", "rest_heights", "rest_readings", "step_figures",
]

DATA_DIR = REPO / "tests" / "data" / "fidelity"
"""The recordings (``.npz``) and their provenance (``SOURCES.md``)."""

RECORDINGS = ("record_test", "pick_place_tape")

STEP_FRAMES = 36
"""record_test episode 0 holds the leader's pose for its first 1.2 s (36 frames at 30 fps)."""

STEP_MIN_DEG = 5.0
"""A joint counts as stepped when its goal is at least this far from its start [deg]."""

MAX_DELAY = 10
"""Largest delay searched [frames]."""

SERVOS = (("default", None, None), ("C001 5 V", 5.0, "C001"), ("C001 7.4 V", 7.4, "C001"),
          ("C001-datasheet 5 V", 5.0, "C001-datasheet"), ("C018 12 V", 12.0, "C018"))
"""(label, supply [V], variant) replayed by default; None: the project's default."""

ARM = len(ARM_JOINTS)

OFFSETS = ("none", "estimated")
"""``--offsets``: the recording's degrees taken as the model's, or shifted by
:func:`estimated_offsets`."""

STOP_JOINT = "elbow_flex"
"""The joint whose recorded readings show where its stop is (:func:`estimated_offsets`)."""

REST_FOLDED_DEG = {"shoulder_lift": -80.0, "elbow_flex": 90.0}
"""A reading is at the folded rest when shoulder_lift is at most, and elbow_flex at least,
this [deg]: both recordings' rests read -82 to -102 and 95-96 deg; record_test episode 0
starts at -72 and 66 deg, away from it (the leader already moved)."""

RECORDED_BASE_HEIGHT = 0.035
"""[m] the table below the base frame that holds every recorded reading: the model's lowest
point (``clearance.lowest_point``) over every frame of the recordings is 31.6 mm
(record_test) and 29.8 mm (pick_place_tape) below the base frame, their rests 16-32 mm
(docs/servo_model.md, "The rest pose and the table"); 35 mm leaves 3 mm of margin.
Measured from the recordings, not a stated mount: the course's lab mount is 15 mm."""


@dataclass(frozen=True)
class Recording:
    """One recording: goals and readings [deg] (gripper [0, 100]) per frame, episode index."""

    name: str
    action: np.ndarray  # (N, 6)
    state: np.ndarray  # (N, 6)
    episode: np.ndarray  # (N,)
    fps: float

    def episodes(self, chosen=None) -> list[np.ndarray]:
        """The frame indices of each episode (``chosen``: those episode numbers only)."""
        numbers = np.unique(self.episode) if chosen is None else chosen
        return [np.flatnonzero(self.episode == e) for e in numbers]


def load(name: str, directory: Path = DATA_DIR) -> Recording:
    """A recording by name (``RECORDINGS``)."""
    data = np.load(directory / f"{name}.npz")
    return Recording(name, data["action"].astype(float), data["state"].astype(float),
                     data["episode"].astype(int), float(data["fps"]))


def estimated_offsets(recording: Recording) -> dict[str, float]:
    """The model's angle minus the recording's [deg], where the recording shows it.

    lerobot counts degrees from the middle of the range swept at calibration, the model
    from the middle of its joint range (upstream ``so101_new_calib``); the two zeros differ
    by how the sweep was made, which neither recording states. One joint shows it:
    :data:`STOP_JOINT`, folded at rest, which gravity pushes further into its fold
    (0.37 N m, ``gravity.py``), reads at most a value it never passes while its goal goes
    beyond it (record_test: 96.48 deg with goals up to 96.92; pick_place_tape: 96.18 in 22 of
    its 50 episodes with goals up to 96.70). That value is its stop, which in the model is the
    joint's upper limit: the offset is the limit minus the largest reading (+0.35 and
    +0.65 deg). The other joints never read past their goals onto a stop; their calibrated
    ranges only bound their offsets (docs/servo_model.md).
    """
    j = JOINTS.index(STOP_JOINT)
    return {STOP_JOINT: JOINT_LIMITS[STOP_JOINT][1] - float(np.max(recording.state[:, j]))}


CALIBRATED_JOINTS = ("shoulder_lift", "elbow_flex", "wrist_flex")
"""The joints that lift or lower the folded arm's jaws (shoulder_pan and wrist_roll barely)."""


def calibration_slack(name: str, directory: Path = DATA_DIR) -> dict[str, float]:
    """How far [deg] each joint's calibrated zero may sit from the model's, by the ranges.

    The zero is the middle of the range swept at calibration (``range_counts``), the
    model's the middle of its joint range: if the two ranges cover the same travel, their
    middles differ by at most half the difference of their lengths.
    """
    counts = np.load(directory / f"{name}.npz")["range_counts"]
    return {j: abs(float(counts[JOINTS.index(j)]) * 360.0 / servo.COUNTS_PER_TURN
                   - (JOINT_LIMITS[j][1] - JOINT_LIMITS[j][0])) / 2.0 for j in CALIBRATED_JOINTS}


def most_lifting_offsets(recording: Recording, slack: dict[str, float]) -> dict[str, float]:
    """Of the offsets within ``slack`` (each at + or -), those that lift the lowest rest most."""
    best, chosen = -math.inf, {}
    for signs in np.ndindex(*(2,) * len(slack)):
        offsets = {j: (1.0 if s else -1.0) * v
                   for (j, v), s in zip(slack.items(), signs, strict=True)}
        lowest = float(np.min(rest_heights(recording, offsets)))
        if lowest > best:
            best, chosen = lowest, offsets
    return chosen


def rest_readings(recording: Recording) -> np.ndarray:
    """Each episode's first reading if it is at the folded rest (:data:`REST_FOLDED_DEG`)."""
    lift, elbow = JOINTS.index("shoulder_lift"), JOINTS.index("elbow_flex")
    firsts = [recording.state[i[0]] for i in recording.episodes()]
    return np.array([r for r in firsts if r[lift] <= REST_FOLDED_DEG["shoulder_lift"]
                     and r[elbow] >= REST_FOLDED_DEG["elbow_flex"]])


def rest_heights(recording: Recording, offsets: dict[str, float] | None = None,
                 base_height: float = 0.0) -> np.ndarray:
    """The model's lowest point above the table [m] at each rest (:func:`rest_readings`).

    Args:
        recording: the recording.
        offsets: joint -> the model's angle minus the recording's [deg] (None: none).
        base_height: the table this far below the base frame [m] (0: the model's table).
    """
    return heights(rest_readings(recording), offsets, base_height)


def heights(readings: np.ndarray, offsets: dict[str, float] | None = None,
            base_height: float = 0.0) -> np.ndarray:
    """The model's lowest point above the table [m] at each reading (rows of ``JOINTS``)."""
    shift = _shift(offsets)
    return np.array([clearance.lowest_point(dict(zip(JOINTS, (row + shift).tolist(),
                                                     strict=True)), base_height)[0]
                     for row in readings])


def _shift(offsets: dict[str, float] | None) -> np.ndarray:
    """The offsets (joint -> the model's angle minus the recording's [deg]) as a row of JOINTS."""
    return np.array([(offsets or {}).get(j, 0.0) for j in JOINTS])


def _clamped(row) -> dict[str, float]:
    """A frame's values as a configuration, inside the model's limits."""
    return {j: min(max(float(v), JOINT_LIMITS[j][0]), JOINT_LIMITS[j][1])
            for j, v in zip(JOINTS, row, strict=True)}


def replay(recording: Recording, volts: float | None = None, variant: str | None = None,
           episodes=None, offsets: dict[str, float] | None = None) -> Recording:
    """The recording's goals replayed in the simulator: the same frames, simulated readings.

    Args:
        recording: the recording.
        volts: the supply [V] (None: the project's default servo).
        variant: a key of ``servo.VARIANTS`` (None: what ``volts`` implies).
        episodes: the episode numbers to replay (None: all).
        offsets: joint -> the model's angle minus the recording's [deg]
            (:func:`estimated_offsets`; None: the recording's degrees are the model's).
            The goals are written and the readings returned in the recording's degrees.
    """
    shift = _shift(offsets)
    m = load_model()
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    options = {"feedforward": False}
    if volts is not None:
        options |= {"volts": volts, "variant": variant}
    actuation.use_servo(m, **options)
    d = mujoco.MjData(m)
    steps = round(1.0 / recording.fps / m.opt.timestep)
    qadr = [int(m.joint(j).qposadr[0]) for j in JOINTS]
    acts = [int(m.actuator(j).id) for j in JOINTS]
    count = 2 * math.pi / servo.COUNTS_PER_TURN
    frames = np.concatenate(recording.episodes(episodes))
    state = np.zeros((len(frames), len(JOINTS)))
    row = 0
    for indices in recording.episodes(episodes):
        mujoco.mj_resetData(m, d)
        set_initial_pose(d, _clamped(recording.state[indices[0]] + shift))
        for k in indices:
            angles = np.round((d.qpos[qadr] - np.radians(shift)) / count) * count
            state[row] = [math.degrees(a) for a in angles]
            goal = to_radians(m, _clamped(recording.action[k] + shift))
            d.ctrl[acts] = [goal[j] for j in JOINTS]
            actuation.step(m, d, steps)
            row += 1
    lower, upper = m.jnt_range[m.joint("gripper").id]
    state[:, -1] = (np.radians(state[:, -1]) - lower) / (upper - lower) * 100.0
    return Recording(recording.name, recording.action[frames], state,
                     recording.episode[frames], recording.fps)


VIRTUAL_FRAMES = (0, 300)
"""record_test episode 0's frames replayed through the virtual arm (10 s in real time)."""

def replay_virtual(recording: Recording, frames, volts: float | None = None,
                   variant: str | None = None,
                   offsets: dict[str, float] | None = None) -> Recording:
    """The recording's goals replayed in real time through the virtual arm and lerobot's bus.

    The loop is lerobot's record loop: read Present_Position, write Goal_Position, wait for
    the next frame (30 fps), on the follower's registers (``hw.bus.configure``).

    Args:
        recording: the recording.
        frames: the frame indices to replay (consecutive, one episode).
        volts: the virtual arm's supply [V] (None: the project's default).
        variant: a key of ``servo.VARIANTS`` (None: what ``volts`` implies).
        offsets: joint -> the model's angle minus the recording's [deg], as :func:`replay`'s
            (the shipped calibration's degrees are the model's).
    """
    import time

    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.bus import configure, connect, disconnect, enable_torque_in_place
    from so101_kinematics.virtual.arm import VirtualSO101
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    volts = servo.DEFAULT_SUPPLY_V if volts is None else volts
    shift = _shift(offsets)
    frames = np.asarray(frames)
    state = np.zeros((len(frames), len(JOINTS)))
    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH, supply=volts, variant=variant,
                      initial=_clamped(recording.state[frames[0]] + shift),
                      base_height=RECORDED_BASE_HEIGHT) as arm:
        bus = connect(arm.port, load_calibration(DEFAULT_CALIBRATION_PATH))
        try:
            configure(bus)
            enable_torque_in_place(bus)
            start = time.perf_counter()
            for row, k in enumerate(frames):
                read = bus.sync_read("Present_Position", num_retry=2)  # a loaded host
                state[row] = np.array([read[j] for j in JOINTS]) - shift
                bus.sync_write("Goal_Position", _clamped(recording.action[k] + shift))
                time.sleep(max(0.0, start + (row + 1) / recording.fps - time.perf_counter()))
        finally:
            disconnect(bus)
    return Recording(recording.name, recording.action[frames], state, recording.episode[frames],
                     recording.fps)


def _delay(recording: Recording, joints=slice(0, ARM)) -> int:
    """The goal's shift [frames] that best matches the readings (least RMS, all episodes)."""
    best, chosen = math.inf, 0
    for shift in range(MAX_DELAY + 1):
        errors = [recording.action[i[:len(i) - shift], joints] - recording.state[i[shift:], joints]
                  for i in recording.episodes()]
        value = float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))
        if value < best:
            best, chosen = value, shift
    return chosen


def delay_ms(recording: Recording, joint: int) -> float:
    """One joint's delay [ms], to a tenth of a frame (the shoulder's ~20 ms is below one).

    The shift of the goal (linearly interpolated) that best matches the readings, over all
    episodes.
    """
    best, chosen = math.inf, 0.0
    for shift in np.arange(0.0, MAX_DELAY + 0.01, 0.1):
        errors = []
        for frames in recording.episodes():
            t = np.arange(len(frames))
            goal = np.interp(t - shift, t, recording.action[frames, joint])
            first = math.ceil(shift)
            errors.append(goal[first:] - recording.state[frames, joint][first:])
        value = float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))
        if value < best:
            best, chosen = value, float(shift)
    return chosen * 1000.0 / recording.fps


def step_figures(recording: Recording) -> dict[str, tuple[float, float, float]]:
    """The step of episode 0: per joint moved, (time to 90 % [ms], overshoot, error left [deg])."""
    frames = recording.episodes([0])[0][:STEP_FRAMES + 1]
    out = {}
    for j, joint in enumerate(ARM_JOINTS):
        start, goal = recording.state[frames[0], j], recording.action[frames[0], j]
        if abs(goal - start) < STEP_MIN_DEG:
            continue
        sign = math.copysign(1.0, goal - start)
        progress = (recording.state[frames, j] - start) / (goal - start)
        crossed = np.flatnonzero(progress >= 0.9)
        if len(crossed) and crossed[0] > 0:
            k = crossed[0]
            fraction = (0.9 - progress[k - 1]) / (progress[k] - progress[k - 1])
            t90 = (k - 1 + fraction) / recording.fps * 1000.0
        else:
            t90 = math.nan
        overshoot = max(0.0, float(np.max(sign * (recording.state[frames, j] - goal))))
        left = float(sign * (goal - recording.state[frames[-1], j]))
        out[joint] = (t90, overshoot, left)
    return out


def figures(recording: Recording) -> dict:
    """Tracking RMS per joint and over the arm [deg], delay [frames], and the step if any."""
    error = recording.action[:, :ARM] - recording.state[:, :ARM]
    out = {"rms": dict(zip(ARM_JOINTS, np.sqrt(np.mean(error ** 2, axis=0)).tolist(),
                           strict=True)),
           "rms_arm": float(np.sqrt(np.mean(error ** 2))),
           "delay": _delay(recording),
           "delay_joint": {joint: _delay(recording, slice(j, j + 1))
                           for j, joint in enumerate(ARM_JOINTS)},
           "delay_ms": {joint: delay_ms(recording, j) for j, joint in enumerate(ARM_JOINTS)}}
    if recording.name == "record_test" and 0 in set(recording.episode.tolist()):
        out["step"] = step_figures(recording)
    return out


def _row(label: str, result: dict, real: dict | None) -> list[str]:
    ratio = f" (x{result['rms_arm'] / real['rms_arm']:.2f})" if real else ""
    lines = [f"  {label:22s} RMS arm {result['rms_arm']:5.2f} deg{ratio}   delay "
             f"{result['delay']} frames (per joint "
             + " ".join(str(v) for v in result["delay_joint"].values()) + "; ms "
             + " ".join(f"{v:.0f}" for v in result["delay_ms"].values()) + ")",
             "  " + " " * 22 + " RMS per joint "
             + " ".join(f"{v:5.2f}" for v in result["rms"].values())]
    for joint, (t90, over, left) in result.get("step", {}).items():
        lines.append(f"  {'':22s} step {joint:13s} t90 {t90:5.0f} ms  overshoot {over:4.2f} deg  "
                     f"left at 1.2 s {left:+5.2f} deg")
    return lines


def report(names=RECORDINGS, servos=SERVOS, episodes=None, offsets: str = "estimated") -> str:
    """The table: each recording's own figures, then the model's on each servo.

    ``offsets``: one of :data:`OFFSETS` (``estimated``: :func:`estimated_offsets` of the
    whole recording).
    """
    lines = []
    for name in names:
        recording = load(name)
        shift = estimated_offsets(recording) if offsets == "estimated" else None
        chosen = episodes if name != "record_test" else None
        if chosen is not None:
            frames = np.concatenate(recording.episodes(chosen))
            recording = Recording(name, recording.action[frames], recording.state[frames],
                                  recording.episode[frames], recording.fps)
        real = figures(recording)
        lines.append(f"{name}: {len(np.unique(recording.episode))} episodes, "
                     f"{len(recording.episode)} frames (joints: {' '.join(ARM_JOINTS)}), "
                     + ("the recording's degrees as the model's" if shift is None else
                        "model = recording + " + ", ".join(f"{j} {v:+.2f} deg"
                                                            for j, v in shift.items())))
        lines += _row("recording", real, None)
        for label, volts, variant in servos:
            if volts is None:
                spec = actuation.use_servo(load_model())
                label = f"default ({spec.variant} {spec.volts:g} V)"
            lines += _row(label, figures(replay(recording, volts, variant, offsets=shift)),
                          real)
    return "\n".join(lines)


def rest_report(names=RECORDINGS) -> str:
    """The rests against the table: the model's lowest point at each recorded rest [mm]."""
    lines = []
    for name in names:
        recording = load(name)
        shift = estimated_offsets(recording)
        every = heights(recording.state) * 1000.0
        k = int(np.argmin(every))
        lines.append(f"  {name}: calibration's slack " + ", ".join(
            f"{j} {v:.2f}" for j, v in calibration_slack(name).items()) + " deg; every "
            f"reading: deepest {every[k]:+.1f} mm (episode {recording.episode[k]}, "
            + " ".join(f"{v:.0f}" for v in recording.state[k, :ARM]) + " deg), "
            f"{np.mean(every < 0) * 100:.0f} % of the frames inside the model's table")
        for label, rest in (
                ("the model's table", rest_heights(recording)),
                ("estimated offsets", rest_heights(recording, shift)),
                ("calibration's most lifting",
                 rest_heights(recording, most_lifting_offsets(recording,
                                                              calibration_slack(name)))),
                ("the lab's 15 mm mount", rest_heights(recording, base_height=0.015)),
                (f"a table {RECORDED_BASE_HEIGHT * 1000:g} mm below the base",
                 rest_heights(recording, base_height=RECORDED_BASE_HEIGHT))):
            mm = rest * 1000.0
            lines.append(f"  {name:16s} {len(mm):2d} rests, {label:28s} lowest point "
                         f"{mm.min():+6.1f} .. {mm.max():+6.1f} mm (median {np.median(mm):+.1f}), "
                         f"{int(np.sum(mm < 0))} inside the table")
    return "\n".join(lines)


def main(argv=None) -> int:
    """``python -m so101_kinematics.lab.replay``: print the table."""
    parser = ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true",
                        help="pick_place_tape's first 10 episodes only (record_test whole)")
    parser.add_argument("--virtual", action="store_true",
                        help="also replay record_test episode 0's first 10 s through the "
                        "virtual arm and lerobot's bus (real time; needs the hw extra)")
    parser.add_argument("--offsets", choices=OFFSETS, default="estimated",
                        help="estimated (default): shift the recording's degrees onto the "
                        "model's where the recording shows the difference (elbow_flex's "
                        "stop); none: take them as the model's")
    args = parser.parse_args(argv)
    print(f"Servo model: lerobot's P {servo.LEROBOT.p} / I {servo.LEROBOT.i} / "
          f"D {servo.LEROBOT.d}, contacts off, no feed-forward.")
    print(report(episodes=range(10) if args.quick else None, offsets=args.offsets))
    print("The recorded rests against the table (the model's lowest point; negative: inside):")
    print(rest_report())
    if args.virtual:
        recording = load("record_test")
        frames = recording.episodes([0])[0][slice(*VIRTUAL_FRAMES)]
        part = Recording(recording.name, recording.action[frames], recording.state[frames],
                         recording.episode[frames], recording.fps)
        print(f"record_test episode 0, frames {VIRTUAL_FRAMES[0]}-{VIRTUAL_FRAMES[1]}: the "
              f"simulator and the virtual arm through lerobot's bus (its base "
              f"{RECORDED_BASE_HEIGHT * 1000:g} mm above its table, contacts on)")
        lines = _row("recording", figures(part), None)
        shift = estimated_offsets(recording) if args.offsets == "estimated" else None
        lines += _row("simulator", figures(replay(part, offsets=shift)), figures(part))
        lines += _row("virtual arm (bus)",
                      figures(replay_virtual(recording, frames, offsets=shift)), figures(part))
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
