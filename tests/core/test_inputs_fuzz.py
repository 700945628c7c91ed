"""Property-based fuzzing of the inputs (hypothesis): plan files, command lines, FK and IK.

Every generated input ends in a correct result or in the project's error (exit
2 and one line naming what is wrong for a script); never a traceback, never a
changed input file. Seeded (``derandomize``) with bounded example counts.
"""

from __future__ import annotations

import contextlib
import io
import json
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import pick_place_sim
import so101_forward_kinematics as fk
import so101_inverse_kinematics as ik
import test_fk_mujoco
from so101_forward_kinematics import ARM_JOINTS, JOINTS
from so101_kinematics.errors import OutputPathError, PlanError
from so101_kinematics.frames import JOINT_LIMITS
from so101_kinematics.ik.geometry import MIN_HEIGHT
from so101_kinematics.inputs import MAX_DURATION
from so101_kinematics.planning.plans import STARTING_CONFIGURATION, load_plan

FUZZ = settings(derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
LIMITS = pick_place_sim.scene_limits()

# --- values ------------------------------------------------------------------------------
nasty_numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.sampled_from([0, -0.0, 1e-300, 5e-324, 1e9, 1e308, 10**400, -(10**400)]),
)
nasty_values = st.one_of(
    nasty_numbers, st.text(max_size=8), st.booleans(), st.none(),
    st.lists(st.integers(), max_size=2), st.dictionaries(st.text(max_size=3), st.integers(),
                                                         max_size=1))


def in_limits(joint):
    low, high = LIMITS[joint]
    return st.floats(min_value=low, max_value=high)


valid_configuration = st.fixed_dictionaries({joint: in_limits(joint) for joint in JOINTS})
any_configuration = st.dictionaries(
    st.one_of(st.sampled_from(JOINTS), st.sampled_from(["wrist_rol", "elbow", ""])),
    st.one_of(st.floats(-200, 200), nasty_values), max_size=7)
valid_step = st.fixed_dictionaries(
    {"name": st.text(min_size=1, max_size=6), "configuration": valid_configuration},
    optional={"duration": st.floats(0.0, 0.3), "hold": st.floats(0.0, 0.2)})
broken_step = st.one_of(
    st.fixed_dictionaries({"configuration": any_configuration},
                          optional={"name": nasty_values, "duration": nasty_values,
                                    "hold": nasty_values, "speed": nasty_values}),
    nasty_values)
plans = st.fixed_dictionaries(
    {"steps": st.one_of(st.lists(valid_step, min_size=1, max_size=3),
                        st.lists(st.one_of(valid_step, broken_step), max_size=3), nasty_values)},
    optional={"return_to_start": st.one_of(st.booleans(), nasty_values),
              "return_duration": st.one_of(st.floats(0.0, 0.3), nasty_values),
              "extra": nasty_values})
valid_plans = st.fixed_dictionaries(
    {"steps": st.lists(valid_step, min_size=1, max_size=3, unique_by=lambda step: step["name"])},
    optional={"return_to_start": st.booleans(), "return_duration": st.floats(0.0, 0.3)})
encodings = st.sampled_from(["utf-8", "utf-8-sig", "utf-16", "latin-1", "garbage", "truncated"])


