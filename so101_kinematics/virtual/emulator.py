"""The virtual SO-101's emulator process: six STS3215s on a pty, a MuJoCo arm behind them.

It runs in its own interpreter, started by :class:`so101_kinematics.virtual.arm.VirtualSO101`
(entry point :func:`emulator_main`), and serves the bus and steps the physics
in one single-threaded event loop; the parent's commands arrive on a socket pair.

Registers (STS3215 control table, sizes and sign-magnitude as lerobot's
tables): Present_Position = encoder - Homing_Offset (mod 4096); Goal_Position
is in the same frame (so a new Homing_Offset written with torque on moves the
joint; lerobot writes it with torque off) and is clamped to [Min_Position_Limit,
Max_Position_Limit] (silently: the STS status byte has no angle-limit bit;
its bit 1 is the encoder-sensor error). Torque_Enable = 0 makes the joint
limp (the position actuator's gains are zeroed; gravity and the joint's
damping and friction act) and, as on the STS, Goal_Position then follows
Present_Position so re-enabling torque does not jump. Max_Torque_Limit scales
the actuator's force range. Lock = 0 saves EEPROM writes (addresses < 40) to
the image restored by :meth:`VirtualSO101.power_cycle`; with Lock = 1 they act
until the next power cycle. Present_Velocity [ticks/s] and Present_Load
[0.1 % of the stall torque, sign bit 10] come from the simulation. Acceleration,
speed limits and the PID coefficients are stored but do not shape the motion:
the MuJoCo position actuator (upstream's sts3215 gains) does. Only
Operating_Mode 0 (position) is emulated; in other modes goals are stored but
the joint keeps its last target.
"""

from __future__ import annotations

import logging
import math
import os
import select
import signal
import statistics
import termios
import time
import tty
from collections import deque
from multiprocessing.connection import Connection

from so101_kinematics.virtual.calibration import TICKS_PER_RAD
from so101_kinematics.virtual.protocol import (
    ADDR,
    BAUD_RATES,
    BITS_PER_BYTE,
    BROADCAST_ID,
    EEPROM_END,
    ERR_OVERLOAD,
    ERROR_BITS,
    FIRMWARE,
    INST_PING,
    INST_READ,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    READ_ONLY,
    RESOLUTION,
    status_packet,
    take_packets,
)
from so101_kinematics.virtual.servo import VirtualServo

logger = logging.getLogger("virtual_so101")

STALL_LOAD_RATE = 2000.0  # [0.1 % per s] Present_Load rise of a stalled servo
LATE_REPLY = 0.045  # [s] after this, lerobot (50 ms timeout) may have given up
GOAL_LOG_LENGTH = 1_000_000  # Goal_Position writes kept (about 30 min of a 100 Hz loop)


