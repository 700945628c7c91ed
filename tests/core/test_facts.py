"""One home per fact: each fact is written once, and what is read from its home is the model's.

The homes: the arm's geometry, joint ranges, masses and collision boxes in ``model/so101.xml``
(read by ``so101_kinematics.model_facts``); the servo variants' identified and datasheet
numbers in ``so101_kinematics/servo_variants/*.json`` (read by ``servo.VARIANTS``); the
encoder's resolution in ``servo.COUNTS_PER_TURN``; the cube's edge in ``constants.CUBE_SIZE``.

A number written in code (not in a comment or a docstring) in the package or the course
files at the root that is one of these facts, outside its home, fails the first test. The
expected values of the others come from the XML text read by hand or from MuJoCo's compiled
model, never from the reader under test.
"""

from __future__ import annotations

import io
import json
import re
import tokenize
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "so101_kinematics"
MODEL_XML = REPO / "model" / "so101.xml"
VARIANT_DIR = PACKAGE / "servo_variants"

# The encoder's resolution (and its last position) and the cube's edge (and half edge).
SCALAR_FACTS = {
    4096.0: ("the encoder's positions per turn", "so101_kinematics/servo.py"),
    4095.0: ("the encoder's last position (4096 - 1)", "so101_kinematics/servo.py"),
    2048.0: ("the encoder's middle (4096 / 2)", "so101_kinematics/servo.py"),
    0.026: ("the cube's edge [m]", "so101_kinematics/constants.py"),
    0.013: ("half the cube's edge [m]", "so101_kinematics/constants.py"),
}

OTHER_MEANINGS = {
    # Files where 4096 is another fact that happens to share the number, with what it is.
    ("so101_kinematics/sim/render.py", 4096.0): "MuJoCo's shadow map and the frame size [px]",
    ("so101_kinematics/sim/stepping.py", 4096.0): "steps per block of commands",
    ("so101_kinematics/virtual/emulator.py", 4096.0): "bytes read from the pty at a time",
    ("so101_kinematics/virtual/registers.py", 4096.0): "the reading noise's random seed",
}


def _distinctive(text: str) -> bool:
    """A number with at least three significant digits (0.0611, 1.2116): not a round value
    such as 0.02 or 7.4 that other facts share by chance."""
    digits = re.sub(r"[^0-9]", "", text.lower().split("e")[0]).lstrip("0")
    return len(digits.rstrip("0") if "." in text else digits) >= 3


def model_numbers() -> set[float]:
    """The distinctive numbers the arm's MJCF states in its attributes (a hand-free reading
    of the XML text: every quoted attribute value, split into numbers)."""
    found = set()
    for value in re.findall(r'(?:pos|quat|range|mass|size|fullinertia)="([^"]*)"',
                            MODEL_XML.read_text()):
        for word in value.split():
            if _distinctive(word) and float(word) not in (0.0,):
                found.add(abs(float(word)))
    return found


def variant_numbers() -> set[float]:
    """The distinctive numbers of the servo variants' data files."""
    found = set()

    def walk(node):
        if isinstance(node, dict):
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)
        elif isinstance(node, float) and _distinctive(repr(node)):
            found.add(abs(node))

    for path in VARIANT_DIR.glob("*.json"):
        walk(json.loads(path.read_text()))
    return found


def code_numbers(source: str) -> list[tuple[int, float]]:
    """(line, value) of every number written in code: comments and strings (docstrings,
    messages) are prose and left out."""
    out = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.NUMBER and not token.string.endswith(("j", "J")):
            text = token.string.replace("_", "")
            value = float(int(text, 0)) if text.isdigit() or text[:2] in ("0x", "0o", "0b") \
                else float(text)
            out.append((token.start[0], value))
    return out


def second_copies(files: list[Path]) -> list[str]:
    """Each fact written outside its home in ``files``: one line per copy."""
    facts = {value: (f"a number of model/so101.xml ({value:g})", "model/so101.xml")
             for value in model_numbers()}
    facts.update({value: (f"a servo variant's number ({value:g})",
                          "so101_kinematics/servo_variants/")
                  for value in variant_numbers()})
    facts.update(SCALAR_FACTS)
    copies = []
    for path in files:
        name = path.relative_to(REPO).as_posix() if path.is_relative_to(REPO) else path.name
        for line, value in code_numbers(path.read_text()):
            value = abs(value)
            if value in facts and (name, value) not in OTHER_MEANINGS:
                what, home = facts[value]
                if name != home:
                    copies.append(f"{name}:{line}: {what} written again; its home is {home}")
    return copies


