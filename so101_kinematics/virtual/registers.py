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
and ``virtual/electrical.py`` (read by ``virtual/sensor_registers.py``); a limp servo's
Present_Load is 0. Overload protection (Unloading_Condition bit 5): after
Protection_Time above Overload_Torque the duty is capped at Protective_Torque until a
new goal or a Torque_Enable write (:meth:`ServoRegisters.protect`). An ID above 253 is
refused. Where Feetech's sources disagree, ``virtual/rules.py`` switches.
"""

from __future__ import annotations

import math
import random
import time

from so101_kinematics import servo as servo_facts
from so101_kinematics.frames import JOINTS
from so101_kinematics.gravity import feedforward
from so101_kinematics.servo import COUNTS_PER_TURN
from so101_kinematics.sim.actuation import IDEAL_GAINS
from so101_kinematics.sim.sts3215 import ServoBank
from so101_kinematics.virtual.electrical import (
    SUPPLY_RESISTANCE_OHM,
    next_temperature,
)
from so101_kinematics.virtual.protocol import (
    EEPROM_END,
    MAX_SERVO_ID,
    READ_ONLY,
    decode_sign_magnitude,
)
from so101_kinematics.virtual.sensor_registers import PWM_DIRECTION, SensorReadings
from so101_kinematics.virtual.servo_memory import VirtualServo

__all__ = ["GOAL_LOG_LENGTH", "ServoRegisters"]

STALL_LOAD_RATE = 2000.0  # [0.1 % per s] Present_Load rise of a stalled servo
HAND_GAINS = IDEAL_GAINS  # a hand guiding a limp joint: the upstream model's stiff spring
STEP_MODE = 3
"""Operating_Mode 3 (step): each Goal_Position written moves the goal by that many counts
(signed), from where it was, with the position loop [MEM]."""
OVERLOAD_ENABLE = 0x20
"""Unloading_Condition (19) bit 5: the overload protection is on (factory value 44) [MEM]."""
SETTING_ADDRESSES = {16, 21, 22, 23, 24, 26, 27, 33, 41, 44, 45, 46, 47, 48}
"""Registers that change the servo's loop (gains, dead zone, mode, profile, torque limit)."""


def servo_settings(servo: VirtualServo) -> servo_facts.Settings:
    """The loop's registers of one virtual servo (``servo.Settings``).

    The duty cap is Torque_Limit, never above Max_Torque_Limit (the STS loads 48 from 16
    at power-up; a Max_Torque_Limit written since then caps it too: lerobot's gripper
    setting acts without a power cycle). The two dead zones are averaged. In wheel
    mode Goal_Velocity is the wheel's speed, not a cap. A servo in overload protection
    drives at most Protective_Torque (34, percent of the maximum) [MEM].
    """
    regs = servo.regs
    wheel = regs[33] == 1
    cap = min(servo.get("Torque_Limit"), servo.get("Max_Torque_Limit"))
    if servo.protected:
        cap = min(cap, 10 * regs[34])
    return servo_facts.Settings(
        p=regs[21], d=regs[22], i=regs[23], min_startup=servo.get("Minimum_Startup_Force"),
        dead_zone=(regs[26] + regs[27]) / 2, acceleration=regs[41],
        goal_velocity=0 if wheel else abs(servo.get("Goal_Velocity")),
        torque_limit=cap)
GOAL_LOG_LENGTH = 1_000_000  # Goal_Position writes kept (about 30 min of a 100 Hz loop)


