"""A virtual SO-101: six Feetech STS3215 servos on a pseudo-terminal, driving a MuJoCo arm.

lerobot's unmodified ``FeetechMotorsBus`` (and ``SO101Follower``) connect to
:attr:`VirtualSO101.port` exactly as to a real arm::

    from virtual_so101 import VirtualSO101, DEFAULT_CALIBRATION_PATH

    with VirtualSO101(calibration=DEFAULT_CALIBRATION_PATH) as arm:
        bus = FeetechMotorsBus(port=arm.port, motors=..., calibration=...)
        bus.connect()                       # PING, model 777, firmware 3.10
        bus.sync_write("Goal_Position", {"elbow_flex": 30.0, ...})
        arm.joint_positions()               # measured in MuJoCo [deg], gripper [0, 100]

Command line: ``python virtual_so101.py [--calibration PATH] [--viewer]
[--wire-timing] [--faults SPEC]`` prints the pty path as the first line of
stdout, then logs to stderr and serves until Ctrl-C.

Design
------
- One emulator process (a fresh interpreter, as multiprocessing's "spawn",
  started with subprocess so the caller's ``__main__`` is not re-run) holds
  the pty, the servo registers and the MuJoCo simulation of
  ``model/scene.xml`` in a single-threaded event loop: it answers the bus
  first and steps the physics (the model's 4 ms steps) to keep up with the wall clock in
  between. Nothing of the emulator runs in the client's process (lerobot
  busy-polls the port; a Python thread there slows it, and a second thread in
  the emulator would fight for its GIL). The parent object talks to it over a
  socket pair. Measured on 2 busy cores (load 3), a 6-motor sync_read +
  sync_write cycle of lerobot: 0.36-0.38 ms median without wire timing
  (lerobot's own cost 0.13 ms, the emulator 0.23-0.25 ms), 1.06-1.24 ms with
  it (0.88 ms of wire); see :func:`measure_cycle`.
- Protocol 0 (``FF FF ID LEN INST P.. CHK``): PING (also broadcast: every servo
  answers, in id order), READ, WRITE, SYNC_READ (replies in the request's id
  order), SYNC_WRITE and broadcast WRITE (never answered). Packets with a bad
  checksum are ignored, as a servo does. REG_WRITE/ACTION/RESET are not
  emulated (lerobot does not send them): they are ignored.
- A servo only understands the host when the pty's baud rate (set by pyserial)
  equals its Baud_Rate register, so baud scans behave as on a real bus. (Rates
  termios cannot name, 128000 and 250000, read as "unchanged".) Wire timing
  uses the same rate.

Where it lives: :mod:`virtual_so101_emulator` (the emulator process and what
the registers do), :mod:`virtual_sts3215` (one servo's register memory),
:mod:`feetech_protocol` (packets, the control table, wire time) and
:mod:`virtual_so101_calibration` (the shipped calibration, ticks <-> joint angles; loading
and checking are :mod:`so101_calibration`'s, shared with the real arm).

Deviations from a real arm (deliberate, for testing):
- At power-up torque is ON, holding the initial pose (``torque_on_start``);
  a real STS3215 starts with torque off. Pass ``torque_on_start=False`` for the
  real behaviour (the arm then sags under gravity until torque is enabled).
- Return_Delay_Time starts at 0 (what lerobot's configure_motors writes), not
  the factory 250.
- Goal log times are ``time.time()`` [s] of the emulator process at the moment
  the write was applied.

Beyond the agreed API, :class:`VirtualSO101` also offers ``commanded_positions()``,
``set_torque()``, ``set_wire_timing()``, ``registers(joint)``, ``power_cycle()``,
``reply_stats()`` / ``clear_stats()`` and the ``torque_on_start`` argument.

Fault injection (``--faults`` / :meth:`VirtualSO101.inject`), comma-separated;
SERVO is an id or a joint name:
- ``drop:SERVO[:N]``: the next N replies (default 1) of the servo are not sent
  (lerobot: ConnectionError "... There is no status packet!").
- ``corrupt:SERVO[:N]``: the next N replies carry a wrong checksum
  (ConnectionError "... Incorrect status packet!").
- ``remove:SERVO``: the servo is off the bus (connect: RuntimeError
  "... Missing motor IDs ...").
- ``stall:SERVO``: the joint is blocked where it is; Present_Load rises
  (2000 per s, signed towards the goal) while the goal is off, and the overload
  bit (0x20) is set in its status once the load reaches Overload_Torque
  (read: RuntimeError "... Overload error!"; sync_read ignores status bits).
- ``firmware:[SERVO:]MAJOR.MINOR``: the servo (default id 1) reports that
  firmware (connect: RuntimeError "Some Motors use different firmware versions").
- ``outage:MS``: the whole bus is down for MS milliseconds from now: every
  request is lost (goals too) and nobody answers (a loose cable, a power dip).
- ``unplug``: the USB cable pulled out: the port vanishes (the client's next
  transaction fails with an OSError); the servos keep holding their last goals.
- ``latency:MS[:N]``: the next N replies (default 1) come MS milliseconds late
  (past lerobot's 50 ms timeout they arrive after it gave up).
- ``overload:SERVO``, ``overheat:SERVO``, ``voltage:SERVO``: the servo sets that
  status error bit in every reply and its Status register (read: RuntimeError
  "... Overload error!" and so on; sync_read ignores status bits).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import socket
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Mapping
from multiprocessing.connection import Connection
from pathlib import Path

from feetech_protocol import BITS_PER_BYTE, INST_SYNC_READ, cycle_wire_bytes, status_packet
from so101_calibration import MOTOR_IDS
from virtual_so101_calibration import (
    DEFAULT_CALIBRATION_PATH,
    CalibrationError,
    load_calibration,
    make_default_calibration,
)

_HERE = Path(__file__).resolve().parent

logger = logging.getLogger("virtual_so101")


class VirtualSO101Error(RuntimeError):
    """The virtual arm could not start or answer."""


class FaultSpecError(ValueError):
    """A fault specification does not follow the grammar."""


# --- faults -----------------------------------------------------------------------------------
FAULT_KINDS = ("drop", "corrupt", "remove", "stall", "firmware", "outage", "unplug", "latency",
               "overload", "overheat", "voltage")
MAX_FAULT_MS = 60_000  # longest outage or latency [ms]


def parse_faults(spec: str | None, calibration: Mapping[str, Mapping[str, int]]) -> list[tuple]:
    """Parse a fault specification (grammar in the module docstring).

    Returns:
        A list of (kind, servo_id, argument) tuples.

    Raises:
        FaultSpecError: naming the bad item and the grammar.
    """
    grammar = ("drop:SERVO[:N], corrupt:SERVO[:N], remove:SERVO, stall:SERVO, "
               "firmware:[SERVO:]MAJOR.MINOR, outage:MS, unplug, latency:MS[:N], "
               "overload:SERVO, overheat:SERVO, voltage:SERVO (SERVO = id or joint name, "
               f"MS in 1..{MAX_FAULT_MS}), comma-separated")
    ids = {name: int(entry["id"]) for name, entry in calibration.items()}

    def servo(token: str, item: str) -> int:
        if token in ids:
            return ids[token]
        if token.isdigit() and int(token) in ids.values():
            return int(token)
        raise FaultSpecError(f"Fault '{item}': unknown servo '{token}'; use an id in "
                             f"{sorted(ids.values())} or a joint in {list(ids)}.")

    faults = []
    for item in (s.strip() for s in (spec or "").split(",")):
        if not item:
            continue
        kind, *args = item.split(":")
        if kind not in FAULT_KINDS:
            raise FaultSpecError(f"Unknown fault '{item}'. Grammar: {grammar}.")
        try:
            if kind == "firmware":
                if len(args) == 1:
                    args = [str(min(ids.values())), args[0]]
                major, minor = (int(x) for x in args[1].split("."))
                if not (0 <= major <= 255 and 0 <= minor <= 255) or len(args) != 2:
                    raise ValueError
                faults.append((kind, servo(args[0], item), (major, minor)))
            elif kind == "unplug":
                if args:
                    raise ValueError
                faults.append((kind, None, None))
            elif kind in ("outage", "latency"):
                milliseconds = float(args[0])
                count = int(args[1]) if len(args) == 2 else 1
                if not (0 < milliseconds <= MAX_FAULT_MS) or count < 1 or len(args) > 2 \
                        or (kind == "outage" and len(args) != 1):
                    raise ValueError
                faults.append((kind, None, milliseconds if kind == "outage"
                               else (milliseconds, count)))
            elif kind in ("drop", "corrupt"):
                count = int(args[1]) if len(args) == 2 else 1
                if len(args) not in (1, 2) or count < 1:
                    raise ValueError
                faults.append((kind, servo(args[0], item), count))
            else:
                if len(args) != 1:
                    raise ValueError
                faults.append((kind, servo(args[0], item), None))
        except FaultSpecError:
            raise
        except (ValueError, IndexError):
            raise FaultSpecError(f"Bad fault '{item}'. Grammar: {grammar}.") from None
    return faults


# =============================================================================================
# Parent side
# =============================================================================================
class VirtualSO101:
    """A virtual SO-101 on a pseudo-terminal (see the module docstring).

    The emulator process starts in the constructor; use it as a context manager
    (or call :meth:`close`) to stop it.

    Args:
        calibration: lerobot calibration JSON path or dict (default: the shipped one).
        wire_timing: delay replies by their byte time at the host's baud rate
            (10 bits a byte) plus Return_Delay_Time (2 us a unit).
        faults: fault specification to apply from power-up (module docstring).
        viewer: show the arm in MuJoCo's passive viewer (needs a display).
        initial: user-units configuration ([deg], gripper [0, 100]) to start
            at; default the model's "home" keyframe.
        torque_on_start: servos hold the initial pose from power-up (default;
            a real STS3215 starts limp).
        log_level: logging level of the emulator process.
        startup_timeout: [s] to wait for the emulator to come up.

    Raises:
        CalibrationError: the calibration is unusable.
        FaultSpecError: ``faults`` does not parse.
        VirtualSO101Error: no display for the viewer, or the emulator failed to start.
        so101_motion.JointLimitError: ``initial`` is outside the joint limits.
    """

    def __init__(self, calibration: str | Path | Mapping = DEFAULT_CALIBRATION_PATH,
                 wire_timing: bool = False, faults: str | None = None, viewer: bool = False,
                 initial: Mapping[str, float] | None = None, torque_on_start: bool = True,
                 log_level: int = logging.WARNING, startup_timeout: float = 60.0):
        self.calibration = load_calibration(calibration)
        self._ids = {name: entry["id"] for name, entry in self.calibration.items()}
        parsed = parse_faults(faults, self.calibration)
        if viewer and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise VirtualSO101Error("--viewer needs a display (DISPLAY or WAYLAND_DISPLAY is "
                                    "not set). Fix: run without the viewer, or on a desktop.")
        options = {"calibration": self.calibration, "wire_timing": wire_timing,
                   "faults": parsed, "viewer": viewer,
                   "initial": dict(initial) if initial is not None else None,
                   "torque_on_start": torque_on_start, "log_level": log_level}
        # A fresh interpreter (as multiprocessing's "spawn", but without re-running
        # the caller's __main__, so scripts without a __main__ guard work too).
        parent_sock, child_sock = socket.socketpair()
        self._lock = threading.Lock()
        code = (f"import sys; sys.path.insert(0, {str(_HERE)!r}); import virtual_so101_emulator; "
                f"virtual_so101_emulator.emulator_main({child_sock.fileno()})")
        self._process = subprocess.Popen([sys.executable, "-c", code],
                                         pass_fds=(child_sock.fileno(),), stdin=subprocess.DEVNULL)
        child_sock.close()
        self._conn = Connection(parent_sock.detach())
        self._conn.send(options)
        if not self._conn.poll(startup_timeout):
            self._process.kill()
            self._process.wait()
            raise VirtualSO101Error(f"The emulator did not start within {startup_timeout} s.")
        try:
            status, value = self._conn.recv()
        except EOFError:
            raise VirtualSO101Error("The emulator process died while starting.") from None
        if status == "err":
            self._process.wait(5)
            raise value
        self.port: str = value
        logger.info("virtual SO-101 on %s (pid %d)", self.port, self._process.pid)

    @property
    def pid(self) -> int:
        """Process id of the emulator process."""
        return self._process.pid

    # --- lifecycle ------------------------------------------------------------------------
    def __enter__(self) -> VirtualSO101:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop the emulator process (idempotent)."""
        if self._process is None:
            return
        try:
            with self._lock:
                self._conn.send(("close", ()))
                if self._conn.poll(5):
                    self._conn.recv()
        except (OSError, EOFError, BrokenPipeError):
            pass
        try:
            self._process.wait(5)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait(5)
        self._conn.close()
        self._process = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001, S110 - interpreter shutdown
            pass

    def _call(self, name: str, *args):
        if self._process is None:
            raise VirtualSO101Error("The virtual SO-101 is closed.")
        with self._lock:
            try:
                self._conn.send((name, args))
                status, value = self._conn.recv()
            except (EOFError, OSError) as exc:
                raise VirtualSO101Error("The emulator process is gone.") from exc
        if status == "err":
            raise value
        return value

    # --- public API -----------------------------------------------------------------------
    def joint_positions(self) -> dict[str, float]:
        """Measured joint positions in the simulation: [deg], gripper [0, 100]."""
        return self._call("joint_positions")

    def commanded_positions(self) -> dict[str, float]:
        """The position actuators' targets (from the goals received): [deg], gripper [0, 100]."""
        return self._call("commanded_positions")

    def goal_log(self) -> list[tuple[float, int, int]]:
        """Every Goal_Position write received, in order: (time.time() [s], servo id, raw ticks).

        The last ``virtual_so101_emulator.GOAL_LOG_LENGTH`` writes are kept.
        """
        return self._call("goal_log")

    def clear_goal_log(self) -> None:
        """Forget the Goal_Position writes logged so far."""
        self._call("clear_goal_log")

    def torque_enabled(self) -> dict[str, bool]:
        """Joint name -> whether its servo's Torque_Enable is set."""
        return self._call("torque_enabled")

    def inject(self, spec: str) -> None:
        """Inject faults (grammar in the module docstring), e.g. ``"drop:3:5,corrupt:2"``."""
        self._call("inject", parse_faults(spec, self.calibration))

    def clear_faults(self) -> None:
        """Remove every fault (removed servos return, firmware back to 3.10, stalls released)."""
        self._call("clear_faults")

    def set_pose(self, cfg: Mapping[str, float]) -> None:
        """Teleport the arm to ``cfg`` ([deg], gripper [0, 100]) at rest; goals follow.

        Raises:
            so101_motion.JointLimitError: a value is outside the joint limits.
        """
        self._call("set_pose", dict(cfg))

    def set_torque(self, enabled: bool, joints: list[str] | None = None) -> None:
        """Set Torque_Enable as the host would (test setup); ``joints`` default: all.

        Enabling holds each joint where it is (Goal_Position := Present_Position).
        """
        unknown = [j for j in joints or () if j not in self._ids]
        if unknown:
            raise KeyError(f"Unknown joints {unknown}; joints are {list(self._ids)}.")
        self._call("set_torque", bool(enabled), list(joints) if joints else None)

    def set_wire_timing(self, enabled: bool) -> None:
        """Switch wire timing on or off while running."""
        self._call("set_wire_timing", enabled)

    def registers(self, joint: str) -> dict[str, int]:
        """The named registers of a joint's servo (decoded, for tests and debugging)."""
        if joint not in self._ids:
            raise KeyError(f"Unknown joint '{joint}'; joints are {list(self._ids)}.")
        return self._call("registers", joint)

    def power_cycle(self) -> None:
        """Cut the servos' power: RAM to factory values, EEPROM to what was saved (Lock = 0)."""
        self._call("power_cycle")

    def reply_stats(self) -> dict[str, float]:
        """Emulator health: replies sent, late ones, timing [ms].

        Keys: ``replies``; ``late_replies`` (sent > 45 ms after the request:
        lerobot may have given up); ``lateness_median_ms`` / ``_p99_ms`` /
        ``_max_ms`` (behind each reply's due time: the wire time with wire
        timing, else the request's arrival); ``max_loop_delay_ms`` (longest the
        emulator process was kept off the CPU past a wake-up); ``sim_time_s``,
        ``wall_time_s`` (the simulation keeps real time when they agree).
        """
        return self._call("reply_stats")

    def clear_stats(self) -> None:
        """Reset :meth:`reply_stats`."""
        self._call("clear_stats")