def checked_files() -> list[Path]:
    """The package's modules and the course files at the root."""
    return sorted(PACKAGE.rglob("*.py")) + sorted(REPO.glob("*.py"))


def test_each_fact_is_written_once():
    copies = second_copies(checked_files())
    assert not copies, "\n".join(copies)


def test_the_facts_test_finds_a_second_copy(tmp_path):
    copy = tmp_path / "copy.py"
    copy.write_text('"""4096 in a docstring is prose."""\n'
                    "COUNTS = 4096  # a second home of the encoder's resolution\n"
                    "EDGE = 0.026\nSHOULDER = (0.0388353, 0.0, 0.0624)\nKT = 1.2116\n")
    found = second_copies([copy])
    assert sorted({int(entry.split(":")[1]) for entry in found}) == [2, 3, 4, 5], found


def test_the_known_numbers_include_the_ones_copied_before():
    """Values that were once copied into Python (frames, gravity, clearance, servo)."""
    assert {0.0388353, 0.11257, 0.1349, 0.0611, 1.9198621771937616, 0.100006, 0.0202,
            0.0172091, 0.1075, 0.0311} <= model_numbers()
    assert {1.2116, 2.676, 0.0524, 0.0591, 0.0284, 1.91, 2.94} <= variant_numbers()


# --- what model_facts reads is what MuJoCo compiles from the same file ----------------------
@pytest.fixture(scope="module")
def arm():
    mujoco = pytest.importorskip("mujoco")
    return mujoco.MjModel.from_xml_path(str(MODEL_XML))


BODIES = ("shoulder", "upper_arm", "lower_arm", "wrist", "gripper", "moving_jaw_so101_v1")


@pytest.mark.parametrize("body", BODIES)
def test_bodies_masses_and_boxes_are_the_compiled_models(arm, body):
    from so101_kinematics import model_facts

    compiled = arm.body(body)
    assert model_facts.body_position(body) == pytest.approx(compiled.pos, abs=1e-12)
    quat = np.array(model_facts.body_quaternion(body))
    assert quat / np.linalg.norm(quat) == pytest.approx(compiled.quat, abs=1e-12)
    assert model_facts.link_mass(body) == pytest.approx(compiled.mass[0], abs=1e-12)
    assert model_facts.centre_of_mass(body) == pytest.approx(compiled.ipos, abs=1e-12)
    boxes = [arm.geom(i) for i in range(arm.ngeom)
             if arm.geom_bodyid[i] == compiled.id and arm.geom_group[i] == 3]
    read = model_facts.collision_boxes(body)
    assert [name for name, _, _ in read] == [geom.name for geom in boxes]
    for (_, centre, half), geom in zip(read, boxes, strict=True):
        assert centre == pytest.approx(geom.pos, abs=1e-12)
        assert half == pytest.approx(geom.size, abs=1e-12)


def test_joint_ranges_and_sites_are_the_compiled_models(arm):
    from so101_kinematics import model_facts
    from so101_kinematics.frames import JOINTS

    for joint in JOINTS:
        assert model_facts.joint_range(joint) == pytest.approx(arm.joint(joint).range, abs=1e-12)
    for site in ("object_frame", "gripperframe"):
        assert model_facts.site_position(site) == pytest.approx(arm.site(site).pos, abs=1e-12)


def test_the_course_factors_turn_as_the_models_quaternions(arm):
    """frames.py writes each body's rotation as the course's Rz/Rx factors: they are the
    MJCF's quaternions (rounded there to 6 digits)."""
    mujoco = pytest.importorskip("mujoco")
    from so101_kinematics.frames import BODY_OF_FRAME, FIXED_ROTATION

    for name, frame in zip(("w1", "12", "23", "34", "45"), "12345", strict=True):
        matrix = np.zeros(9)
        mujoco.mju_quat2Mat(matrix, arm.body(BODY_OF_FRAME[frame]).quat)
        assert FIXED_ROTATION[name] == pytest.approx(matrix.reshape(3, 3), abs=2e-6), name


