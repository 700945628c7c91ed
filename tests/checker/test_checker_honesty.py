"""The checkers are honest (issue 33): the project's own modules score full marks, the stand-in
MuJoCo reads as MuJoCo does, a submission cannot write outside its temporary folder, and an FK
that mutates its input, returns NaN or returns a 4x4 is told so.

The expected values come from MuJoCo itself (the real model loaded beside the stand-in) and
from the course's assignment (``get_forward_kinematics`` returns ``(position, rotation)``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from so101_kinematics.checker import report, traj, traj_standin
from so101_kinematics.checker.fk import check_file
from so101_kinematics.checker.ik import check_ik_file
from so101_kinematics.frames import JOINTS

REPO = Path(__file__).resolve().parents[2]


def test_the_projects_own_cubic_utils_scores_100_through_the_console_script():
    """The README's own example: ``so101-check-traj so101_mujoco_utils.py`` (it scored 0/100:
    the stand-in's ``qposadr`` was an int where MuJoCo's is an array)."""
    done = subprocess.run([sys.executable, "-m", "so101_kinematics.checker.traj",
                           "so101_mujoco_utils.py"], cwd=REPO, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.rstrip().endswith("Score 100/100."), done.stdout


def test_the_projects_own_fk_and_ik_score_full_marks():
    fk = check_file(REPO / "so101_forward_kinematics.py", count=200)
    results = report.gradescope_results(fk, report.DEFAULT_POINTS)
    assert fk["verdict"] == "pass" and results["score"] == sum(report.DEFAULT_POINTS.values())
    ik = check_ik_file(REPO / "so101_inverse_kinematics.py", count=60)
    assert ik["verdict"] == "pass", ik["reason"] or ik["note"]


def test_the_courses_fk_test_script_runs_on_the_stand_in_with_the_projects_utils(tmp_path):
    """tests/course's script (set_initial_pose, send_position_command, mjv_initGeom on the
    viewer's scene, hold_position) imported beside this project's utils and FK, as a student's
    week-6 folder holds them, with the cubic taken from the utils: 100/100 (on today's main
    its import failed in the utils: 'int' object is not subscriptable)."""
    for name in ("so101_kinematics", "so101_mujoco_utils.py", "so101_forward_kinematics.py"):
        (tmp_path / name).symlink_to(REPO / name)  # this tree's package, not an installed one
    script = tmp_path / "week6.py"
    script.write_text((REPO / "tests" / "course" / "fk_test_from_the_course.py").read_text()
                      + "\nfrom so101_mujoco_utils import move_to_pose_cubic  # noqa: E402\n")
    check = traj.check_traj_file(script)
    assert check["verdict"] == "pass", check["reason"] or check["causes"]
    assert traj.gradescope_results(check)["score"] == sum(traj.POINTS.values())


def test_the_courses_reference_cubic_scores_full_marks():
    check = traj.check_traj_file(REPO / "tests" / "traj_submissions" / "correct.py")
    assert traj.gradescope_results(check)["score"] == sum(traj.POINTS.values())


@pytest.fixture(scope="module")
def both():
    """The real model (MuJoCo) and the stand-in, side by side."""
    import mujoco

    from so101_kinematics.sim.scene import load_model

    m = load_model()
    return (m, mujoco.MjData(m)), (traj_standin.StandInModel(m.opt.timestep),
                                   traj_standin.StandInData())


def _kind(value):
    """What a caller can rely on: the type, and an array's dtype and shape."""
    if isinstance(value, np.ndarray):
        return ("ndarray", value.dtype, value.shape)
    return (type(value).__name__,)


def test_the_stand_in_model_and_data_read_as_mujocos(both):
    (m, d), (sm, sd) = both
    for name in ("jnt_qposadr", "jnt_dofadr", "jnt_range", "actuator_trnid",
                 "actuator_ctrlrange", "actuator_gainprm", "actuator_biasprm", "dof_damping"):
        assert _kind(getattr(sm, name)) == _kind(getattr(m, name)), name
    for name in ("qpos", "qvel", "ctrl"):
        assert _kind(getattr(sd, name)) == _kind(getattr(d, name)), name
    assert (sm.nq, sm.nv, sm.nu, sm.njnt) == (m.nq, m.nv, m.nu, m.njnt)
    for joint in JOINTS:
        for a, b in ((m.joint(joint), sm.joint(joint)), (m.actuator(joint), sm.actuator(joint)),
                     (d.joint(joint), sd.joint(joint)), (d.actuator(joint), sd.actuator(joint))):
            for field in ("id", "name", "qposadr", "dofadr", "range", "trnid", "ctrlrange",
                          "qpos", "qvel", "ctrl"):
                if hasattr(a, field):
                    assert _kind(getattr(b, field)) == _kind(getattr(a, field)), (joint, field)
            assert b.id == a.id and b.name == a.name
        assert m.joint(joint).qposadr[0] == sm.joint(joint).qposadr[0]
    assert sm.actuator(2).name == m.actuator(2).name == "elbow_flex"
    for call in (lambda model: model.joint("elbow"), lambda model: model.actuator(99)):
        with pytest.raises(Exception) as real:
            call(m)
        with pytest.raises(Exception) as stand_in:
            call(sm)
        assert type(stand_in.value) is type(real.value)
        assert str(stand_in.value) == str(real.value)