# =============================================================================================
# Measurement and command line
# =============================================================================================
SO101_MOTORS = {name: ("sts3215", ("range_0_100" if name == "gripper" else "degrees"))
                for name in MOTOR_IDS}


def make_bus(arm: VirtualSO101, degrees: bool = True):
    """A lerobot ``FeetechMotorsBus`` for the arm with its calibration (needs lerobot).

    Args:
        arm: the virtual arm.
        degrees: arm joints in DEGREES (else RANGE_M100_100); the gripper is RANGE_0_100.
    """
    from lerobot.motors import Motor, MotorCalibration, MotorNormMode
    from lerobot.motors.feetech import FeetechMotorsBus

    body = MotorNormMode.DEGREES if degrees else MotorNormMode.RANGE_M100_100
    motors = {name: Motor(entry["id"], "sts3215",
                          MotorNormMode.RANGE_0_100 if name == "gripper" else body)
              for name, entry in arm.calibration.items()}
    calibration = {name: MotorCalibration(**entry) for name, entry in arm.calibration.items()}
    return FeetechMotorsBus(port=arm.port, motors=motors, calibration=calibration)


class _LoopbackSerial:
    """A stand-in for the bus's pyserial port that answers SYNC_READs instantly, in-process.

    Timing lerobot against it gives the host's own cost of a cycle (packing,
    parsing, decoding), which a real arm costs too.
    """

    def __init__(self, replies: bytes):
        self.replies = replies
        self.buffer = bytearray()
        self.is_open = True

    def write(self, data) -> int:
        if len(data) > 4 and data[4] == INST_SYNC_READ:
            self.buffer += self.replies
        return len(data)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self.buffer[:size])
        del self.buffer[:size]
        return out

    @property
    def in_waiting(self) -> int:
        return len(self.buffer)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self.buffer.clear()

    def close(self) -> None:
        self.is_open = False


