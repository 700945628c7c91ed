"""Print the SO-101's pose live (torque off, move it by hand) as a configuration and FK position."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from pick_place_hw import TEACH_RATE_HZ, teach
from so101_bus import FIND_PORT_HINT, connect, disconnect
from so101_calibration import HardwareError, find_calibration, load_calibration

RATE_HZ = TEACH_RATE_HZ  # printing rate [Hz]


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 2 refused)."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--port", required=True,
                        help=f"serial port of the arm (find it with `{FIND_PORT_HINT}`)")
    who = parser.add_mutually_exclusive_group(required=True)
    who.add_argument("--id", dest="robot_id", help="robot id given to lerobot-calibrate")
    who.add_argument("--calibration", type=Path, help="lerobot calibration JSON of this arm")
    parser.add_argument("--rate", type=float, default=RATE_HZ, help="printing rate [Hz]")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many seconds (default: Ctrl-C)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s: %(message)s")
    try:
        path = args.calibration or find_calibration(args.robot_id, args.port)
        calibration = load_calibration(path, args.robot_id)
        bus = connect(args.port, calibration, robot_id=args.robot_id)
    except HardwareError as error:
        print(f"Refused: {error}", file=sys.stderr)
        return 2
    try:
        teach(bus, rate_hz=args.rate, duration=args.duration)
    finally:
        disconnect(bus)
    return 0


if __name__ == "__main__":
    sys.exit(main())