def encode(text: str, encoding: str, noise: bytes) -> bytes:
    if encoding == "garbage":
        return noise
    if encoding == "truncated":
        return text.encode("utf-8")[: max(1, len(text) // 2)]
    return text.encode(encoding, errors="replace")


def check_plan_error(error: PlanError, path: Path) -> None:
    message = str(error)
    assert "\n" not in message, message
    assert str(path) in message, message  # the file named; the field follows in the message


@pytest.mark.slow
@settings(FUZZ, max_examples=300)
@given(plan=st.one_of(valid_plans, plans), encoding=encodings, noise=st.binary(max_size=40),
       nan_literal=st.booleans())
def test_plan_files_load_or_name_the_problem(plan, encoding, noise, nan_literal):
    text = json.dumps(plan, allow_nan=True)  # NaN and Infinity literals, as Python writes them
    if nan_literal:
        text = text.replace("0.0", "NaN", 1)
    content = encode(text, encoding, noise)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "plan.json"
        path.write_bytes(content)
        try:
            loaded = load_plan(path, LIMITS)
        except PlanError as error:
            event("refused")
            check_plan_error(error, path)
        else:
            event("loaded")
            for step in loaded.steps:
                assert 0.0 <= step.duration <= MAX_DURATION and 0.0 <= step.hold <= MAX_DURATION
                for joint, value in step.configuration.items():
                    assert LIMITS[joint][0] <= value <= LIMITS[joint][1]
            assert isinstance(loaded.return_to_start, bool)
            assert 0.0 <= loaded.return_duration <= MAX_DURATION
        assert path.read_bytes() == content



def test_a_waypoint_name_with_a_line_break_is_refused_on_one_line(tmp_path):
    # Found by the fuzz test above: the name was echoed into a two-line error.
    path = tmp_path / "plan.json"
    path.write_text(json.dumps({"steps": [{"name": "up\n", "configuration": dict.fromkeys(
        LIMITS, 0.0)}]}))
    with pytest.raises(PlanError, match=r"the name 'up\\n' holds a line break") as error:
        load_plan(path, LIMITS)
    check_plan_error(error.value, path)


# --- pick_place_sim.py -------------------------------------------------------------------
def run_main(main, argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def check_refusal(code, err, argv) -> None:
    assert code == 2, (argv, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, (argv, err)
    # The line names what is wrong: an option of the command line, or one of its values.
    assert any(token.split("=")[0] in lines[0] for token in argv if token.strip()) or \
        "the following arguments" in lines[0], (argv, lines[0])


number_text = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**30), 10**30).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e400", "x", "", "1e9", "0", "-0.1", "0.013",
                     "30", "250", "251", "1_0", " 5"]),
    st.text(max_size=5))
option_values = {
    "--fps": st.lists(number_text, min_size=1, max_size=1),
    "--size": st.one_of(st.tuples(st.integers(-20, 20000), st.integers(-20, 20000)).map(
        lambda wh: [f"{wh[0]}x{wh[1]}"]), st.lists(st.text(max_size=8), min_size=1, max_size=1)),
    "--cube-offset": st.lists(number_text, min_size=0, max_size=3),
    "--cube-turn": st.lists(number_text, min_size=1, max_size=1),
    "--move-duration": st.lists(number_text, min_size=1, max_size=1),
    "--hold": st.lists(number_text, min_size=1, max_size=1),
    "--pick": st.lists(number_text, min_size=2, max_size=3),
    "--place": st.lists(number_text, min_size=3, max_size=3),
    "--cube-yaw": st.lists(number_text, min_size=1, max_size=1),
    "--lift-height": st.lists(number_text, min_size=1, max_size=1),
    "--stack": st.lists(number_text, min_size=1, max_size=2),
    "--blocks": st.lists(st.sampled_from(["0", "1", "2", "3", "5", "-1", "x", "2.5"]),
                         min_size=1, max_size=1),
    "--block": st.lists(number_text, min_size=1, max_size=4),
    "--base-height": st.lists(number_text, min_size=1, max_size=1),
    "--camera": st.sampled_from([["pick_place"], ["nope"], [""]]),
    "--quality": st.sampled_from([["fast"], ["best"]]),
    "--json": st.sampled_from([["OUT/report.json"], ["OUT"], ["PLAN"], ["OUT/a\0b"]]),
    "--record": st.sampled_from([["OUT/v.mp4"], ["OUT/v.avi"], ["OUT"], ["PLAN"]]),
    "--plan": st.sampled_from([["PLAN"], ["OUT/missing.json"], ["OUT"]]),
    "--no-cube": st.just([]), "--strict": st.just([]), "--bogus": st.just([]),
}
sim_arguments = st.lists(
    st.sampled_from(sorted(option_values)).flatmap(
        lambda option: option_values[option].map(lambda values: [option, *values])),
    max_size=4).map(lambda groups: [token for group in groups for token in group])


