"""Serve a virtual SO-101 on a pseudo-terminal: six STS3215s, a MuJoCo arm behind them, hands.

The course's files at the root are the project's one facade; ``so101_kinematics`` does the work.

    python virtual_so101.py [--calibration PATH] [--factory | --leader] [--link PATH]
                            [--viewer] [--wire-timing] [--faults SPEC] [--supply VOLTS]
                            [--camera NAME ... [--camera-size WxH] [--camera-fps FPS]
                            [--target X Y [YAW]]]

prints the pty path as the first line of stdout, then ``camera NAME: ADDRESS`` for each
served camera (``cv2.VideoCapture(ADDRESS)`` opens it), (give it to ``pick_place_hw.py
--port``, ``lerobot-calibrate``, ``lerobot-teleoperate``, ...), then reads
commands on stdin, one a line, each answered with one line on stdout (``ok
...`` / ``error ...``): ``pose JOINT=DEG ...``, ``sweep [JOINT ...]``,
``middle``, ``play FILE``, ``demo``, ``where``, ``limp``, ``plug``,
``supply VOLTS``, ``help``, ``quit`` (see ``so101_kinematics/virtual/shell.py``).
At the end of stdin it keeps serving until Ctrl-C. Logs go to stderr. The
emulator, its faults and its deviations from a real arm are described in
``so101_kinematics/virtual/arm.py``; this script only parses the options.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
from pathlib import Path

from so101_kinematics.cli import ArgumentParser, add_moved_options
from so101_kinematics.commands.so101_command import MOVED_FROM_VIRTUAL
from so101_kinematics.display import has_display
from so101_kinematics.errors import (
    CalibrationError,
    CubePositionError,
    FaultSpecError,
    JointLimitError,
    OpenCVMissing,
    RenderSettingError,
    VirtualSO101Error,
)
from so101_kinematics.frames import JOINTS
from so101_kinematics.servo import KIT_SUPPLY_V, VARIANTS
from so101_kinematics.sim.render import check_frame_size
from so101_kinematics.virtual import shell
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.camera_server import CAMERA_FPS
from so101_kinematics.virtual.cubes import CUBE_REACH_M
from so101_kinematics.virtual.electrical import SUPPLY_V
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

logger = logging.getLogger("virtual_so101")


def make_link(link: str, port: str) -> Path:
    """Create the symlink ``link`` to ``port``; never replace what this program did not create.

    Only a link that an earlier virtual SO-101 left behind (it points into ``/dev/pts/``, at
    a pty that is gone) is replaced; anything else there (a file, a folder, a user's own
    link, a live pty's link) is refused in one line.
    """
    path = Path(link)
    if path.is_symlink():
        target = os.readlink(path)
        if not (target.startswith("/dev/pts/") and not os.path.exists(target)):
            raise VirtualSO101Error(f"--link {link}: is a symlink to {target}, not one an earlier "
                                    "virtual arm left to a pty that is gone; it is kept. Fix: "
                                    "choose another path, e.g. /tmp/ttySO101, or remove it "
                                    "yourself.")
        path.unlink()
    elif path.exists():
        raise VirtualSO101Error(f"--link {link}: exists and is not a symlink. Fix: choose "
                                "another path, e.g. /tmp/ttySO101.")
    os.symlink(port, path)
    return path


def remove_link(link: Path, port: str) -> None:
    """Remove ``link`` at exit only while it is still the link this program made to ``port``."""
    try:
        if link.is_symlink() and os.readlink(link) == port:
            link.unlink()
    except OSError:
        pass


def camera_size(text: str) -> tuple[int, int]:
    """``--camera-size WxH`` -> (width, height) [px]."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
        return check_frame_size((width, height), "--camera-size", even=False)
    except RenderSettingError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT [px]. Fix: e.g. "
                                         "--camera-size 640x480.") from None


