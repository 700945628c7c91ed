"""The simulated servo's options say what they do (issue 33's poor rows, issue 34's default).

- ``--servo ideal`` has no supply, variant or P: given with it they are refused in one line
  (before, silently ignored);
- a supply above the variant's Max_Voltage_Limit (the C001's 8.0 V, Feetech's memory table)
  is refused in one line with the fix (before, a C001 on 12 V ran);
- the default is the course's follower: C018 servos on the 12 V supply (ECE4560 assignment 3).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from so101_kinematics.cli import add_servo_arguments, servo_from_arguments
from so101_kinematics.errors import PlanError
from so101_kinematics.sim import actuation
from so101_kinematics.sim.scene import load_model

REPO = Path(__file__).resolve().parents[2]


def _options(*argv: str) -> dict:
    parser = argparse.ArgumentParser()
    add_servo_arguments(parser)
    return servo_from_arguments(parser.parse_args(list(argv)))


@pytest.mark.parametrize("given", [("--supply", "7.4"), ("--variant", "C001"),
                                   ("--p-coefficient", "32")])
def test_the_ideal_servo_refuses_the_options_it_would_ignore(given):
    with pytest.raises(PlanError, match=f"{given[0]} with --servo ideal.*Fix:"):
        _options("--servo", "ideal", *given)
    assert _options("--servo", "ideal")["mode"] == "ideal"


def test_a_c001_on_12_v_is_refused_with_the_fix():
    with pytest.raises(PlanError, match=r"12 V is above the C001's Max_Voltage_Limit 8 V.*Fix"):
        _options("--supply", "12", "--variant", "C001")
    with pytest.raises(PlanError, match="Max_Voltage_Limit"):
        actuation.use_servo(load_model(), volts=12.0, variant="C001")
    # within its range it runs, as does the 12 V C018 on 5 V (below its rating, weaker)
    assert _options("--supply", "7.4", "--variant", "C001")["volts"] == 7.4
    actuation.use_servo(load_model(), volts=5.0, variant="C018")


def test_the_default_is_the_course_s_12_v_follower():
    assert _options() == {"mode": "sts3215", "volts": 12.0, "variant": None, "p": 16,
                          "feedforward": True}
    spec = actuation.servo_spec(load_model())
    assert (spec.variant, spec.volts) == ("C018", 12.0)
    assert _options("--supply", "5")["volts"] == 5.0  # the standard kit's, an option


def test_a_script_refuses_a_c001_on_12_v_in_one_line():
    done = subprocess.run([sys.executable, "test_ik_mujoco.py", "--headless", "--supply", "12",
                           "--variant", "C001"], cwd=REPO, capture_output=True, text=True,
                          timeout=600, env={"PYTHONPATH": str(REPO), "MUJOCO_GL": "egl",
                                            "PATH": "/usr/bin:/bin"})
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Max_Voltage_Limit" in lines[0] and "Fix:" in lines[0]