def test_a_view_writes_into_the_stand_ins_arrays_as_mujocos_do(both):
    (m, d), (sm, sd) = both
    for data in (d, sd):
        data.joint("wrist_flex").qpos[0] = 0.25
        data.actuator("elbow_flex").ctrl[0] = -0.5
        assert data.qpos[3] == 0.25 and data.ctrl[2] == -0.5
    with pytest.raises(ValueError, match=r"could not broadcast .* \(2,\) into shape \(6,\)"):
        sd.ctrl = [1.0, 2.0]


def test_name_lookups_use_mujocos_object_numbers(both):
    import mujoco

    (m, _), (sm, _) = both
    stand_in = traj_standin.OBJ
    for kind, name in (("joint", "elbow_flex"), ("actuator", "wrist_flex"),
                       ("joint", "no_such_joint")):
        number = int(getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"))
        assert stand_in[kind] == number
        assert traj_standin.mj_name2id(sm, number, name) == mujoco.mj_name2id(m, number, name)


ESCAPES = {
    "a parent folder": 'open("../escape.txt", "w").write("x")',
    "an absolute path": 'open(OUTSIDE, "w").write("x")',
    "os.open": 'import os\nos.close(os.open(OUTSIDE, os.O_WRONLY | os.O_CREAT))',
    "a symlink out": 'import os\nos.symlink(os.path.dirname(OUTSIDE), "out")\n'
                     'open(os.path.join("out", os.path.basename(OUTSIDE)), "w").write("x")',
    "a rename out": 'open("inside.txt", "w").write("x")\nimport os\n'
                    'os.replace("inside.txt", OUTSIDE)',
    "a remove": 'import os\nos.remove(VICTIM)',
    "a mkdir": 'import os\nos.mkdir(OUTSIDE)',
}
"""What a submission does at import (caught or not), each outside its temporary folder."""


@pytest.mark.parametrize("caught", [False, True])
@pytest.mark.parametrize("how", list(ESCAPES))
def test_a_submission_cannot_write_outside_its_temporary_folder(tmp_path, how, caught):
    """Issue 33: a submission that wrote outside its folder scored 100. Each way out is refused,
    nothing is written (or removed), and the check names the path instead of scoring it."""
    outside, victim = tmp_path / "outside" / "escape.txt", tmp_path / "victim.txt"
    outside.parent.mkdir()
    victim.write_text("keep me")
    body = ESCAPES[how]
    if caught:
        body = "try:\n" + "".join(f"    {line}\n" for line in body.splitlines()) + \
            "except OSError:\n    pass\n"
    module = tmp_path / "student" / "so101_forward_kinematics.py"
    module.parent.mkdir()
    module.write_text(f"OUTSIDE = {str(outside)!r}\nVICTIM = {str(victim)!r}\n{body}\n"
                      + (REPO / "tests" / "fk_submissions" / "correct.py").read_text())
    check = check_file(module, count=20)
    assert check["verdict"] == "error"
    assert check["reason"].startswith("it writes outside its temporary folder: ")
    assert report.gradescope_results(check, report.DEFAULT_POINTS)["score"] == 0
    assert not outside.exists() and not (tmp_path / "student" / "escape.txt").exists()
    assert victim.read_text() == "keep me"
    assert sorted(p.name for p in module.parent.iterdir()) == ["so101_forward_kinematics.py"]


def test_writes_inside_the_temporary_folder_home_and_tmpdir_are_allowed(tmp_path):
    module = tmp_path / "so101_forward_kinematics.py"
    module.write_text(
        "import os, tempfile\nopen('log.txt', 'w').write('x')\nos.mkdir('plots')\n"
        "os.replace('log.txt', 'plots/log.txt')\n"
        "open(os.path.expanduser('~/cache.txt'), 'w').write('x')\n"
        "tempfile.NamedTemporaryFile().close()\n"
        "import shutil\nos.makedirs('a/b')\nopen('a/b/c', 'w').close()\nshutil.rmtree('a')\n"
        + (REPO / "tests" / "fk_submissions" / "correct.py").read_text())
    check = check_file(module, count=20)
    assert check["verdict"] == "pass", check["reason"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["so101_forward_kinematics.py"]


@pytest.mark.parametrize("checker", ["ik", "traj"])
def test_the_ik_and_trajectory_checkers_refuse_the_same_writes(tmp_path, checker):
    outside = tmp_path / "escape.txt"
    module = tmp_path / "student" / "submission.py"
    module.parent.mkdir()
    module.write_text(f"open({str(outside)!r}, 'w').write('x')\n")
    check = (check_ik_file(module, count=5) if checker == "ik"
             else traj.check_traj_file(module))
    assert check["verdict"] == "error" and "writes outside" in check["reason"], check["reason"]
    assert not outside.exists()


CORRECT_FK = (REPO / "tests" / "fk_submissions" / "correct.py").read_text()
FACTORS_ONLY = CORRECT_FK[:CORRECT_FK.index("def get_forward_kinematics")]
COURSE_FK_BODY = """    gw1 = get_gw1(position_dict['shoulder_pan'])
    g12 = get_g12(position_dict['shoulder_lift'])
    g23 = get_g23(position_dict['elbow_flex'])
    g34 = get_g34(position_dict['wrist_flex'])
    g45 = get_g45(position_dict['wrist_roll'])
    gwt = gw1 @ g12 @ g23 @ g34 @ g45 @ get_g5t()
"""


def _fk_test(tmp_path, first_lines: str, returns: str) -> dict:
    """The FK test of a course-style module whose FK starts with ``first_lines``."""
    module = tmp_path / "so101_forward_kinematics.py"
    module.write_text(FACTORS_ONLY + "def get_forward_kinematics(position_dict):\n"
                      + first_lines + COURSE_FK_BODY + f"    return {returns}\n")
    check = check_file(module, count=50)
    return next(t for t in check["tests"] if t["function"] == "get_forward_kinematics")


def test_an_fk_that_changes_its_input_is_named_not_a_product_order(tmp_path):
    """A clamp written back into the caller's dict: it was diagnosed as a wrong product order."""
    fk = _fk_test(tmp_path, "    for joint in position_dict:\n        position_dict[joint] = "
                  "max(-90.0, min(90.0, position_dict[joint]))\n", "gwt[0:3, 3], gwt[0:3, 0:3]")
    assert fk["status"] == "wrong"
    (cause,) = [c for c in fk["causes"] if "changes the configuration it is given" in c]
    assert "-> 90.0" in cause and "cfg = dict(position_dict)" in cause
    assert not any("order of the product" in c for c in fk["causes"])


def test_an_fk_that_changes_its_input_fails_even_when_its_pose_is_right(tmp_path):
    fk = _fk_test(tmp_path, "    position_dict.pop('gripper', None)\n",
                  "gwt[0:3, 3], gwt[0:3, 0:3]")
    assert fk["status"] == "wrong" and fk["max_error_mm"] < 0.01
    assert any("(gripper deleted; in 53 of 53 calls)" in c for c in fk["causes"]), fk["causes"]


def test_nan_returned_by_the_fk_is_named_with_where(tmp_path):
    fk = _fk_test(tmp_path, "    scale = np.sqrt(position_dict['shoulder_pan'])\n",
                  "gwt[0:3, 3] * scale / scale, gwt[0:3, 0:3]")
    assert fk["status"] == "broken"
    # sqrt of a negative pan, and 0/0 at pan 0: the course's starting pose (pan -45) first
    (cause,) = fk["causes"]
    assert cause.startswith("returns NaN or infinite numbers at ")
    assert "the first at the course's starting configuration" in cause


def test_a_4x4_return_is_named_broken_with_its_pose_right(tmp_path):
    """It was "WRONG, max 0.00 mm": the pose is right, the form breaks the course's script."""
    fk = _fk_test(tmp_path, "", "gwt")
    assert fk["status"] == "broken" and fk["max_error_mm"] < 0.01
    assert "(the pose in it is right)" in fk["causes"][0]
    assert "Fix: return gwt[0:3, 3], gwt[0:3, 0:3]" in fk["causes"][0]


def test_nan_returned_by_a_factor_names_the_angle(tmp_path):
    from so101_kinematics.checker.fk_compare import factor_angles

    module = tmp_path / "so101_forward_kinematics.py"
    module.write_text(CORRECT_FK.replace("def get_g23(theta3_deg):\n",
                                         "def get_g23(theta3_deg):\n"
                                         "    if theta3_deg < 0:\n"
                                         "        theta3_deg = np.nan\n"))
    check = check_file(module, count=20)
    g23 = next(t for t in check["tests"] if t["function"] == "get_g23")
    first_negative = next(a for a in factor_angles("elbow_flex") if a < 0)
    assert g23["status"] == "broken"
    assert g23["causes"] == [f"returns NaN or infinite numbers at {first_negative:g} deg"]
