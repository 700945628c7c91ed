"""What the virtual servos' registers do to the simulated arm, and the physics that answers.

Registers (STS3215 control table, sizes and sign-magnitude as lerobot's
tables): Present_Position = encoder - Homing_Offset (mod 4096); Goal_Position
is in the same frame (so a new Homing_Offset written with torque on moves the
joint; lerobot writes it with torque off) and is clamped to [Min_Position_Limit,
Max_Position_Limit] (silently: the STS status byte has no angle-limit bit;
its bit 1 is the encoder-sensor error). Torque_Enable = 0 makes the joint
limp (gravity and the joint's damping and friction act) and, as on the STS,
Goal_Position then follows Present_Position so re-enabling torque does not jump.
Lock = 0 saves EEPROM writes (addresses < 40) to the image restored by
:meth:`VirtualSO101.power_cycle`; with Lock = 1 they act until the next power cycle.
The servo's loop is ``sim/sts3215.py``'s model, fed by :func:`servo_settings`: the
gains, dead zones, Minimum_Startup_Force, the motion profile (Acceleration,
Goal_Velocity), the duty cap (Torque_Limit) and the Operating_Mode (0 position, 1
wheel, 2 PWM with Goal_Time as the duty, 3 step). Goal_Time is not a move's duration
in position mode: Feetech's STS memory table makes address 44 the PWM mode's duty
("effective in PWM open-loop speed mode"), and Feetech's SMS_STS driver writes 0 there
with every position (``WritePosEx``: acceleration, position, time 0, speed); only the
SCS series' driver passes a time (``SCSCL::WritePos``). Present_Velocity [counts/s],
Present_Load [0.1 % duty, sign bit 10], Present_Current, Present_Temperature,
Present_Voltage and the overheat/voltage/overload status bits follow the servo model
and ``virtual/electrical.py``; a limp servo's Present_Load is 0.
"""

from __future__ import annotations

import math
import random
import time

from so101_kinematics import servo as servo_facts
from so101_kinematics.frames import JOINTS
from so101_kinematics.gravity import feedforward
from so101_kinematics.sim.actuation import IDEAL_GAINS
from so101_kinematics.sim.sts3215 import ServoBank
from so101_kinematics.virtual.calibration import TICKS_PER_RAD
from so101_kinematics.virtual.electrical import (
    SUPPLY_RESISTANCE_OHM,
    next_temperature,
    status_bits,
)
from so101_kinematics.virtual.protocol import EEPROM_END, READ_ONLY, RESOLUTION
from so101_kinematics.virtual.servo import VirtualServo

STALL_LOAD_RATE = 2000.0  # [0.1 % per s] Present_Load rise of a stalled servo
HAND_GAINS = IDEAL_GAINS  # a hand guiding a limp joint: the upstream model's stiff spring
ENCODER_NOISE = 0.3
"""How often a Present_Position reading is a count off (either way, seeded): a real STS3215 at
rest reads a count or two apart from one read to the next (issue 26, clients on real arms)."""
STEP_MODE = 3
"""Operating_Mode 3 (step): each Goal_Position written moves the goal by that many counts
(signed), from where it was, with the position loop [MEM]."""
SETTING_ADDRESSES = {16, 21, 22, 23, 24, 26, 27, 33, 41, 44, 45, 46, 47, 48}
"""Registers that change the servo's loop (gains, dead zone, mode, profile, torque limit)."""


def servo_settings(servo: VirtualServo) -> servo_facts.Settings:
    """The loop's registers of one virtual servo (``servo.Settings``).

    The duty cap is Torque_Limit, never above Max_Torque_Limit (the STS loads 48 from 16
    at power-up; a Max_Torque_Limit written since then caps it too: lerobot's gripper
    setting acts without a power cycle). The two dead zones are averaged. In wheel
    mode Goal_Velocity is the wheel's speed, not a cap.
    """
    regs = servo.regs
    wheel = regs[33] == 1
    return servo_facts.Settings(
        p=regs[21], d=regs[22], i=regs[23], min_startup=servo.get("Minimum_Startup_Force"),
        dead_zone=(regs[26] + regs[27]) / 2, acceleration=regs[41],
        goal_velocity=0 if wheel else abs(servo.get("Goal_Velocity")),
        torque_limit=min(servo.get("Torque_Limit"), servo.get("Max_Torque_Limit")))
