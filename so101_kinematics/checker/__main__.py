"""``python -m so101_kinematics.checker PATH``: see :mod:`so101_kinematics.checker.fk`."""

import sys

from so101_kinematics.checker.fk import main

__all__: list[str] = []

if __name__ == "__main__":
    sys.exit(main())