class Ran(BaseException):
    """The stub runner was reached with checked values."""


def fake_stack(stack, *, mode, video, fps, size, camera, quality, progress, show_ui=False,
               servo=None):
    # A stack reaches the runner only checked: 1 to 4 blocks, each level reachable, the table
    # 0 to 5 cm below the base.
    assert 1 <= len(stack.blocks) <= 4 and 0.0 <= stack.base_height <= 0.05
    raise Ran


def fake_run(plan, *, cube, mode, video, fps, size, camera, quality, progress, timestep=None,
             show_ui=False, base_height=0.0, servo=None):
    # Reached only with values inside their documented ranges.
    assert 1.0 <= fps <= 250.0 and all(16 <= v <= 4096 and v % 2 == 0 for v in size)
    assert 0.0 <= base_height <= 0.05
    for step in plan.steps:
        assert 0.0 <= step.duration <= MAX_DURATION
    if cube is not None:
        assert all(abs(v) <= 0.1 for v in cube.offset) and -180.0 <= cube.yaw <= 180.0
    raise Ran


SHORT_PLAN = json.dumps({"steps": [{"name": "up", "configuration": dict(
    STARTING_CONFIGURATION, shoulder_lift=0.0), "duration": 0.1, "hold": 0.0}],
    "return_to_start": False})


@pytest.mark.slow
@settings(FUZZ, max_examples=250)
@given(argv=sim_arguments)
def test_simulator_command_lines_run_or_name_the_problem(argv):
    with tempfile.TemporaryDirectory() as folder:
        plan = Path(folder) / "plan.json"
        plan.write_text(SHORT_PLAN)
        argv = ["--headless", "--no-progress"] + [
            token.replace("OUT", f"{folder}/out").replace("PLAN", str(plan)) for token in argv]
        with mock.patch.object(pick_place_sim, "run_pick_place", fake_run), \
                mock.patch.object(pick_place_sim, "run_stack", fake_stack):
            try:
                code, _, err = run_main(pick_place_sim.main, argv)
            except Ran:
                event("ran")
            else:
                event(f"exit {code}")
                if code != 0:  # 0: --help
                    check_refusal(code, err, argv)
        assert plan.read_text() == SHORT_PLAN
        assert not (Path(folder) / "out" / "report.json").exists()


@settings(FUZZ, max_examples=12)
@given(plan=st.one_of(valid_plans, plans))
def test_simulated_runs_of_fuzzed_plans_finish_or_refuse(plan):
    # Real headless runs (durations of at most 0.3 s per waypoint when valid).
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "plan.json"
        text = json.dumps(plan)
        path.write_text(text)
        argv = ["--headless", "--no-cube", "--plan", str(path), "--json", f"{folder}/r.json"]
        code, _, err = run_main(pick_place_sim.main, argv)
        event(f"exit {code}")
        if code == 0:
            report = json.loads(Path(f"{folder}/r.json").read_text())
            assert report["completed"]
        else:
            check_refusal(code, err, argv)
            assert not Path(f"{folder}/r.json").exists()
        assert path.read_text() == text


# --- test_fk_mujoco.py -------------------------------------------------------------------
fk_option_values = {
    "--seconds": st.one_of(st.lists(number_text, min_size=1, max_size=1),
                           st.floats(0.0, 0.05).map(lambda v: [repr(v)])),
    "--screenshot": st.sampled_from([["OUT/s.png"], ["OUT/s.jpg"], ["OUT"], ["MODEL"]]),
    "--frames": st.sampled_from([[], ["OUT/f.png"], ["OUT"], ["OUT/f.txt"]]),
    "--table": st.sampled_from([[], ["-"], ["OUT/t.md"], ["OUT"], ["MODEL"]]),
    "--headless": st.just([]), "--bogus": st.just([]),
}
fk_arguments = st.lists(
    st.sampled_from(sorted(fk_option_values)).flatmap(
        lambda option: fk_option_values[option].map(lambda values: [option, *values])),
    max_size=3).map(lambda groups: [token for group in groups for token in group])