def main(argv: list[str] | None = None) -> int:
    """Serve a virtual SO-101 until ``quit`` or Ctrl-C."""
    parser = ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", default=str(DEFAULT_CALIBRATION_PATH),
                        help="lerobot calibration JSON (default: %(default)s)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--factory", action="store_true",
                      help="six factory-fresh servos (ID 1, 1 Mbit/s) plugged in one at a time, "
                           "gripper first, for lerobot-setup-motors")
    mode.add_argument("--leader", action="store_true",
                      help="a leader arm: limp, moved by `demo` / `play FILE` / `pose`")
    parser.add_argument("--link", metavar="PATH",
                        help="a stable symlink to the pty (e.g. /tmp/ttySO101), removed on exit")
    parser.add_argument("--supply", type=float, default=None,
                        help=f"the servos' supply voltage [V], 0..25 (default: the course's: "
                        f"{SUPPLY_V:g} V C018 servos for the follower, {KIT_SUPPLY_V:g} V for "
                        "--leader; --supply 5 for the kit's C001 follower); Present_Voltage "
                        "reports it, the servos' torque follows it")
    parser.add_argument("--variant", choices=sorted(VARIANTS), default=None,
                        help="STS3215 variant (default: C018 above 9 V, else C001)")
    parser.add_argument("--viewer", action="store_true", help="show the arm (needs a display)")
    parser.add_argument("--wire-timing", action="store_true",
                        help="delay replies by their byte time at the host's baud rate")
    parser.add_argument("--faults", default=None,
                        help="faults from power-up, e.g. 'drop:3:5,stall:elbow_flex'")
    parser.add_argument("--cube", nargs="+", type=float, action="append", metavar="X Y [YAW]",
                        help="put one of the simulator's free 26 mm cubes on the table, its "
                             f"centre at (X, Y) [m] in the base frame (each within "
                             f"+-{CUBE_REACH_M:g} m), turned YAW [deg]; repeat it for more cubes "
                             "(the cube sensor reports them in this order)")
    parser.add_argument("--cube-yaw", type=float, default=0.0, metavar="DEG",
                        help="the turn about the vertical [deg] of each cube given without "
                             "its own YAW (default 0)")
    parser.add_argument("--initial", nargs=6, type=float, default=None,
                        metavar=("PAN", "LIFT", "ELBOW", "WRIST", "ROLL", "GRIPPER"),
                        help="the pose the arm powers up holding [deg], the gripper [0, 100], in "
                             "joint order (default the model's home: 0 -90 90 30 0 9; "
                             "two_arms.py --print-virtual-arms gives each arm's park pose)")
    parser.add_argument("--base-height", type=float, default=0.0, metavar="M",
                        help="the table is M [m] below the robot's base frame, 0 to 0.05 "
                             "(default 0; the lab's mount: 0.015)")
    parser.add_argument("--camera", action="append", default=[], metavar="NAME",
                        help="serve the model's camera NAME (overhead, wrist, ...) rendered live "
                             "as an MJPEG stream cv2.VideoCapture opens; repeat for more; prints "
                             "`camera NAME: ADDRESS` for each (needs OpenCV)")
    parser.add_argument("--camera-size", type=camera_size, default=(640, 480), metavar="WxH",
                        help="the cameras' frame size [px] (default 640x480)")
    parser.add_argument("--camera-fps", type=float, default=CAMERA_FPS, metavar="FPS",
                        help="frames per second served while a client watches, 1..60 "
                             "(default %(default)g)")
    parser.add_argument("--target", nargs="+", type=float, default=None, metavar="X Y [YAW]",
                        help="lay the target tag on the table at X Y [m] in the base frame, "
                             "turned YAW [deg], for the served cameras (the first cube "
                             "carries the cube tag); needs --camera")
    add_moved_options(parser, MOVED_FROM_VIRTUAL)
    parser.add_argument("-v", "--verbose", action="store_true", help="log every fault and start-up")
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # a bad option (one line printed) or --help: its exit code
        return stop.code
    level = logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=level, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    if args.viewer and not has_display():
        print("error: --viewer needs a display (DISPLAY or WAYLAND_DISPLAY is not set); "
              "run without --viewer.", file=sys.stderr)
        return 2
    words = sys.argv[1:] if argv is None else argv
    given = [o for o in ("--camera-size", "--camera-fps", "--target")
             if any(w.startswith(o) for w in words)]
    if given and not args.camera:
        print(f"error: {given[0]} is for the served cameras, but none is served; add --camera "
              "NAME (e.g. --camera overhead).", file=sys.stderr)
        return 2
    if args.supply is not None and not 0.0 <= args.supply <= 25.0:
        print(f"error: --supply {args.supply:g}: outside 0..25 V; use e.g. --supply 12.",
              file=sys.stderr)
        return 2
    try:
        arm = VirtualSO101(calibration=args.calibration, wire_timing=args.wire_timing,
                           faults=args.faults, viewer=args.viewer, log_level=level,
                           factory=args.factory, leader=args.leader, supply=args.supply,
                           variant=args.variant,
                           cube=[c if len(c) != 2 else (*c, args.cube_yaw)
                                 for c in args.cube or []],
                           base_height=args.base_height, cameras=args.camera,
                           camera_size=args.camera_size, camera_fps=args.camera_fps,
                           target=args.target,
                           initial=None if args.initial is None else dict(
                               zip(JOINTS, args.initial, strict=True)))
    except (CalibrationError, JointLimitError, CubePositionError, FaultSpecError, OpenCVMissing,
            RenderSettingError, VirtualSO101Error) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    link = None
    with arm:
        try:
            link = make_link(args.link, arm.port) if args.link else None
            print(arm.port, flush=True)
            for name, address in arm.camera_addresses.items():
                print(f"camera {name}: {address}", flush=True)
            logger.warning("virtual SO-101 serving on %s%s (wire timing %s); commands on stdin "
                           "(`help`), Ctrl-C to stop", arm.port, f" = {link}" if link else "",
                           "on" if args.wire_timing else "off")
            if not shell.serve(arm, sys.stdin, sys.stdout):
                arm._process.wait()  # stdin ended: serve until Ctrl-C
        except VirtualSO101Error as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            logger.warning("stopping")
        finally:
            if link is not None:
                remove_link(link, arm.port)
    return 0


if __name__ == "__main__":
    sys.exit(main())
