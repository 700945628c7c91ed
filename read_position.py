"""Print the SO-101's pose live (torque off, move it by hand) as a configuration and FK position.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from so101_kinematics.calibration import find_calibration, load_calibration
from so101_kinematics.cli import ArgumentParser
from so101_kinematics.errors import HardwareError, PlanError
from so101_kinematics.hw.bus import connect, disconnect
from so101_kinematics.hw.port import FIND_PORT_HINT
from so101_kinematics.hw.run import release_arm
from so101_kinematics.hw.signals import signals_as_interrupt
from so101_kinematics.hw.teach import MAX_TEACH_RATE_HZ, TEACH_RATE_HZ, teach
from so101_kinematics.inputs import check_number

RATE_HZ = TEACH_RATE_HZ  # printing rate [Hz]
MAX_DURATION_S = 86_400.0  # --duration at most a day [s]


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 1 failed, 2 refused)."""
    parser = ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", required=True,
                        help=f"serial port of the arm (find it with `{FIND_PORT_HINT}`)")
    who = parser.add_mutually_exclusive_group(required=True)
    who.add_argument("--id", dest="robot_id", help="robot id given to lerobot-calibrate")
    who.add_argument("--calibration", type=Path, help="lerobot calibration JSON of this arm")
    parser.add_argument("--rate", type=float, default=RATE_HZ,
                        help=f"printing rate [Hz] (up to {MAX_TEACH_RATE_HZ:g}, "
                             f"default {RATE_HZ:g})")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many seconds (default: Ctrl-C)")
    parser.add_argument("--release", action="store_true",
                        help="only release the torque of every servo (hold the arm: it falls), "
                             "then exit")
    parser.add_argument("--yes", "-y", action="store_true", help="do not ask before --release")
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # a bad option (one line printed) or --help: its exit code
        return stop.code
    logging.basicConfig(level=logging.INFO, format="%(levelname)s: %(message)s")
    try:
        with signals_as_interrupt():
            check_number(args.rate, "--rate", 0.0, MAX_TEACH_RATE_HZ, "Hz", low_open=True)
            if args.duration is not None:
                check_number(args.duration, "--duration", 0.0, MAX_DURATION_S, "s",
                             low_open=True)
            path = args.calibration or find_calibration(args.robot_id, args.port)
            calibration = load_calibration(path, args.robot_id)
            if args.release:
                from pick_place_hw import ask

                unreleased = release_arm(args.port, calibration, robot_id=args.robot_id,
                                         confirm=lambda q: ask(q, args.yes))
                print("Torque off on every servo." if not unreleased else
                      f"Torque could NOT be released on {', '.join(unreleased)}: check that "
                      "servo's cable and power, then run this again.")
                return 1 if unreleased else 0
            bus = connect(args.port, calibration, robot_id=args.robot_id)
            try:
                teach(bus, rate_hz=args.rate, duration=args.duration)
            finally:
                disconnect(bus)
    except (HardwareError, PlanError) as error:
        print(f"Refused: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("Interrupted.", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