def small_frames_picture(path, *args, **kwargs):
    from so101_kinematics.outputs import write_text_atomic

    return write_text_atomic(path, "a stand-in for the 1200x900 picture")


@pytest.mark.slow
@settings(FUZZ, max_examples=40)
@given(argv=fk_arguments)
def test_fk_script_command_lines_run_or_name_the_problem(argv):
    scene = test_fk_mujoco.SCENE_PATH
    before = scene.read_bytes()
    with tempfile.TemporaryDirectory() as folder:
        argv = ["--headless"] + [token.replace("OUT", f"{folder}/out").replace("MODEL", str(scene))
                                 for token in argv]
        patches = [mock.patch.object(test_fk_mujoco, name, Path(folder) / "default" / file)
                   for name, file in (("DEFAULT_SCREENSHOT", "s.png"), ("FRAMES_PATH", "f.png"),
                                      ("TABLE_PATH", "t.md"))]
        patches.append(mock.patch.object(test_fk_mujoco, "render_frames", small_frames_picture))
        with contextlib.ExitStack() as stack:
            for patch in patches:
                stack.enter_context(patch)
            code, _, err = run_main(test_fk_mujoco.main, argv)
        event(f"exit {code}")
        if code != 0:
            check_refusal(code, err, argv)
    assert scene.read_bytes() == before


# --- FK and IK ---------------------------------------------------------------------------
reachable_positions = st.fixed_dictionaries(
    {joint: in_limits(joint) for joint in ARM_JOINTS}).map(
    lambda cfg: tuple(float(v) for v in fk.get_forward_kinematics(cfg)[0]))
angle_values = st.one_of(st.floats(-400.0, 400.0), nasty_values)


