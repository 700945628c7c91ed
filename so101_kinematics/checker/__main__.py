"""``python -m so101_kinematics.checker PATH``: see :mod:`so101_kinematics.checker.fk`."""

import sys

from so101_kinematics.checker.fk import main

if __name__ == "__main__":
    sys.exit(main())