def test_read_by_hand_from_the_xml_text():
    """A few numbers read off model/so101.xml by eye (a reader that parses the wrong
    attribute or body gets them wrong)."""
    from so101_kinematics import model_facts

    assert model_facts.body_position("lower_arm") == (-0.11257, -0.028, 0.0)
    assert model_facts.joint_range("elbow_flex") == (-1.69, 1.69)
    assert model_facts.link_mass("wrist") == 0.079
    assert model_facts.centre_of_mass("gripper") == (0.000213627, 0.000245138, -0.025187)
    assert model_facts.collision_boxes("wrist") == (
        ("wrist_box", (-0.0022, -0.0269, 0.0222), (0.0179, 0.0389, 0.0311)),)
    assert model_facts.site_position("object_frame") == (0.0051, -0.000218, -0.1075)


def test_the_object_frames_box_is_the_courses_cube():
    from so101_kinematics import model_facts
    from so101_kinematics.constants import CUBE_SIZE

    assert model_facts.site_size("object_frame") == (CUBE_SIZE / 2,) * 3
    assert CUBE_SIZE == 0.026  # the course's 26 mm cube


def test_a_missing_name_is_refused_with_the_fix():
    from so101_kinematics import model_facts
    from so101_kinematics.errors import KinematicsInputError

    with pytest.raises(KinematicsInputError, match="no body named 'elbow'.*Fix"):
        model_facts.body_position("elbow")


# --- the servo variants: data files, their sources, the registry ----------------------------
def test_every_variant_file_names_its_source_and_is_package_data():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: the tomli backport (a dependency there)
        import tomli as tomllib

    from so101_kinematics import servo

    files = sorted(VARIANT_DIR.glob("*.json"))
    assert sorted(path.stem for path in files) == sorted(servo.VARIANTS)
    for path in files:
        data = json.loads(path.read_text())
        assert data["source"] and data["references"], path.name
    config = tomllib.loads((REPO / "pyproject.toml").read_text())
    globs = config["tool"]["setuptools"]["package-data"]["so101_kinematics"]
    assert all(any(path.relative_to(PACKAGE).match(glob) for glob in globs) for path in files)


def test_the_variants_are_their_sources_numbers():
    """BAM's identified motor and the datasheets' figures, by hand (servo.py's source list)."""
    from so101_kinematics import servo

    c001, sheet, c018 = (servo.VARIANTS[name] for name in ("C001", "C001-datasheet", "C018"))
    assert c001.torque_per_volt == pytest.approx(1.2116 / 2.676)  # BAM: kt / R
    assert (c001.coulomb, c001.viscous, c001.armature) == (0.0524, 0.0591, 0.0284)  # BAM
    assert sheet.stall_torque(7.4) == pytest.approx(1.91 * 0.97)  # 19.5 kg cm at 97 % duty
    assert c018.stall_torque(12.0) == pytest.approx(2.94 * 0.97)  # 30 kg cm
    assert c018.kt == pytest.approx(2.94 / 2.7)  # stall torque over stall current
    assert sheet.kt == pytest.approx(1.2116)  # BAM's, the datasheet gives no current
    assert (c001.max_volts, c018.max_volts) == (8.0, 14.0)  # Max_Voltage_Limit 80, 140


def test_the_command_lines_variants_are_the_registrys():
    import argparse

    from so101_kinematics import servo
    from so101_kinematics.cli import add_servo_arguments

    parser = argparse.ArgumentParser()
    add_servo_arguments(parser)
    variant = next(action for action in parser._actions if action.dest == "variant")
    assert tuple(variant.choices) == tuple(servo.VARIANTS)
    model = next(action for action in parser._actions if action.dest == "servo")
    assert tuple(model.choices) == servo.SIMULATED_SERVOS == ("sts3215", "ideal")
    assert parser.parse_args(["--supply", "14"]).supply == 14.0
    with pytest.raises(SystemExit):
        parser.parse_args(["--supply", "14.5"])