def _time_cycles(bus, n: int, warmup: int, on_warm=None) -> list[float]:
    """Durations [s] of n sync_read(Present_Position) + sync_write(Goal_Position) cycles."""
    times = []
    for i in range(n + warmup):
        t0 = time.perf_counter()
        present = bus.sync_read("Present_Position", normalize=False)
        bus.sync_write("Goal_Position", present, normalize=False)
        if i == warmup - 1 and on_warm is not None:
            on_warm()
        if i >= warmup:
            times.append(time.perf_counter() - t0)
    return sorted(times)


def measure_cycle(n: int = 1000, wire_timing: bool = True, arm: VirtualSO101 | None = None,
                  warmup: int = 50) -> dict[str, float]:
    """Time lerobot's 6-motor sync_read + sync_write cycle against the virtual arm (needs lerobot).

    Each cycle reads Present_Position and writes it back as Goal_Position (raw
    ticks), as a teleoperation loop does. The same cycles are then timed
    against an in-process loopback port, which gives lerobot's own (host) cost;
    what remains of the cycle after the wire time and the host cost is what
    the emulator adds (its wake-up and processing).

    Args:
        n: cycles to time.
        wire_timing: emulate the wire's byte time.
        arm: an existing virtual arm (else one is started and closed).
        warmup: cycles run before timing.

    Returns:
        ``cycle_median_ms`` / ``cycle_p99_ms`` (client side); ``wire_ms``
        (88 bytes x 10 bits at the bus's baud rate, 0 without wire timing);
        ``overhead_median_ms`` / ``_p99_ms`` (cycle - wire); ``host_median_ms``
        (lerobot's cost, loopback); ``emulator_added_median_ms`` (cycle median -
        wire - host median: without wire timing, the emulator's whole share,
        i.e. wake-ups, processing and the pty; with wire timing the host's work
        partly overlaps the sync_write's wire time, so it reads lower); the
        emulator's lateness behind each reply's due time
        (``emulator_lateness_median_ms`` / ``_p99_ms``) and ``late_replies``.
    """
    own = arm is None
    arm = arm or VirtualSO101(wire_timing=wire_timing)
    bus = None
    try:
        arm.set_wire_timing(wire_timing)
        bus = make_bus(arm)
        bus.connect()
        times = _time_cycles(bus, n, warmup, on_warm=arm.clear_stats)
        stats = arm.reply_stats()
        wire_ms = cycle_wire_bytes() * BITS_PER_BYTE / bus.port_handler.getBaudRate() * 1e3
        wire_ms = wire_ms if wire_timing else 0.0
        present = bus.sync_read("Present_Position", normalize=False)
        replies = b"".join(status_packet(bus.motors[name].id, 0, value.to_bytes(2, "little"))
                           for name, value in present.items())
        serial_port = bus.port_handler.ser
        bus.port_handler.ser = _LoopbackSerial(replies)
        try:
            host = _time_cycles(bus, n, warmup)
        finally:
            bus.port_handler.ser = serial_port
        median, p99 = 1e3 * statistics.median(times), 1e3 * times[int(0.99 * (len(times) - 1))]
        host_median = 1e3 * statistics.median(host)
        return {
            "cycles": n, "wire_timing": wire_timing, "wire_ms": wire_ms,
            "cycle_median_ms": median, "cycle_p99_ms": p99,
            "overhead_median_ms": median - wire_ms, "overhead_p99_ms": p99 - wire_ms,
            "host_median_ms": host_median,
            "emulator_added_median_ms": median - wire_ms - host_median,
            "emulator_lateness_median_ms": stats["lateness_median_ms"],
            "emulator_lateness_p99_ms": stats["lateness_p99_ms"],
            "late_replies": stats["late_replies"],
        }
    finally:
        if bus is not None:
            bus.disconnect(disable_torque=False)
        if own:
            arm.close()


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
    parser.add_argument("--write-default-calibration", metavar="PATH",
                        help="write the calibration derived from the model to PATH and exit")
    parser.add_argument("-v", "--verbose", action="store_true", help="log every fault and start-up")
    args = parser.parse_args(argv)
    level = logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=level, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    if args.write_default_calibration:
        import so101_mujoco_utils

        calibration = make_default_calibration(so101_mujoco_utils.load_model())
        Path(args.write_default_calibration).write_text(json.dumps(calibration, indent=4) + "\n")
        return 0
    if args.viewer and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print("error: --viewer needs a display (DISPLAY or WAYLAND_DISPLAY is not set); "
              "run without --viewer.", file=sys.stderr)
        return 2
    try:
        arm = VirtualSO101(calibration=args.calibration, wire_timing=args.wire_timing,
                           faults=args.faults, viewer=args.viewer, log_level=level)
    except (CalibrationError, FaultSpecError, VirtualSO101Error) as exc:
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