def is_angle(value) -> bool:
    """The FK's documented input: a real number (not a boolean) in [-360, 360] deg."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return -360.0 <= float(value) <= 360.0
    except OverflowError:
        return False


@settings(FUZZ, max_examples=400)
@given(cfg=st.one_of(
    st.fixed_dictionaries({joint: st.floats(-360.0, 360.0) for joint in ARM_JOINTS}),
    st.fixed_dictionaries({joint: angle_values for joint in ARM_JOINTS})))
def test_fk_gives_a_pose_or_a_project_error(cfg):
    numbers_in_range = all(is_angle(v) for v in cfg.values())
    try:
        position, rotation = fk.get_forward_kinematics(cfg)
    except fk.KinematicsInputError as error:
        event("refused")
        assert not numbers_in_range, cfg
        assert "\n" not in str(error)
        assert any(joint in str(error) for joint in ARM_JOINTS), str(error)
    else:
        assert numbers_in_range, cfg
        assert np.isfinite(position).all()
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)


@settings(FUZZ, max_examples=150)
@given(cfg=st.fixed_dictionaries({joint: in_limits(joint) for joint in ARM_JOINTS}))
def test_fk_then_position_ik_round_trips(cfg):
    position, _ = fk.get_forward_kinematics(cfg)
    if position[2] < MIN_HEIGHT:
        with pytest.raises(ik.UnreachableError, match="below"):
            ik.get_inverse_kinematics(position, approach=None)
        return
    solved = ik.get_inverse_kinematics(position, approach=None, initial=cfg)
    back, _ = fk.get_forward_kinematics(solved)
    np.testing.assert_allclose(back, position, atol=1e-9)
    for joint in ARM_JOINTS:
        assert JOINT_LIMITS[joint][0] - 1e-9 <= solved[joint] <= JOINT_LIMITS[joint][1] + 1e-9


@settings(FUZZ, max_examples=300)
@given(call=st.one_of(
    # Well-formed: a reachable position, any of the approaches that need no more.
    st.tuples(reachable_positions, st.sampled_from([None, "down"]), st.none(), st.none(),
              st.one_of(st.none(), st.floats(0.0, 100.0))),
    st.tuples(st.one_of(reachable_positions,
                        st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5),
                                  st.floats(-0.1, 0.5)),
                        st.tuples(angle_values, angle_values, angle_values), nasty_values),
              st.sampled_from([None, "down", "pitch", "sideways"]),
              st.one_of(st.none(), st.floats(-180.0, 180.0), angle_values),
              st.one_of(st.none(), st.floats(-90.0, 90.0), angle_values),
              st.one_of(st.none(), st.floats(0.0, 100.0), angle_values))))
def test_ik_gives_a_configuration_or_a_project_error(call):
    position, approach, yaw, pitch, gripper = call
    try:
        cfg = ik.get_inverse_kinematics(position, approach=approach, yaw_deg=yaw, pitch_deg=pitch,
                                        gripper=gripper)
    except (fk.KinematicsInputError, PlanError) as error:  # PlanError: UnreachableError
        event(type(error).__name__)
        assert "\n" not in str(error)
    else:
        event("solved")
        for joint in ARM_JOINTS:
            low, high = JOINT_LIMITS[joint]
            assert low - 1e-9 <= cfg[joint] <= high + 1e-9
        assert 0.0 <= cfg["gripper"] <= 100.0
        back, _ = fk.get_forward_kinematics(cfg)
        np.testing.assert_allclose(back, [float(v) for v in position], atol=1e-9)


@settings(FUZZ, max_examples=150)
@given(angles=st.one_of(
    st.lists(st.lists(st.floats(-360.0, 360.0), min_size=5, max_size=5), max_size=4),
    st.lists(st.lists(angle_values, min_size=4, max_size=6), max_size=3), nasty_values),
    chunk=st.one_of(st.integers(1, 5), st.integers(-2, 0), st.floats(-1, 5), st.text(max_size=2),
                    st.booleans()))
def test_batch_fk_gives_poses_or_a_project_error(angles, chunk):
    try:
        positions, _ = fk.get_forward_kinematics_batch(angles, chunk=chunk)
    except fk.KinematicsInputError as error:
        event("refused")
        assert "\n" not in str(error)
    else:
        event("computed")
        assert positions.shape == (len(angles), 3)
        for row, position in zip(angles, positions, strict=True):
            single, _ = fk.get_forward_kinematics(dict(zip(ARM_JOINTS, row, strict=True)))
            np.testing.assert_allclose(position, single, atol=1e-13)


# --- hold_position's call shapes ---------------------------------------------------------
hold_arguments = st.lists(st.one_of(valid_configuration, any_configuration,
                                    st.floats(0.0, 0.05), nasty_values), max_size=3)


@pytest.mark.slow
@settings(FUZZ, max_examples=200)
@given(args=hold_arguments)
def test_hold_position_holds_or_names_the_shapes(model, args):
    import mujoco

    import so101_mujoco_utils as utils

    d = mujoco.MjData(model)
    try:
        utils.hold_position(model, d, None, *args)
    except PlanError as error:
        event(type(error).__name__)
        assert "\n" not in str(error) and "Fix:" in str(error), str(error)
        assert d.time == 0.0  # refused before any step
    else:
        event("held")
        assert 1 <= len(args) <= 2 and not isinstance(args[-1], dict)
        assert d.time == pytest.approx(float(args[-1]), abs=model.opt.timestep)


# --- test_ik_mujoco.py -------------------------------------------------------------------
ik_option_values = {
    "--targets": st.lists(number_text, min_size=1, max_size=1),
    "--seed": st.lists(number_text, min_size=1, max_size=1),
    "--target": st.one_of(st.lists(number_text, min_size=2, max_size=3),
                          st.tuples(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4),
                                    st.floats(-400, 400)).map(lambda t: [repr(v) for v in t])),
    "--move-duration": st.lists(number_text, min_size=1, max_size=1),
    "--hold": st.lists(number_text, min_size=1, max_size=1),
    "--json": st.sampled_from([["OUT/report.json"], ["OUT"], ["OUT/v.mp4"], ["OUT/a\0b"]]),
    "--record": st.sampled_from([["OUT/v.mp4"], ["OUT/v.avi"], ["OUT"]]),
    "--bogus": st.just([]),
}
ik_arguments = st.lists(
    st.sampled_from(sorted(ik_option_values)).flatmap(
        lambda option: ik_option_values[option].map(lambda values: [option, *values])),
    max_size=4).map(lambda groups: [token for group in groups for token in group])


@settings(FUZZ, max_examples=150)
@given(argv=ik_arguments)
def test_ik_script_command_lines_run_or_name_the_problem(argv):
    import test_ik_mujoco

    def fake_scene(mode, video, *, total_time, progress, show_ui, servo=None):
        # Reached only with checked outputs and durations, and reachable targets.
        assert mode in ("headless", "record") and (video is None or video.suffix == ".mp4")
        assert 0.0 <= total_time <= 100 * 2 * MAX_DURATION
        raise Ran

    with tempfile.TemporaryDirectory() as folder:
        argv = ["--headless", "--no-progress"] + [token.replace("OUT", f"{folder}/out")
                                                  for token in argv]
        with mock.patch.object(test_ik_mujoco, "open_scene", fake_scene):
            try:
                code, _, err = run_main(test_ik_mujoco.main, argv)
            except Ran:
                event("ran")
            else:
                event(f"exit {code}")
                if code != 0:
                    check_refusal(code, err, argv)
        assert not (Path(folder) / "out" / "report.json").exists()


# --- existing output files (issue 28, 33): replaced only when ours (its marker), or --overwrite --
def _box(kind: bytes, payload: bytes) -> bytes:
    return (8 + len(payload)).to_bytes(4, "big") + kind + payload


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    import zlib

    return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")


OURS = {  # the smallest file of each kind that carries this project's marker (markers.py)
    "png": b"\x89PNG\r\n\x1a\n" + _png_chunk(b"tEXt", b"Software\0so101-kinematics fuzz")
           + _png_chunk(b"IEND", b""),
    "pdf": b"%PDF-1.4\n1 0 obj\n<< /Creator (so101-kinematics fuzz) >>\nendobj\n%%EOF\n",
    "mp4": _box(b"ftyp", b"isom\x00\x00\x02\x00isom")
           + _box(b"moov", _box(b"udta", b"so101-kinematics")),
    "json": b'{"generator": "so101-kinematics fuzz"}'}


@FUZZ
@given(kind=st.sampled_from(sorted(OURS)), ours=st.booleans(),
       content=st.binary(max_size=200), overwrite=st.booleans())
def test_an_existing_output_is_replaced_only_when_ours_or_overwritten(kind, ours, content,
                                                                     overwrite):
    from so101_kinematics import outputs

    kinds = {"png": outputs.PNG, "pdf": outputs.PDF, "mp4": outputs.MP4,
             "json": outputs.JSON_REPORT}
    # another program's file: any bytes, even behind our kind's own signature (a PNG, an MP4)
    data = OURS[kind] if ours else OURS[kind][:8] + content
    with tempfile.TemporaryDirectory() as folder:
        target = Path(folder) / f"out.{kind}"
        target.write_bytes(data)
        try:
            outputs.check_output_path(target, "--out", kind=kinds[kind], overwrite=overwrite)
            allowed = True
        except OutputPathError as error:
            allowed = False
            assert "Fix:" in str(error) and "--overwrite" in str(error)
        assert target.read_bytes() == data  # checking never touches the file
        assert allowed == (ours or overwrite)