class _Emulator:
    """The event loop of the emulator process: pty + registers + physics."""

    def __init__(self, conn, options: dict):
        import mujoco

        import so101_kinematics.sim.scene as smu

        self.mujoco, self.smu = mujoco, smu
        self.conn = conn
        self.m = smu.load_model()
        self.d = mujoco.MjData(self.m)
        self.dt = float(self.m.opt.timestep)
        self.servos: dict[int, VirtualServo] = {}
        for joint, cal in options["calibration"].items():
            servo = VirtualServo(joint, cal, self.m)
            self.servos[servo.id] = servo
        self.by_joint = {s.joint: s for s in self.servos.values()}
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
        for servo in self.servos.values():
            servo.set("Torque_Enable", 1 if options["torque_on_start"] else 0)
            servo.sync_cache()
            self._apply_torque(servo)
            self._hold(servo)
        self.update_listening()
        self.inject(options["faults"])
        self.viewer = None
        if options["viewer"]:
            import mujoco.viewer

            self.viewer = mujoco.viewer.launch_passive(self.m, self.d)
        self.next_view = 0.0
        # The pty: keep the slave open (else the master reads EIO in a busy loop).
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.port = os.ttyname(self.slave)
        self.speeds = {getattr(termios, f"B{b}"): b for b in BAUD_RATES.values()
                       if hasattr(termios, f"B{b}")}
        self.t0 = time.perf_counter()
        self.steps = 0

    # --- physics --------------------------------------------------------------------------
    def _apply_torque(self, servo: VirtualServo) -> None:
        on = servo.torque
        m, act = self.m, servo.act
        m.actuator_gainprm[act, 0] = servo.kp if on else 0.0
        m.actuator_biasprm[act, 1] = -servo.kp if on else 0.0
        m.actuator_biasprm[act, 2] = -servo.kv if on else 0.0
        force = servo.max_force * min(1000, servo.get("Max_Torque_Limit")) / 1000.0
        m.actuator_forcerange[act] = (-force, force)

    def _hold(self, servo: VirtualServo) -> None:
        """Goal_Position := Present_Position, actuator target := measured angle."""
        angle = float(self.d.qpos[servo.qadr])
        servo.set("Goal_Position", servo.angle_to_present(angle))
        self.d.ctrl[servo.act] = angle

    def step_physics(self) -> None:
        due = int((time.perf_counter() - self.t0) / self.dt) - self.steps
        if due <= 0:
            return
        if due > 25:  # fell behind (busy machine): let simulated time slip
            self.steps += due - 25
            due = 25
        m, d, step = self.m, self.d, self.mujoco.mj_step
        stalled = [s for s in self.servos.values() if s.stalled_at is not None]
        for _ in range(due):
            step(m, d)
            for s in stalled:
                d.qpos[s.qadr] = s.stalled_at
                d.qvel[s.dofadr] = 0.0
        self.steps += due
        for s in stalled:
            err = s.get("Goal_Position") - s.angle_to_present(s.stalled_at)
            rate = STALL_LOAD_RATE * due * self.dt
            if abs(err) > 3 and s.torque:
                s.load = math.copysign(min(1000.0, abs(s.load) + rate), err)
            else:
                s.load = math.copysign(max(0.0, abs(s.load) - rate), s.load)
        if self.viewer is not None and time.perf_counter() >= self.next_view:
            if not self.viewer.is_running():
                raise KeyboardInterrupt("viewer closed")
            self.viewer.sync()
            self.next_view = time.perf_counter() + 1 / 60

    def refresh(self, servo: VirtualServo, lo: int = 56, hi: int = 71) -> None:
        """Update the servo's Present_* registers overlapping [lo, hi) from the simulation."""
        d, regs = self.d, servo.regs
        angle = servo.stalled_at if servo.stalled_at is not None else float(d.qpos[servo.qadr])
        present = round(servo.base + servo.scale * angle + servo.delta) % RESOLUTION
        regs[56] = present & 0xFF
        regs[57] = present >> 8
        if not servo.torque:  # the STS keeps Goal_Position on Present_Position while limp
            regs[42], regs[43] = regs[56], regs[57]
        if hi <= 58:
            return
        velocity = float(d.qvel[servo.dofadr]) * TICKS_PER_RAD
        if servo.stalled_at is not None:
            load = servo.load
        else:
            load = float(d.actuator_force[servo.act]) / servo.max_force * 1000.0
        load = max(-1000, min(1000, round(load)))
        servo.set("Present_Velocity", max(-32767, min(32767, round(velocity))))
        servo.set("Present_Load", load)
        servo.set("Present_Current", abs(load) * 2)
        regs[66] = int(abs(velocity) > 20)
        regs[65] = self.error_byte(servo)

    def error_byte(self, servo: VirtualServo) -> int:
        bits = servo.error_bits
        if servo.stalled_at is not None and abs(servo.load) >= 10 * servo.regs[36]:
            bits |= ERR_OVERLOAD
        return bits

    # --- registers ------------------------------------------------------------------------
    def write_goal(self, servo: VirtualServo, low: int, high: int) -> None:
        """Fast path: a Goal_Position write (the hot path of a control loop)."""
        regs = servo.regs
        regs[42] = low
        regs[43] = high
        goal = low | high << 8
        if goal & 0x8000:
            goal = -(goal & 0x7FFF)
        if servo.torque and servo.position_mode:
            self.d.ctrl[servo.act] = servo.goal_to_angle(goal)
        self.goal_log.append((time.time(), servo.id, goal))

    def write(self, servo: VirtualServo, addr: int, data: bytes) -> None:
        if addr == 42 and len(data) == 2:
            self.write_goal(servo, data[0], data[1])
            return
        regs = servo.regs
        old_id, was_on = servo.id, servo.torque
        for i, byte in enumerate(data):
            if addr + i not in READ_ONLY and addr + i < 256:
                regs[addr + i] = byte
        if addr < EEPROM_END and regs[55] == 0:
            servo.saved = bytes(regs[:EEPROM_END])
        servo.sync_cache()
        touched = set(range(addr, addr + len(data)))
        if servo.id != old_id or touched & {6}:
            self.servos = {s.id: s for s in self.by_joint.values()}
            self.update_listening()
        if touched & {40, 16, 17}:
            self._apply_torque(servo)
            if servo.torque and not was_on:
                self._hold(servo)
        if touched & {42, 43, 31, 32, 9, 10, 11, 12, 33}:
            if servo.torque and servo.position_mode:
                self.d.ctrl[servo.act] = servo.goal_to_angle(servo.get("Goal_Position"))
            if touched & {42, 43}:
                self.goal_log.append((time.time(), servo.id, servo.get("Goal_Position")))

    def read(self, servo: VirtualServo, addr: int, size: int) -> bytes:
        end = addr + size
        if (end > 56 and addr < 71) or (not servo.torque and addr <= 43 and end > 42):
            self.refresh(servo, addr, end)
        return bytes(servo.regs[addr:end]).ljust(size, b"\0")

    def update_listening(self) -> None:
        """The servos that hear the host: present, and at the host's baud rate."""
        self.listening = {i: s for i, s in self.servos.items()
                          if not s.removed and s.baud == self.host_baud}

    # --- protocol -------------------------------------------------------------------------
    def on_serial(self) -> None:
        try:
            chunk = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # EIO: no slave open (cannot happen while we hold one)
            time.sleep(0.001)
            return
        now = time.perf_counter()
        if now < self.outage_until:  # the bus is down: requests are lost, nobody answers
            self.rx.clear()
            return
        baud = self.speeds.get(termios.tcgetattr(self.master)[5], self.host_baud)
        if baud != self.host_baud:
            self.host_baud = baud
            self.update_listening()
        rx = self.rx
        if rx and now - self.rx_partial_since > 0.01:
            del rx[:2]  # a stale partial packet: a servo's byte timeout would discard it
        rx += chunk
        for packet in take_packets(rx):
            self.handle(packet, now)
        if rx:
            self.rx_partial_since = now

    def handle(self, packet: bytes, t_seen: float) -> None:
        target, inst, params = packet[2], packet[4], packet[5:-1]
        tpb = BITS_PER_BYTE / self.host_baud
        if self.wire_timing:  # the request ends on the wire after its bytes (queued behind others)
            t_end = max(t_seen, self.wire_free) + len(packet) * tpb
            self.wire_free = t_end
        else:
            t_end = t_seen
        listening = self.listening
        replies: list[tuple[VirtualServo, bytes]] = []
        if inst == INST_PING:
            if target == BROADCAST_ID:
                replies = [(s, b"") for _, s in sorted(listening.items())]
            elif target in listening:
                replies = [(listening[target], b"")]
        elif inst == INST_READ and len(params) == 2 and target in listening:
            servo = listening[target]
            replies = [(servo, self.read(servo, params[0], params[1]))]
        elif inst == INST_WRITE and len(params) >= 2:
            addr, data = params[0], params[1:]
            targets = list(listening.values()) if target == BROADCAST_ID else (
                [listening[target]] if target in listening else [])
            for servo in targets:
                self.write(servo, addr, data)
            if target != BROADCAST_ID and targets:
                servo = targets[0]
                if servo.regs[8] != 0:
                    replies = [(servo, b"")]
        elif inst == INST_SYNC_READ and target == BROADCAST_ID and len(params) >= 2:
            addr, size = params[0], params[1]
            for servo_id in params[2:]:
                servo = listening.get(servo_id)
                if servo is not None:
                    replies.append((servo, self.read(servo, addr, size)))
        elif inst == INST_SYNC_WRITE and target == BROADCAST_ID and len(params) >= 2:
            addr, size = params[0], params[1]
            body = params[2:]
            for i in range(0, len(body) - size, size + 1):
                servo = listening.get(body[i])
                if servo is not None:
                    self.write(servo, addr, body[i + 1:i + 1 + size])
        if replies:
            self.send(replies, t_end, tpb)

    def send(self, replies: list[tuple[VirtualServo, bytes]], t_end: float, tpb: float) -> None:
        t_ready = t_end
        out = []
        for servo, params in replies:
            if servo.drop:
                servo.drop -= 1
                continue
            if servo.removed:
                continue
            packet = status_packet(servo.id, self.error_byte(servo), params)
            if servo.corrupt:
                servo.corrupt -= 1
                packet = packet[:-1] + bytes(((packet[-1] + 1) & 0xFF,))
            t_ready += servo.return_delay + len(packet) * tpb
            out.append((t_ready, packet))
        if not out:
            return
        if self.latency_left > 0:  # late replies (injected): the whole batch waits
            self.latency_left -= 1
            out = [(ready + self.latency, packet) for ready, packet in out]
            t_ready += self.latency
            if not self.wire_timing:
                _wait_until(t_ready)
        if self.wire_timing:
            self.wire_free = t_ready
            for deadline, packet in out:
                _wait_until(deadline)
                self._emit(packet, deadline, t_end)
        else:
            now = time.perf_counter()
            self._emit(b"".join(p for _, p in out), t_end, t_end, now)
            self.replies += len(out) - 1

    def _emit(self, data: bytes, deadline: float, t_end: float, now: float | None = None) -> None:
        try:
            os.write(self.master, data)
        except BlockingIOError:  # nobody reads the port: the bytes are lost on the wire
            pass
        now = time.perf_counter() if now is None else now
        self.replies += 1
        self.lateness.append(time.perf_counter() - deadline)
        if now - t_end > LATE_REPLY:
            self.late += 1

    # --- faults and commands --------------------------------------------------------------
    def inject(self, faults: list[tuple]) -> None:
        for kind, servo_id, arg in faults:
            if kind == "outage":
                self.outage_until = time.perf_counter() + arg / 1000.0
                logger.info("fault injected: bus outage of %g ms", arg)
                continue
            if kind == "latency":
                self.latency, self.latency_left = arg[0] / 1000.0, arg[1]
                logger.info("fault injected: the next %d replies %g ms late", arg[1], arg[0])
                continue
            if kind == "unplug":
                self.unplug()
                continue
            servo = next(s for s in self.by_joint.values() if s.cal["id"] == servo_id)
            if kind in ERROR_BITS:
                servo.error_bits |= ERROR_BITS[kind]
            elif kind == "drop":
                servo.drop += arg
            elif kind == "corrupt":
                servo.corrupt += arg
            elif kind == "remove":
                servo.removed = True
            elif kind == "stall":
                servo.stalled_at = float(self.d.qpos[servo.qadr])
                servo.load = 0.0
            elif kind == "firmware":
                servo.regs[0], servo.regs[1] = arg
            self.update_listening()
            logger.info("fault injected: %s on servo %d (%s)", kind, servo_id, servo.joint)

    def unplug(self) -> None:
        """The USB cable pulled out: the port vanishes; the servos keep their last goals."""
        if self.unplugged:
            return
        self.unplugged = True
        os.close(self.master)
        os.close(self.slave)
        logger.info("fault injected: unplugged (%s is gone)", self.port)

    def clear_faults(self) -> None:
        self.outage_until = 0.0
        self.latency_left = 0
        for servo in self.servos.values():
            servo.error_bits = 0
            servo.drop = servo.corrupt = 0
            servo.removed = False
            servo.stalled_at = None
            servo.load = 0.0
            servo.regs[0], servo.regs[1] = FIRMWARE
        self.update_listening()

    def command(self, name: str, args: tuple):
        smu = self.smu
        if name == "joint_positions":
            return smu.get_configuration(self.m, self.d)
        if name == "commanded_positions":
            return smu.get_command(self.m, self.d)
        if name == "goal_log":
            return list(self.goal_log)
        if name == "clear_goal_log":
            self.goal_log.clear()
            return None
        if name == "torque_enabled":
            return {s.joint: s.torque for s in self.by_joint.values()}
        if name == "inject":
            return self.inject(args[0])
        if name == "clear_faults":
            return self.clear_faults()
        if name == "set_pose":
            smu.set_initial_pose(self.d, args[0])
            for servo in self.servos.values():
                if servo.stalled_at is not None:
                    servo.stalled_at = float(self.d.qpos[servo.qadr])
                self._hold(servo)
            return None
        if name == "set_torque":
            for servo in self.by_joint.values():
                if args[1] is None or servo.joint in args[1]:
                    self.write(servo, 40, bytes((int(args[0]),)))
            return None
        if name == "set_wire_timing":
            self.wire_timing = bool(args[0])
            return None
        if name == "registers":
            servo = self.by_joint[args[0]]
            self.refresh(servo)
            return {reg: servo.get(reg) for reg in ADDR}
        if name == "power_cycle":
            for servo in self.servos.values():
                eeprom = servo.saved
                gains = servo.kp, servo.kv, servo.max_force  # the model's, before any torque change
                servo.__init__(servo.joint, servo.cal, self.m)
                servo.kp, servo.kv, servo.max_force = gains
                servo.regs[:EEPROM_END] = eeprom
                servo.saved = eeprom
                servo.sync_cache()
                self._apply_torque(servo)
            self.servos = {s.id: s for s in self.by_joint.values()}
            self.update_listening()
            return None
        if name == "reply_stats":
            lateness = sorted(self.lateness)
            p99 = lateness[int(0.99 * (len(lateness) - 1))] if lateness else 0.0
            return {
                "replies": self.replies, "late_replies": self.late,
                "lateness_median_ms": 1e3 * statistics.median(lateness) if lateness else 0.0,
                "lateness_p99_ms": 1e3 * p99,
                "lateness_max_ms": 1e3 * lateness[-1] if lateness else 0.0,
                "max_loop_delay_ms": 1e3 * self.max_gap,
                "sim_time_s": self.d.time, "wall_time_s": time.perf_counter() - self.t0,
            }
        if name == "clear_stats":
            self.lateness.clear()
            self.replies = self.late = 0
            self.max_gap = 0.0
            return None
        raise ValueError(f"unknown command {name!r}")

    def run(self) -> None:
        self.conn.send(("ready", self.port))
        master, conn = self.master, self.conn
        while True:
            now = time.perf_counter()
            wake = max(now, self.t0 + (self.steps + 1) * self.dt)
            watched = [conn] if self.unplugged else [master, conn]
            ready, _, _ = select.select(watched, [], [], wake - now)
            # How long past its wake-up time the loop got the CPU back (descheduled).
            self.max_gap = max(self.max_gap, time.perf_counter() - wake)
            if master in ready:
                self.on_serial()
            if conn in ready:
                try:
                    name, args = conn.recv()
                except (EOFError, OSError):
                    return
                if name == "close":
                    conn.send(("ok", None))
                    return
                try:
                    conn.send(("ok", self.command(name, args)))
                except Exception as exc:  # noqa: BLE001 - handed to the caller
                    conn.send(("err", exc))
            self.step_physics()


SPIN_S = float(os.environ.get("VIRTUAL_SO101_SPIN_S", "1e-4"))  # [s] busy-wait before a reply


def _wait_until(deadline: float) -> None:
    """Sleep, then spin the last ``SPIN_S``, until ``time.perf_counter() >= deadline``.

    The process runs with a 1 us timer slack (:func:`_tighten_timer_slack`),
    so a short sleep wakes within tens of microseconds; sleeping rather than
    spinning keeps the emulator a light, interactive task for the scheduler,
    which then wakes it promptly on a busy machine.
    """
    remaining = deadline - time.perf_counter()
    if remaining > SPIN_S:
        time.sleep(remaining - SPIN_S)
    while time.perf_counter() < deadline:
        pass


def _raise_priority() -> None:
    """Ask for a higher CPU priority (nice -5) where allowed.

    The emulator sleeps most of the time but must answer within lerobot's
    50 ms timeout even on a machine busy with other work; a real servo does
    not share the host's CPU. Without the privilege this does nothing.
    """
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -5)
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
        if not emulator.unplugged:
            os.close(emulator.master)
            os.close(emulator.slave)
