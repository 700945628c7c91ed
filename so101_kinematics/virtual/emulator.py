"""The virtual SO-101's emulator process: six STS3215s on a pty, a MuJoCo arm behind them.

It runs in its own interpreter, started by :class:`so101_kinematics.virtual.arm.VirtualSO101`
(entry point :func:`emulator_main`), and serves the bus and steps the physics
in one single-threaded event loop; the parent's commands arrive on a socket pair. The
physics keeps up with the wall clock, or, with ``sim_clock``, with the program's simulated
time (``virtual/sim_clock.py``, on a second socket pair).
What the instructions do is ``virtual/instructions.py``'s, what the registers do to the
arm ``virtual/registers.py``'s.
"""
from __future__ import annotations

import fcntl
import logging
import os
import select
import signal
import struct
import termios
import time
import tty
from collections import deque
from multiprocessing.connection import Connection

from so101_kinematics.virtual.commands import ParentCommands
from so101_kinematics.virtual.electrical import SUPPLY_V, THERMAL_TIME_S
from so101_kinematics.virtual.hand import Hand
from so101_kinematics.virtual.instructions import BusInstructions
from so101_kinematics.virtual.protocol import BROADCAST_ID, INST_SYNC_READ, take_packets
from so101_kinematics.virtual.registers import GOAL_LOG_LENGTH, ServoRegisters
from so101_kinematics.virtual.rules import check_rules
from so101_kinematics.virtual.servo_memory import VirtualServo
from so101_kinematics.virtual.sim_clock import LEROBOT_TIMEOUT_S, ClockFollower

__all__: list[str] = []

logger = logging.getLogger("virtual_so101")

SIM_IDLE_S = 1 / 60  # [s] the simulated clock's loop wakes this often for a viewer or cameras
TCGETS2 = 0x802C542A  # Linux ioctl: struct termios2, whose c_ospeed is the exact rate [bit/s]


def pty_baud_rate(fd: int) -> int | None:
    """The baud rate [bit/s] the client set on the pty (any rate, standard or not), or None."""
    try:
        return struct.unpack_from("I", fcntl.ioctl(fd, TCGETS2, bytes(44)), 40)[0]
    except OSError:  # not Linux: the standard rates only
        speed = termios.tcgetattr(fd)[5]
        return next((b for b in (4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800,
                                 500000, 576000, 921600, 1000000)
                     if getattr(termios, f"B{b}", None) == speed), None)


