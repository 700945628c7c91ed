"""``python -m so101_kinematics.checker PATH``: see :mod:`so101_kinematics.checker.cli`."""

import sys

from so101_kinematics.checker.cli import main

if __name__ == "__main__":
    sys.exit(main())