GOAL_LOG_LENGTH = 1_000_000  # Goal_Position writes kept (about 30 min of a 100 Hz loop)


class ServoRegisters:
    """The servos' registers applied to the MuJoCo arm (a mixin of the emulator's event loop).

    Expects ``m``, ``d``, ``mujoco``, ``dt``, ``t0``, ``steps``, ``servos``,
    ``by_joint``, ``goal_log``, ``viewer``, ``next_view``, ``supply`` [V],
    ``voltage`` [0.1 V] and ``thermal_time_s`` on the instance.
    """

    # --- physics --------------------------------------------------------------------------
    def make_servo_bank(self, variant: str | None = None) -> None:
        """The servos' dynamics (``sim/sts3215.py``), in ``JOINTS`` order, at the supply."""
        self.noise = random.Random(4096)  # the encoders' reading noise (ENCODER_NOISE), seeded
        self.order = [self.by_joint[j] for j in JOINTS if j in self.by_joint]
        for index, s in enumerate(self.order):
            s.index = index
        variant = variant or servo_facts.default_variant(self.supply)
        self.bank = ServoBank([servo_settings(s) for s in self.order], self.supply, variant)
        self.bank_acts = [s.act for s in self.order]
        self.bank_qadr = [s.qadr for s in self.order]
        for s in self.order:
            self._apply_torque(s)

    def _apply_torque(self, servo: VirtualServo) -> None:
        """The servo pushes when torque is on; a hand gripping a limp joint is a spring there."""
        if servo.torque and servo.joint in self.hand_grip:  # the servo takes over from the hand
            del self.hand_grip[servo.joint]
            self.d.qfrc_applied[servo.dofadr] = 0.0
        m, act = self.m, servo.act
        self.bank.torque_on[servo.index] = servo.torque
        self.bank.set(servo.index, servo_settings(servo))
        self.bank.mode[servo.index] = servo.regs[33]
        spring = not servo.torque and servo.joint in self.hand_grip
        kp, kv, force, _ = HAND_GAINS if spring else (0.0, 0.0, 1e3, 0.0)
        m.actuator_gainprm[act, 0] = kp
        m.actuator_biasprm[act, 1] = -kp
        m.actuator_biasprm[act, 2] = -kv
        m.actuator_biasprm[act, 0] = 0.0
        m.actuator_forcerange[act] = (-force, force)
        pwm = servo.get("Goal_Time")  # Operating_Mode 2: duty [0.1 %], bit 10 the direction
        self.bank.pwm[servo.index] = -(pwm & 0x3FF) if pwm & 0x400 else pwm & 0x3FF
        self.bank.wheel_speed[servo.index] = servo.get("Goal_Velocity")

    def _hold(self, servo: VirtualServo) -> None:
        """Goal_Position := Present_Position, actuator target := measured angle."""
        angle = float(self.d.qpos[servo.qadr])
        servo.set("Goal_Position", servo.angle_to_present(angle))
        self.d.ctrl[servo.act] = angle
        self.bank.reset_target(servo.index, round(angle * servo_facts.COUNTS_PER_RAD))

    def rest_in_place(self) -> None:
        """Each torqued servo holds its joint where it is, at rest, without a sag.

        Its goal is the pose plus the error at which it holds gravity there
        (``gravity.feedforward`` at its registers and the supply), as after a move with
        the feed-forward.
        """
        cfg = self.smu.get_configuration(self.m, self.d)
        settings = {s.joint: servo_settings(s) for s in self.order}
        offsets = feedforward(cfg, settings, self.bank.volts, self.bank.variant.name)
        for servo in self.order:
            if not servo.torque or servo.stalled_at is not None:
                continue
            angle = float(self.d.qpos[servo.qadr]) + math.radians(offsets.get(servo.joint, 0.0))
            servo.set("Goal_Position", servo.angle_to_present(angle))
            self.d.ctrl[servo.act] = angle
            self.bank.reset_target(servo.index, round(angle * servo_facts.COUNTS_PER_RAD))

    def step_physics(self) -> None:
        """Step the simulation up to the wall clock (at most 25 steps behind: then time slips)."""
        due = int((time.perf_counter() - self.t0) / self.dt) - self.steps
        if due <= 0:
            return
        if due > 25:  # fell behind (busy machine): let simulated time slip
            self.steps += due - 25
            due = 25
        m, d, step = self.m, self.d, self.mujoco.mj_step
        stalled = [s for s in self.by_joint.values() if s.stalled_at is not None]
        acts, qadr, torques, bias = self.bank_acts, self.bank_qadr, self.bank.torques, \
            m.actuator_biasprm
        ctrl, qpos = d.ctrl, d.qpos
        for _ in range(due):
            bias[acts, 0] = torques(ctrl[acts].tolist(), qpos[qadr].tolist(), self.dt)
            step(m, d)
            for s in stalled:
                d.qpos[s.qadr] = s.stalled_at
                d.qvel[s.dofadr] = 0.0
        self.steps += due
        self.step_hand(due)
        self.update_electrical(due * self.dt)
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

    def effort(self, servo: VirtualServo) -> float:
        """Present_Load: the duty the servo's loop applies [0.1 %]; 0 when limp."""
        if servo.stalled_at is not None:
            return servo.load
        return self.bank.duty[servo.index] if servo.torque else 0.0

    def current(self, servo: VirtualServo) -> float:
        """The servo's motor current [A] (a stalled one draws its stall duty's)."""
        if servo.stalled_at is not None:
            return abs(servo.load) / 1000.0 * self.supply * self.bank.variant.torque_per_volt \
                / self.bank.variant.kt
        return self.bank.current(servo.index, float(self.d.qvel[servo.dofadr]))

    def update_electrical(self, dt: float) -> None:
        """Advance every servo's temperature and overload timer by ``dt`` [s]; the bus voltage."""
        amps = 0.0
        for servo in self.by_joint.values():
            load = self.effort(servo)
            amps += self.current(servo)
            servo.temperature = next_temperature(servo.temperature, load, dt, self.thermal_time_s)
            limit = 10 * servo.regs[36]  # Overload_Torque [%] -> [0.1 %]
            servo.overload_time = servo.overload_time + dt if 0 < limit <= abs(load) else 0.0
        volts = self.supply - SUPPLY_RESISTANCE_OHM * amps
        self.voltage = max(0, min(255, round(10.0 * volts)))
        self.bank.volts = max(0.0, volts)

    def refresh(self, servo: VirtualServo, lo: int = 56, hi: int = 71) -> None:
        """Update the servo's Present_* registers overlapping [lo, hi) from the simulation."""
        d, regs = self.d, servo.regs
        angle = servo.stalled_at if servo.stalled_at is not None else float(d.qpos[servo.qadr])
        noise = self.noise.random()
        jitter = -1 if noise < ENCODER_NOISE / 2 else 1 if noise > 1 - ENCODER_NOISE / 2 else 0
        present = (round(servo.base + servo.scale * angle + servo.delta) + jitter) % RESOLUTION
        regs[56] = present & 0xFF
        regs[57] = present >> 8
        if not servo.torque:  # the STS keeps Goal_Position on Present_Position while limp
            regs[42], regs[43] = regs[56], regs[57]
        if hi <= 58:
            return
        velocity = float(d.qvel[servo.dofadr]) * TICKS_PER_RAD
        velocity = round(velocity / servo_facts.VELOCITY_STEP) * servo_facts.VELOCITY_STEP
        load = max(-1000, min(1000, round(self.effort(servo))))
        servo.set("Present_Velocity", max(-32767, min(32767, velocity)))
        servo.set("Present_Load", load)
        regs[62] = self.voltage
        regs[63] = max(0, min(255, round(servo.temperature)))
        servo.set("Present_Current", round(self.current(servo) / servo_facts.CURRENT_UNIT_A))
        regs[66] = int(abs(velocity) > 20)
        regs[65] = self.error_byte(servo)

    def error_byte(self, servo: VirtualServo) -> int:
        """The servo's status error bits: injected ones, and the electrical model's.

        A stalled joint (fault ``stall``) is overloaded as soon as its load
        reaches Overload_Torque; any other load must stay there for Protection_Time.
        """
        regs = servo.regs
        overloaded = servo.overload_time >= 0.01 * regs[35] and servo.overload_time > 0
        if servo.stalled_at is not None and abs(servo.load) >= 10 * regs[36]:
            overloaded = True
        bits = status_bits(servo.temperature, self.voltage, overloaded, regs[13],
                           (regs[15], regs[14]))
        return servo.error_bits | bits

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
        elif servo.torque and regs[33] == STEP_MODE:  # a relative move of ``goal`` counts
            self.d.ctrl[servo.act] += goal / servo.scale
        self.goal_log.append((time.time(), servo.id, goal))

    def write(self, servo: VirtualServo, addr: int, data: bytes) -> None:
        """Write ``data`` at ``addr`` (read-only bytes ignored) and apply what it changes."""
        if addr == 42 and len(data) == 2:
            self.write_goal(servo, data[0], data[1])
            return
        regs = servo.regs
        old_id, was_on, old_mode = servo.id, servo.torque, regs[33]
        for i, byte in enumerate(data):
            if addr + i not in READ_ONLY and addr + i < 256:
                regs[addr + i] = byte
        touched = set(range(addr, addr + len(data)))
        if 40 in touched and regs[40] == 128:  # "calibrate the present position to 2048"
            regs[40] = int(was_on)  # reads back 0/1: torque stays as it was
            self.set_present(servo, 2048)
            touched |= {31, 32}
        if addr < EEPROM_END and regs[55] == 0:
            servo.saved = bytes(regs[:EEPROM_END])
        servo.sync_cache()
        if servo.id != old_id or touched & {6}:
            self.servos = {s.id: s for s in self.by_joint.values()}
            self.update_listening()
            if touched & {6}:
                self.on_setup_write(servo)
        if touched & ({40} | SETTING_ADDRESSES):
            self._apply_torque(servo)
            if servo.torque and (not was_on or (regs[33] == STEP_MODE and old_mode != STEP_MODE)):
                self._hold(servo)  # step mode steps from where the joint is (a choice)
        if touched & {42, 43, 31, 32, 9, 10, 11, 12, 33}:
            if servo.torque and servo.position_mode:
                self.d.ctrl[servo.act] = servo.goal_to_angle(servo.get("Goal_Position"))
            elif servo.torque and regs[33] == STEP_MODE and touched & {42, 43}:
                self.d.ctrl[servo.act] += servo.get("Goal_Position") / servo.scale
            if touched & {42, 43}:
                self.goal_log.append((time.time(), servo.id, servo.get("Goal_Position")))

    def set_present(self, servo: VirtualServo, value: int) -> None:
        """Set Homing_Offset so that Present_Position reads ``value`` where the joint is now.

        Torque_Enable = 128 (value 2048) and the calibration instruction 0x0B do this
        (Feetech's memory table; STS firmware >= 3.10). The offset is sign-magnitude with
        its sign at bit 11, so it stays within +-2047 (an encoder 2048 counts away from
        ``value`` reads ``value`` - 1). Saved like any EEPROM write (Lock = 0); a servo
        with torque on holds where it is.
        """
        angle = servo.stalled_at if servo.stalled_at is not None else float(self.d.qpos[servo.qadr])
        encoder = (servo.angle_to_present(angle) + servo.get("Homing_Offset")) % RESOLUTION
        offset = (encoder - value + RESOLUTION // 2) % RESOLUTION - RESOLUTION // 2
        servo.set("Homing_Offset", max(-2047, offset))
        if servo.regs[55] == 0:
            servo.saved = bytes(servo.regs[:EEPROM_END])
        servo.sync_cache()
        if servo.torque:  # the same goal angle, in the new frame: the servo holds as it held
            servo.set("Goal_Position", servo.angle_to_present(float(self.d.ctrl[servo.act])))

    def read(self, servo: VirtualServo, addr: int, size: int) -> bytes:
        """``size`` bytes from ``addr``, the Present_* registers refreshed from the simulation."""
        end = addr + size
        if (end > 56 and addr < 71) or (not servo.torque and addr <= 43 and end > 42):
            self.refresh(servo, addr, end)
        return bytes(servo.regs[addr:end]).ljust(size, b"\0")

    def update_listening(self) -> None:
        """The servos that hear the host, by ID: present, and at the host's baud rate.

        Two servos may share an ID (two new ones on one bus): both hear and obey.
        """
        listening: dict[int, list[VirtualServo]] = {}
        for s in self.by_joint.values():
            if s.plugged and not s.removed and s.baud == self.host_baud:
                listening.setdefault(s.id, []).append(s)
        self.listening = listening