class _Emulator(BusInstructions, ServoRegisters, ParentCommands, Hand):
    """The event loop of the emulator process: the pty, the physics, the parent's commands."""

    def __init__(self, conn, options: dict):
        import mujoco

        import so101_kinematics.sim.scene as smu

        self.mujoco, self.smu = mujoco, smu
        self.conn = conn
        self.base_height = options.get("base_height", 0.0)  # the table below the base [m]
        if options.get("cubes") or self.base_height:  # the simulator's cubes, on its table
            from so101_kinematics.sim.cube import build_model

            self.m = build_model(cubes_at=options.get("cubes", ()), base_height=self.base_height)
        else:
            self.m = smu.load_model()
        self.d = mujoco.MjData(self.m)
        self.dt = float(self.m.opt.timestep)
        self.dt_ns = round(self.dt * 1e9)
        clock_fd = options.get("sim_clock_fd")  # virtual/sim_clock.py: the program's time
        self.sim_clock = None if clock_fd is None else ClockFollower(clock_fd)
        self.servos: dict[int, VirtualServo] = {}
        for joint, cal in options["calibration"].items():
            servo = VirtualServo(joint, cal, self.m)
            self.servos[servo.id] = servo
        self.by_joint = {s.joint: s for s in self.servos.values()}
        self.hand_path, self.hand_grip = [], {}
        self.supply = float(options.get("supply", SUPPLY_V))  # [V]
        self.voltage = round(10 * self.supply)  # [0.1 V] Present_Voltage, updated by the physics
        self.thermal_time_s = float(options.get("thermal_time_s", THERMAL_TIME_S))
        self.rules = check_rules(options.get("rules"))  # virtual/rules.py
        self.make_servo_bank(options.get("variant"))
        self.wire_timing = bool(options["wire_timing"])
        self.goal_log: deque[tuple[float, int, int]] = deque(maxlen=GOAL_LOG_LENGTH)
        self.lateness = deque(maxlen=20000)
        self.replies = 0
        self.late = 0
        self.max_gap = 0.0
        self.rx = bytearray()
        self.rx_partial_since = 0.0
        self.wire_free = 0.0
        self.host_baud = 1_000_000
        self.outage_until = 0.0  # [perf_counter s] the whole bus is silent until then
        self.latency = 0.0  # [s] extra delay of the next ``latency_left`` replies
        self.latency_left = 0
        self.unplugged = False
        self.listening: dict[int, VirtualServo] = {}
        if options["initial"] is None:
            mujoco.mj_resetDataKeyframe(self.m, self.d, self.m.key("home").id)
            mujoco.mj_forward(self.m, self.d)
        else:
            smu.set_initial_pose(self.d, options["initial"])
        self.factory_queue = []  # factory mode: servos not plugged in yet, next first
        if options.get("factory"):
            self.factory_reset()
        for servo in self.by_joint.values():
            servo.set("Torque_Enable", 1 if options["torque_on_start"] else 0)
            servo.sync_cache()
            self._apply_torque(servo)
            self._hold(servo)
        self.rest_in_place()  # powered up where it was put down: holding it, no sag
        if options.get("hand_holds"):  # a hand rests on the limp arm: it does not sag
            self.hand_move([])
        self.update_listening()
        self.inject(options["faults"])
        self.viewer = None
        if options["viewer"]:
            import mujoco.viewer

            self.viewer = mujoco.viewer.launch_passive(self.m, self.d)
        self.next_view = 0.0
        self.cameras = None
        if options.get("cameras"):  # virtual/camera_server.py: rendered, served over HTTP
            self.cameras = _camera_server(self.m, options)
        # The pty: keep the slave open (else the master reads EIO in a busy loop).
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.port = os.ttyname(self.slave)
        self.t0 = time.perf_counter()
        self.steps = 0

    def arm_time(self) -> float:
        """Now on the arm's clock [s]: the program's simulated time, else ``perf_counter``."""
        return time.perf_counter() if self.sim_clock is None else self.sim_clock.now

    # --- protocol -------------------------------------------------------------------------
    def serve_serial(self) -> None:
        """Answer any request already on the bus (called from long parent commands)."""
        if not self.unplugged:
            self.on_serial()

    def on_serial(self) -> None:
        try:
            chunk = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # EIO: no slave open (cannot happen while we hold one)
            time.sleep(0.001)
            return
        now = time.perf_counter()
        if self.arm_time() < self.outage_until:  # the bus is down: requests lost, no answers
            if self.sim_clock is not None:  # each request cost its asker lerobot's timeout
                self.rx += chunk
                for packet in take_packets(self.rx):
                    if _replies_awaited(packet):
                        self.sim_clock.charge(LEROBOT_TIMEOUT_S)
            self.rx.clear()
            return
        baud = pty_baud_rate(self.master) or 0  # 0: a rate no servo speaks
        if baud != self.host_baud:
            self.host_baud = baud
            self.update_listening()
        rx = self.rx
        if rx and now - self.rx_partial_since > 0.01:
            del rx[:2]  # a stale partial packet: a servo's byte timeout would discard it
        rx += chunk
        for packet in take_packets(rx):
            answered = self.replies
            self.handle(packet, now)
            if self.sim_clock is not None and self.replies - answered < _replies_awaited(packet):
                self.sim_clock.charge(LEROBOT_TIMEOUT_S)  # the host waited for a reply in vain
        if rx:
            self.rx_partial_since = now

    def run(self) -> None:
        self.conn.send(("ready", self.port))
        master, conn, follower = self.master, self.conn, self.sim_clock
        while True:
            now = time.perf_counter()
            watched = [conn] if self.unplugged else [master, conn]
            if follower is None:
                wake = max(now, self.t0 + (self.steps + 1) * self.dt)
                timeout = wake - now
            else:  # the physics waits for the program's time, not the wall clock's
                timeout = SIM_IDLE_S if self.viewer or self.cameras else None
                watched += [follower] if follower.open else []
            ready, _, _ = select.select(watched, [], [], timeout)
            if follower is None:  # how long past its wake-up time it got the CPU back
                self.max_gap = max(self.max_gap, time.perf_counter() - wake)
            if master in ready:
                self.on_serial()
            if conn in ready and not self.on_command():
                return
            if follower in ready:
                self.serve_serial()  # the requests sent before the sleep act first
                follower.receive()
            self.step_physics()
            if follower is not None:
                follower.acknowledge(self.steps * self.dt_ns)
            if self.cameras is not None:
                self.cameras.tick(self.d, time.perf_counter())

    def on_command(self) -> bool:
        """Obey one of the parent's commands; False when the emulator is to stop."""
        try:
            name, args = self.conn.recv()
        except (EOFError, OSError):
            return False
        if name == "close":
            self.conn.send(("ok", None))
            return False
        try:
            self.conn.send(("ok", self.command(name, args)))
        except Exception as exc:  # noqa: BLE001 - handed to the caller
            self.conn.send(("err", exc))
        return True


