"""Facts of the course's scene, each written once: the cube, the arm's home pose."""

__all__ = ["CUBE_HALF_SIZE", "CUBE_SIZE", "HOME_POSE"]

CUBE_SIZE = 0.026
"""Edge of the course's cubes [m]: its one home (``sim/cube.py`` builds the simulator's cubes
from it; the ``object_frame`` site of ``model/so101.xml`` draws a held one, half sizes 0.013,
and ``tests/core/test_facts.py`` checks the two agree)."""

CUBE_HALF_SIZE = CUBE_SIZE / 2
"""Half the cube's edge [m]: the height of its centre resting on the table."""

HOME_POSE = {"shoulder_pan": 0.0, "shoulder_lift": -90.0, "elbow_flex": 90.0, "wrist_flex": 30.0,
             "wrist_roll": 0.0, "gripper": 9.0}
"""The model's ``home`` keyframe in user units ([deg], gripper [0, 100]), rounded: the arm
folded at rest, where the virtual arm powers up."""
