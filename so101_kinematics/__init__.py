"""so101-kinematics: the machinery behind the course's SO-101 files (see docs/architecture.md).

The shared core is the modules here (plans and motion, calibration, errors,
display, outputs, command-line helpers); ``sim/`` simulates the arm in MuJoCo,
``hw/`` drives the real arm through lerobot, ``virtual/`` is a virtual arm
behind a serial port. ``hw`` and ``virtual`` never import each other.
Importing this package is cheap: nothing here imports MuJoCo or lerobot.
"""

__all__: list[str] = []
