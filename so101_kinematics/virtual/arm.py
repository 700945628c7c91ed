"""A virtual SO-101: six Feetech STS3215 servos on a pseudo-terminal, driving a MuJoCo arm.

lerobot's unmodified ``FeetechMotorsBus`` (and ``SO101Follower``) connect to
:attr:`VirtualSO101.port` exactly as to a real arm::

    from so101_kinematics.virtual.arm import VirtualSO101, DEFAULT_CALIBRATION_PATH

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
  between; with ``sim_clock=True``, to keep up with the program's simulated time instead
  (:attr:`VirtualSO101.clock`, ``virtual/sim_clock.py``). Nothing of the emulator runs in
  the client's process (lerobot busy-polls the port; a Python thread there slows it, and
  a second thread in the emulator would fight for its GIL). The parent object talks to it over a
  socket pair. Measured on 2 busy cores (load 3), a 6-motor sync_read +
  sync_write cycle of lerobot: 0.36-0.38 ms median without wire timing
  (lerobot's own cost 0.13 ms, the emulator 0.23-0.25 ms), 1.06-1.24 ms with
  it (0.88 ms of wire); see :func:`measure_cycle`.
- Protocol 0 (``FF FF ID LEN INST P.. CHK``): PING (also broadcast: every servo
  answers, in id order), READ, WRITE, SYNC_READ (replies in the request's id
  order), SYNC_WRITE and broadcast WRITE (never answered), and what other
  clients send: REG_WRITE + ACTION, RESET, BACKUP, RESTART, calibration
  (``virtual/instructions.py``; the coverage table is docs/virtual_arm_protocol.md).
  Packets with a bad checksum and unknown instructions are ignored, as a servo
  does. Servos sharing an ID all obey and their replies collide.
- A servo only understands the host when the pty's baud rate (set by pyserial)
  equals its Baud_Rate register, so baud scans behave as on a real bus. (Rates
  termios cannot name, 128000 and 250000, read as "unchanged".) Wire timing
  uses the same rate.

Where it lives: :mod:`so101_kinematics.virtual.emulator` (the emulator process and what
the registers do), :mod:`so101_kinematics.virtual.servo_memory` (one servo's register memory),
:mod:`so101_kinematics.virtual.protocol` (packets, the control table, wire time) and
:mod:`so101_kinematics.virtual.shipped_calibration` (the shipped calibration, ticks <-> joint
angles; loading and checking are :mod:`so101_kinematics.calibration`'s, shared with the real arm).

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

import logging
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from multiprocessing.connection import Connection
from pathlib import Path

from so101_kinematics.display import choose_gl_backend, has_display
from so101_kinematics.errors import VirtualSO101Error
from so101_kinematics.paths import REPO
from so101_kinematics.sensors.cube_wire import CubeReading
from so101_kinematics.servo import KIT_SUPPLY_V
from so101_kinematics.sim.render import check_frame_size
from so101_kinematics.virtual.camera_server import CAMERA_FPS, check_camera_fps, require_cv2
from so101_kinematics.virtual.cubes import (
    check_base_height,
    check_cube_position,
    check_cubes,
    check_target_position,
)
from so101_kinematics.virtual.electrical import SUPPLY_V, THERMAL_TIME_S
from so101_kinematics.virtual.faults import parse_faults
from so101_kinematics.virtual.rules import check_rules
from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH, load_calibration
from so101_kinematics.virtual.sim_clock import SimClock

__all__ = ["VirtualSO101"]

logger = logging.getLogger("virtual_so101")


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
        cube: (x [m], y [m][, yaw [deg]]): the simulator's free cube resting on the
            table there, in the base frame, or a list of them (stacking); each pose is
            readable through the bus's cube sensor (``so101_kinematics.sensors.cube_wire``)
            and :meth:`cube`.
        base_height: the table is this far below the base frame [m] (the lab's
            15 mm mount), in [0, 0.05].
        startup_timeout: [s] to wait for the emulator to come up.
        factory: six factory-fresh servos (ID 1, 1 Mbit/s, no calibration),
            plugged in one at a time, gripper first (``lerobot-setup-motors``).
        leader: a leader arm: limp from power-up, a hand resting on it (it
            does not sag) that ``hand_move`` moves.
        supply: [V] the servos' supply voltage (``virtual/electrical.py``); default: the
            course's, 12 V for the follower (assignment 3), 5 V for a ``leader`` (assignment 2).
        variant: the servos' STS3215 variant (``so101_kinematics.servo.VARIANTS``; default:
            what ``supply`` implies).
        thermal_time_s: [s] the servos' thermal time constant.
        rules: where Feetech's sources disagree, the other choice (``virtual/rules.py``:
            ``goal_time``, ``limp_goal``, ``locked_eeprom``, ``restart_reply``).
        cameras: names of the model's cameras to serve (``overhead``, ``wrist``, ...), each
            rendered live and served as MJPEG over HTTP (``virtual/camera_server.py``); their
            addresses are :attr:`camera_addresses`.
        camera_size: (width, height) [px] of the served frames.
        camera_fps: [frames/s] served while a client watches.
        target: (x [m], y [m][, yaw [deg]]): the target tag (``sim/tag_textures.py``) on the
            table there, in the base frame, drawn for the served cameras (which also see the
            first cube's tag); visual only, the physics has no such body.
        sim_clock: run the arm on a simulated clock the program drives (:attr:`clock`,
            ``virtual/sim_clock.py``): time passes only when it calls ``clock.sleep``, and
            the physics takes every step up to it, however busy the machine. Default: the
            wall clock.

    Raises:
        CalibrationError: the calibration is unusable.
        FaultSpecError: ``faults`` does not parse.
        VirtualSO101Error: no display for the viewer, or the emulator failed to start.
        JointLimitError: ``initial`` is outside the joint limits.
        RenderSettingError: an unknown camera (the message lists the model's) or size.
        OpenCVMissing: cameras asked for without OpenCV.
    """

    def __init__(self, calibration: str | Path | Mapping = DEFAULT_CALIBRATION_PATH,
                 wire_timing: bool = False, faults: str | None = None, viewer: bool = False,
                 initial: Mapping[str, float] | None = None, torque_on_start: bool = True,
                 log_level: int = logging.WARNING, startup_timeout: float = 60.0,
                 factory: bool = False, leader: bool = False, supply: float | None = None,
                 thermal_time_s: float = THERMAL_TIME_S,
                 cube=None, base_height: float = 0.0, variant: str | None = None,
                 rules: Mapping[str, str] | None = None, cameras: Sequence[str] = (),
                 camera_size: Sequence[int] = (640, 480), camera_fps: float = CAMERA_FPS,
                 target: Sequence[float] | None = None, sim_clock: bool = False):
        self.calibration = load_calibration(calibration)
        supply = (KIT_SUPPLY_V if leader else SUPPLY_V) if supply is None else supply
        chosen_rules = check_rules(rules)
        cubes, base_height = check_cubes(cube), check_base_height(base_height)
        self._ids = {name: entry["id"] for name, entry in self.calibration.items()}
        parsed = parse_faults(faults, self.calibration)
        if viewer and not has_display():
            raise VirtualSO101Error("--viewer needs a display (DISPLAY or WAYLAND_DISPLAY is "
                                    "not set). Fix: run without the viewer, or on a desktop.")
        options = {"calibration": self.calibration, "wire_timing": wire_timing,
                   "faults": parsed, "viewer": viewer,
                   "initial": dict(initial) if initial is not None else None,
                   "torque_on_start": torque_on_start and not (factory or leader),
                   "log_level": log_level, "factory": factory, "hand_holds": factory or leader,
                   "supply": float(supply), "thermal_time_s": float(thermal_time_s),
                   "cubes": cubes, "base_height": base_height, "variant": variant,
                   "rules": chosen_rules, "cameras": list(cameras),
                   "camera_size": check_frame_size(camera_size, "camera size", even=False),
                   "camera_fps": check_camera_fps(camera_fps),
                   "target": check_target_position(target) if target is not None else None}
        env = dict(os.environ)
        if cameras:
            require_cv2()  # one line before a start-up, not a traceback from the child
            choose_gl_backend(env)  # headless: EGL (MuJoCo reads it when imported)
        # A fresh interpreter (as multiprocessing's "spawn", but without re-running
        # the caller's __main__, so scripts without a __main__ guard work too).
        parent_sock, child_sock = socket.socketpair()
        self._lock = threading.Lock()
        code = (f"import sys; sys.path.insert(0, {str(REPO)!r}); "
                "from so101_kinematics.virtual import emulator; "
                f"emulator.emulator_main({child_sock.fileno()})")
        passed = [child_sock]
        self.clock: SimClock | None = None
        """The simulated clock (``clock()``, ``sleep(seconds)``, ``spin``), or None: the wall's."""
        if sim_clock:
            ours, theirs = socket.socketpair()
            self.clock = SimClock(ours)
            options["sim_clock_fd"] = theirs.fileno()
            passed.append(theirs)
        self._process = subprocess.Popen([sys.executable, "-c", code],
                                         pass_fds=[p.fileno() for p in passed],
                                         stdin=subprocess.DEVNULL, env=env)
        for sock in passed:
            sock.close()
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
        self.camera_addresses: dict[str, str] = self._call("camera_addresses") if cameras else {}
        """Camera name -> the address ``cv2.VideoCapture`` opens (``http://127.0.0.1:PORT/NAME.mjpg``)."""
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
        if self.clock is not None:
            self.clock.close()
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

        The last ``emulator.GOAL_LOG_LENGTH`` writes are kept.
        """
        return self._call("goal_log")

    def clear_goal_log(self) -> None:
        """Forget the Goal_Position writes logged so far."""
        self._call("clear_goal_log")

    def torque_enabled(self) -> dict[str, bool]:
        """Joint name -> whether its servo's Torque_Enable is set."""
        return self._call("torque_enabled")

    def cube(self, index: int = 0) -> CubeReading | None:
        """Where cube ``index`` is (centre [m], tilt [deg], held), or None without it."""
        return self._call("cube", index)

    def place_cube(self, x: float, y: float, yaw_deg: float = 0.0, index: int = 0) -> None:
        """Put cube ``index`` on the table at (x, y) [m] in the base frame, turned ``yaw_deg``.

        Raises:
            ValueError: no such cube (start with ``cube=``), or the jaws hold it.
        """
        x, y, yaw_deg = check_cube_position((x, y, yaw_deg))
        self._call("place_cube", x, y, yaw_deg, index)

    def remove_cube(self, index: int = 0) -> None:
        """Take cube ``index`` off the table (the sensor then reports none there)."""
        self._call("remove_cube", index)

    def place_target(self, x: float, y: float, yaw_deg: float = 0.0) -> None:
        """Move the target tag (``target=``; drawn in the cameras) to (x, y) [m], ``yaw_deg``.

        Raises:
            ValueError: no target tag or no camera (start with ``target=`` and ``cameras=``).
        """
        x, y, yaw_deg = check_target_position((x, y, yaw_deg))
        self._call("place_target", x, y, yaw_deg)

    def hide_target(self) -> None:
        """Hide the target tag from the cameras (as a hand over it); ``place_target`` shows it."""
        self._call("place_target", 0.0, 0.0, 0.0, True)

    def inject(self, spec: str) -> None:
        """Inject faults (grammar in the module docstring), e.g. ``"drop:3:5,corrupt:2"``."""
        self._call("inject", parse_faults(spec, self.calibration))

    def clear_faults(self) -> None:
        """Remove every fault (removed servos return, firmware back to 3.10, stalls released)."""
        self._call("clear_faults")

    def set_pose(self, cfg: Mapping[str, float]) -> None:
        """Teleport the arm to ``cfg`` ([deg], gripper [0, 100]) at rest; goals follow.

        Raises:
            JointLimitError: a value is outside the joint limits.
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

    def camera_stats(self) -> dict[str, float]:
        """The served cameras' figures; empty without cameras.

        Keys: ``frames`` drawn, ``skipped`` (the renderer was busy), mean ``render_ms`` (all
        watched cameras, with the JPEG encoding) and ``latency_ms`` (from the state's copy to
        the frame ready to send).
        """
        return self._call("camera_stats")

    def clear_stats(self) -> None:
        """Reset :meth:`reply_stats`."""
        self._call("clear_stats")

    # --- a hand on the arm, the bus's wiring and supply (virtual/hand.py, virtual/shell.py) --
    def hand_move(self, waypoints: list[Mapping[str, float]]) -> float:
        """A hand moves the limp arm through ``waypoints`` ([deg], gripper [0, 100]).

        Returns:
            The motion's duration [s] (it runs in the background; see :meth:`hand_wait`).

        Raises:
            ValueError: a joint is torqued or unknown, a target outside its
                limits, or the path would go into the table.
        """
        return self._call("hand_move", [dict(w) for w in waypoints])

    def hand_wait(self, settle: float = 0.3) -> None:
        """Wait until the hand's motion has ended, then ``settle`` [s] more."""
        sleep = time.sleep if self.clock is None else self.clock.sleep
        while (remaining := self._call("hand_remaining")) > 0:
            sleep(min(0.05, remaining))
        sleep(settle)

    def hand_release(self) -> None:
        """The hand lets go of the arm (a limp arm then sags under gravity)."""
        self._call("hand_release")

    def plug(self) -> str:
        """Factory mode: plug the next servo into the bus; returns its joint's name."""
        return self._call("plug")

    def set_supply(self, volts: float) -> None:
        """Set the servos' supply voltage [V] (Present_Voltage, the voltage error bit)."""
        self._call("set_supply", float(volts))