class ServoRegisters(SensorReadings):
    """The servos' registers applied to the MuJoCo arm (a mixin of the emulator's event loop).

    Expects ``m``, ``d``, ``mujoco``, ``dt``, ``t0``, ``steps``, ``sim_clock`` (None: the wall
    clock), ``dt_ns``, ``servos``,
    ``by_joint``, ``goal_log``, ``viewer``, ``next_view``, ``supply`` [V],
    ``voltage`` [0.1 V] and ``thermal_time_s`` on the instance.
    """

    # --- physics --------------------------------------------------------------------------
    def make_servo_bank(self, variant: str | None = None) -> None:
        """The servos' dynamics (``sim/sts3215.py``), in ``JOINTS`` order, at the supply."""
        self.noise = random.Random(4096)  # the encoders' reading noise (ENCODER_NOISE), seeded
        self.readings_noise = random.Random(69)  # current and voltage readings', seeded
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
        # Operating_Mode 2: the duty [0.1 %] in Goal_Time, bit 10 the direction; a positive
        # duty turns the way Present_Position counts down (PWM_DIRECTION)
        self.bank.pwm[servo.index] = PWM_DIRECTION * math.copysign(1.0, servo.scale) \
            * decode_sign_magnitude(servo.get("Goal_Time") & 0x7FF, 10)
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
        """Step the simulation up to its clock.

        The wall clock by default (at most 25 steps behind: then time slips); the program's
        simulated time with ``sim_clock`` (``virtual/sim_clock.py``): every step, never slipping.
        """
        if self.sim_clock is not None:
            due = self.sim_clock.target_ns // self.dt_ns - self.steps
            if due <= 0:
                return
        else:
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

    def update_electrical(self, dt: float) -> None:
        """Advance every servo's temperature and overload timer by ``dt`` [s]; the bus voltage."""
        amps = 0.0
        for servo in self.by_joint.values():
            load = self.effort(servo)
            amps += self.current(servo)
            servo.temperature = next_temperature(servo.temperature, load, dt, self.thermal_time_s)
            limit = 10 * servo.regs[36]  # Overload_Torque [%] -> [0.1 %]
            servo.overload_time = servo.overload_time + dt if 0 < limit <= abs(load) else 0.0
            if not servo.protected and servo.regs[19] & OVERLOAD_ENABLE and servo.torque \
                    and servo.overload_time >= max(0.01 * servo.regs[35], dt):
                self.protect(servo, True)  # Protection_Time over Overload_Torque: [MEM]
        volts = self.supply - SUPPLY_RESISTANCE_OHM * amps
        self.voltage = max(0, min(255, round(10.0 * volts)))
        self.bank.volts = max(0.0, volts)

    def settings_of(self, servo: VirtualServo) -> servo_facts.Settings:
        """The loop's registers of ``servo`` (:func:`servo_settings`)."""
        return servo_settings(servo)

    def protect(self, servo: VirtualServo, on: bool) -> None:
        """Enter (or leave) the overload protection: the duty capped at Protective_Torque.

        Memory table: after Overload_Torque (36) has been exceeded for Protection_Time
        (35), the output drops to Protective_Torque (34); the C018 datasheet: "a new
        position command clears" it. Here a Goal_Position write of another value, or a
        Torque_Enable write, clears it (a choice: an unchanged goal, which lerobot sends
        every cycle, keeps it).
        """
        servo.protected = on
        servo.overload_time = 0.0
        if hasattr(self, "bank"):
            self.bank.set(servo.index, servo_settings(servo))

    # --- registers ------------------------------------------------------------------------
    def write_goal(self, servo: VirtualServo, low: int, high: int) -> None:
        """Fast path: a Goal_Position write (the hot path of a control loop)."""
        regs = servo.regs
        if servo.protected and (regs[42], regs[43]) != (low, high):
            self.protect(servo, False)  # "a new position command clears" the protection
        regs[42] = low
        regs[43] = high
        goal = low | high << 8
        if goal & 0x8000:
            goal = -(goal & 0x7FFF)
        if servo.torque and servo.position_mode:
            self.d.ctrl[servo.act] = servo.goal_to_angle(goal)
            self.timed_move(servo)
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
        old_goal = bytes(regs[42:44])
        locked = EEPROM_END if regs[55] and self.rules["locked_eeprom"] == "refused" else 0
        for i, byte in enumerate(data):
            if addr + i not in READ_ONLY and locked <= addr + i < 256:  # rules.py: Lock
                regs[addr + i] = byte
        touched = set(range(addr, addr + len(data)))
        if regs[5] > MAX_SERVO_ID:  # 254 is the broadcast ID, 255 none: the ID is refused
            regs[5] = old_id
        if servo.protected and (40 in touched or bytes(regs[42:44]) != old_goal):
            servo.protected = False  # a Torque_Enable write or a new goal: applied below
            servo.overload_time = 0.0
            touched.add(48)
        if 40 in touched and regs[40] == 128:  # "calibrate the present position to 2048"
            regs[40] = int(was_on)  # reads back 0/1: torque stays as it was
            self.set_present(servo, COUNTS_PER_TURN // 2)
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
                kept = servo.get("Goal_Position")
                self._hold(servo)  # step mode steps from where the joint is (a choice)
                if not was_on and servo.position_mode and self.rules["limp_goal"] == "kept":
                    servo.set("Goal_Position", kept)  # the goal written while limp (rules.py)
                    touched.add(42)
        if touched & {42, 43, 31, 32, 9, 10, 11, 12, 33}:
            if servo.torque and servo.position_mode:
                self.d.ctrl[servo.act] = servo.goal_to_angle(servo.get("Goal_Position"))
            elif servo.torque and regs[33] == STEP_MODE and touched & {42, 43}:
                self.d.ctrl[servo.act] += servo.get("Goal_Position") / servo.scale
            if touched & {42, 43}:
                self.goal_log.append((time.time(), servo.id, servo.get("Goal_Position")))
                self.timed_move(servo)

    def timed_move(self, servo: VirtualServo) -> None:
        """Rule ``goal_time = "move_time"`` (SCS series): the goal reached in Goal_Time ms.

        The profile's speed is the distance over the time [counts/s] (at least 1), until
        the next write of a loop register.
        """
        time_ms = servo.get("Goal_Time")
        if self.rules["goal_time"] != "move_time" or not time_ms or not servo.torque \
                or not servo.position_mode:
            return
        goal = round(float(self.d.ctrl[servo.act]) * servo_facts.COUNTS_PER_RAD)
        distance = abs(goal - round(float(self.d.qpos[servo.qadr]) * servo_facts.COUNTS_PER_RAD))
        speed = max(1, round(distance / (time_ms / 1000.0)))
        self.bank.set(servo.index, servo_settings(servo).with_(goal_velocity=speed))

    def set_present(self, servo: VirtualServo, value: int) -> None:
        """Set Homing_Offset so that Present_Position reads ``value`` where the joint is now.

        Torque_Enable = 128 (value 2048) and the calibration instruction 0x0B do this
        (Feetech's memory table; STS firmware >= 3.10). The offset is sign-magnitude with
        its sign at bit 11, so it stays within +-2047 (an encoder 2048 counts away from
        ``value`` reads ``value`` - 1). Saved like any EEPROM write (Lock = 0); a servo
        with torque on holds where it is.
        """
        angle = servo.stalled_at if servo.stalled_at is not None else float(self.d.qpos[servo.qadr])
        encoder = (servo.angle_to_present(angle) + servo.get("Homing_Offset")) % COUNTS_PER_TURN
        offset = (encoder - value + COUNTS_PER_TURN // 2) % COUNTS_PER_TURN - COUNTS_PER_TURN // 2
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