def _replies_awaited(packet: bytes) -> int:
    """How many replies a host waits for after ``packet``: one from an addressed servo.

    One per ID of a SYNC_READ, none after another broadcast.
    """
    target, inst, params = packet[2], packet[4], packet[5:-1]
    if target != BROADCAST_ID:
        return 1
    return max(0, len(params) - 2) if inst == INST_SYNC_READ else 0


def _camera_server(m, options: dict):
    """The cameras' server, drawing the emulator's scene with the render meshes and the tags.

    The first cube carries the cube tag and ``options["target"]`` lays the target tag: visual
    geoms of the drawn model only (the physics model has none; the positions are the same).
    """
    from so101_kinematics.sim.cube import build_model
    from so101_kinematics.virtual.camera_server import CameraServer

    render_model = build_model(cubes_at=options.get("cubes", ()),
                               base_height=options.get("base_height", 0.0), render_meshes=True,
                               tagged=True, target_at=options.get("target"))
    return CameraServer(m, render_model, options["cameras"], options["camera_size"],
                        options["camera_fps"])


def _raise_priority() -> None:
    """Ask for a higher CPU priority (nice -10) where allowed.

    The emulator sleeps most of the time but must answer within lerobot's
    50 ms timeout even on a machine busy with other work; a real servo does
    not share the host's CPU. At nice -5 (a third of the CPU share of -10)
    lerobot's own calibration tool still missed a reply beside CI's two test
    legs on 2 cores (2026-12-04, twice). Without the privilege this does nothing.
    """
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -10)
    except (OSError, AttributeError):
        pass


def _tighten_timer_slack() -> None:
    """Ask Linux for 1 us timer slack (default 50 us) so short sleeps are precise."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(29, 1000, 0, 0, 0)  # PR_SET_TIMERSLACK
    except (OSError, AttributeError):
        pass


def emulator_main(fd: int) -> None:
    """Entry point of the emulator process: ``fd`` is its end of the socket pair."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    _tighten_timer_slack()
    _raise_priority()
    conn = Connection(fd)
    options = conn.recv()
    logging.basicConfig(level=options.get("log_level", logging.WARNING),
                        format="%(asctime)s virtual_so101: %(message)s")
    try:
        emulator = _Emulator(conn, options)
    except Exception as exc:  # noqa: BLE001 - reported to the parent
        conn.send(("err", exc))
        return
    try:
        emulator.run()
    except KeyboardInterrupt:
        pass
    finally:
        if emulator.viewer is not None:
            emulator.viewer.close()
        if emulator.cameras is not None:
            emulator.cameras.close()
        if emulator.sim_clock is not None:
            emulator.sim_clock.close()
        if not emulator.unplugged:
            os.close(emulator.master)
            os.close(emulator.slave)
