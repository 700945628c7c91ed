"""``python -m so101_kinematics ...``: the ``so101`` command (:mod:`.commands.so101_command`)."""

import sys

from so101_kinematics.commands.so101_command import main

__all__: list[str] = []

if __name__ == "__main__":
    sys.exit(main())
