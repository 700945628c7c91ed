"""Every worked example in a docstring runs and gives what it shows: course files and package."""

import doctest
import importlib
import pkgutil

import pytest

import so101_kinematics

COURSE = ["so101_forward_kinematics", "so101_inverse_kinematics"]
PACKAGE = sorted(info.name for info in pkgutil.walk_packages(so101_kinematics.__path__,
                                                             "so101_kinematics."))
MUST_TEACH = {"so101_forward_kinematics", "so101_inverse_kinematics",
              "so101_kinematics.planning.cartesian_plan", "so101_kinematics.planning.motion",
              "so101_kinematics.sim.meshes"}
"""Modules whose worked examples are part of what they teach: they must have some."""


@pytest.mark.parametrize("name", COURSE + PACKAGE)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
    if name in MUST_TEACH:
        assert result.attempted > 0, f"{name} has no worked example"
