"""Serve a virtual SO-101 on a pseudo-terminal until Ctrl-C: six STS3215s, a MuJoCo arm behind them.

    python virtual_so101.py [--calibration PATH] [--viewer] [--wire-timing] [--faults SPEC]

prints the pty path as the first line of stdout (give it to ``pick_place_hw.py
--port``, ``lerobot-teleoperate``, ...), then logs to stderr. The emulator, its
faults and its deviations from a real arm are described in
``so101_kinematics/virtual/arm.py``; this script only parses the options.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

from so101_kinematics.display import has_display
from so101_kinematics.errors import (
    CalibrationError,
    CubePositionError,
    FaultSpecError,
    OutputPathError,
    VirtualSO101Error,
)
from so101_kinematics.outputs import check_output_path, write_text_atomic
from so101_kinematics.sim.scene import load_model
from so101_kinematics.virtual.arm import (  # noqa: F401 - the virtual arm's API, re-exported
    CUBE_REACH_M,
    DEFAULT_CALIBRATION_PATH,
    VirtualSO101,
    parse_faults,
)
from so101_kinematics.virtual.calibration import make_default_calibration

logger = logging.getLogger("virtual_so101")


def main(argv: list[str] | None = None) -> int:
    """Serve a virtual SO-101 until Ctrl-C."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", default=str(DEFAULT_CALIBRATION_PATH),
                        help="lerobot calibration JSON (default: %(default)s)")
    parser.add_argument("--viewer", action="store_true", help="show the arm (needs a display)")
    parser.add_argument("--wire-timing", action="store_true",
                        help="delay replies by their byte time at the host's baud rate")
    parser.add_argument("--faults", default=None,
                        help="faults from power-up, e.g. 'drop:3:5,stall:elbow_flex'")
    parser.add_argument("--cube", nargs=2, type=float, metavar=("X", "Y"),
                        help="put the simulator's free 26 mm cube on the table, its centre at "
                             f"(X, Y) [m] in the base frame (each within +-{CUBE_REACH_M:g} m)")
    parser.add_argument("--cube-yaw", type=float, default=0.0, metavar="DEG",
                        help="the cube's turn about the vertical [deg] (default 0)")
    parser.add_argument("--write-default-calibration", metavar="PATH",
                        help="write the calibration derived from the model to PATH and exit")
    parser.add_argument("--force", action="store_true",
                        help="with --write-default-calibration: replace an existing file")
    parser.add_argument("-v", "--verbose", action="store_true", help="log every fault and start-up")
    args = parser.parse_args(argv)
    level = logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=level, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    if args.write_default_calibration:
        try:
            path = check_output_path(args.write_default_calibration,
                                     "--write-default-calibration", overwrite=args.force)
        except OutputPathError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        calibration = make_default_calibration(load_model())
        write_text_atomic(path, json.dumps(calibration, indent=4) + "\n")
        print(f"Calibration written to {path}")
        return 0
    if args.viewer and not has_display():
        print("error: --viewer needs a display (DISPLAY or WAYLAND_DISPLAY is not set); "
              "run without --viewer.", file=sys.stderr)
        return 2
    try:
        arm = VirtualSO101(calibration=args.calibration, wire_timing=args.wire_timing,
                           faults=args.faults, viewer=args.viewer, log_level=level,
                           cube=(*args.cube, args.cube_yaw) if args.cube else None)
    except (CalibrationError, CubePositionError, FaultSpecError, VirtualSO101Error) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with arm:
        print(arm.port, flush=True)
        logger.warning("virtual SO-101 serving on %s (wire timing %s); Ctrl-C to stop",
                       arm.port, "on" if args.wire_timing else "off")
        try:
            arm._process.wait()
        except KeyboardInterrupt:
            logger.warning("stopping")
    return 0


if __name__ == "__main__":
    sys.exit(main())

