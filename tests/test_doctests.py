"""Every worked example in a module docstring runs and gives what it shows."""

import doctest
import importlib

import pytest

MODULES = ["so101_forward_kinematics", "so101_inverse_kinematics", "so101_cartesian_plan",
           "so101_motion", "so101_meshes"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} has no worked example"
    assert result.failed == 0
