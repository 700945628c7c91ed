"""What the virtual servos' sensors report: the Present_* registers and the status bits.

A mixin of the emulator (``registers.ServoRegisters`` inherits it): each reading is taken
from the simulation when a client reads it.

- **Present_Position** (56): the encoder, a count off on ``ENCODER_NOISE`` of the readings
  (seeded). In position mode less Homing_Offset; in wheel, PWM and step modes the bare
  encoder (``ENCODER_OUTSIDE_POSITION_MODE``).
- **Present_Load** (60): the loop's duty [0.1 %, sign bit 10]. The loop reads the same
  encoder, so a reading a count off comes with the duty the firmware's law gives at that
  count (roboninecom's telemetry: a servo resting at its goal reads 2346/2347 with a load of
  -1.2 %/0 in step). In PWM mode the duty written.
- **Present_Current** (69), **Present_Voltage** (62): ``virtual/electrical.py``'s model, with
  its seeded reading noise.
"""

from __future__ import annotations

import math

from so101_kinematics import servo as servo_facts
from so101_kinematics.servo import COUNTS_PER_TURN
from so101_kinematics.virtual.electrical import (
    CURRENT_FLICKER,
    VOLTAGE_FLICKER,
    limp_current,
    noisy_reading,
    status_bits,
)
from so101_kinematics.virtual.servo_memory import VirtualServo
from so101_kinematics.virtual.shipped_calibration import TICKS_PER_RAD

__all__ = ["PWM_DIRECTION", "SensorReadings"]

ENCODER_NOISE = 0.3
"""How often a Present_Position reading is a count off (either way, seeded): a real STS3215 at
rest reads a count or two apart from one read to the next (issue 26, clients on real arms)."""
ENCODER_OUTSIDE_POSITION_MODE = True
"""In wheel, PWM and step modes Present_Position is the bare encoder, Homing_Offset not
subtracted (the servolab client's source, as issue 34 reports it; not found in Feetech's
public documents: docs/virtual_arm_protocol.md)."""
PWM_DIRECTION = -1
"""Operating_Mode 2: a positive duty turns the output the way Present_Position counts down, as
on a real STS3215 (lerobot PR #4547's bench check, firmware 3.10: a positive duty moved the joint
-227 counts, the same duty with bit 10 set +130; the servolab client's source, issue 34)."""


class SensorReadings:
    """The Present_* registers and status bits from the simulation (a mixin of the emulator).

    Expects ``d``, ``bank``, ``supply``, ``voltage``, ``noise``, ``readings_noise`` and the
    register methods (``servo_settings`` through ``registers``) on the instance.
    """

    def effort(self, servo: VirtualServo) -> float:
        """Present_Load: the duty the servo's loop applies [0.1 %]; 0 when limp.

        In PWM mode the duty written (its sign as written, though the motor turns the
        other way: ``PWM_DIRECTION``).
        """
        if servo.stalled_at is not None:
            return servo.load
        if not servo.torque:
            return 0.0
        duty = self.bank.duty[servo.index]
        return duty * PWM_DIRECTION * math.copysign(1.0, servo.scale) if servo.regs[33] == 2 \
            else duty

    def current(self, servo: VirtualServo) -> float:
        """The servo's motor current [A] (a stalled one draws its stall duty's).

        A limp servo's driver is off: a back-driven motor draws nothing until its EMF
        overcomes the supply (``electrical.limp_current``).
        """
        variant = self.bank.variant
        if servo.stalled_at is not None:
            return abs(servo.load) / 1000.0 * self.supply * variant.torque_per_volt / variant.kt
        velocity = float(self.d.qvel[servo.dofadr])
        if not servo.torque:
            emf = variant.emf_damping / variant.torque_per_volt * velocity  # kt w [V]
            return limp_current(emf, self.bank.volts, variant.kt / variant.torque_per_volt)
        return self.bank.current(servo.index, velocity)

    def refresh(self, servo: VirtualServo, lo: int = 56, hi: int = 71) -> None:
        """Update the servo's Present_* registers overlapping [lo, hi) from the simulation."""
        d, regs = self.d, servo.regs
        angle = servo.stalled_at if servo.stalled_at is not None else float(d.qpos[servo.qadr])
        noise = self.noise.random()
        jitter = -1 if noise < ENCODER_NOISE / 2 else 1 if noise > 1 - ENCODER_NOISE / 2 else 0
        present = (round(servo.base + servo.scale * angle + servo.delta) + jitter) % COUNTS_PER_TURN
        if not servo.torque and self.rules["limp_goal"] == "follows":  # the STS's (rules.py)
            servo.set("Goal_Position", present)
        if ENCODER_OUTSIDE_POSITION_MODE and not servo.position_mode:  # the bare encoder
            present = (present + servo.get("Homing_Offset")) % COUNTS_PER_TURN
        regs[56] = present & 0xFF
        regs[57] = present >> 8
        if hi <= 58:
            return
        velocity = float(d.qvel[servo.dofadr]) * TICKS_PER_RAD
        velocity = round(velocity / servo_facts.VELOCITY_STEP) * servo_facts.VELOCITY_STEP
        load = self.effort(servo)
        if jitter and servo.torque and servo.stalled_at is None and servo.regs[33] in (0, 3):
            load += self.jitter_duty(servo, jitter)  # the loop reads the same encoder
        load = max(-1000, min(1000, round(load)))
        servo.set("Present_Velocity", max(-32767, min(32767, velocity)))
        servo.set("Present_Load", load)
        readings = self.readings_noise
        regs[62] = max(0, min(255, noisy_reading(self.voltage, readings, VOLTAGE_FLICKER)))
        regs[63] = max(0, min(255, round(servo.temperature)))
        amps = self.current(servo) / servo_facts.CURRENT_UNIT_A
        servo.set("Present_Current", noisy_reading(amps, readings, CURRENT_FLICKER) if load
                  else round(amps))
        regs[66] = int(abs(velocity) > 20)
        regs[65] = self.error_byte(servo)

    def jitter_duty(self, servo: VirtualServo, jitter: int) -> float:
        """How much the loop's duty [0.1 %] changes when its encoder reads ``jitter`` off.

        The firmware's law (``servo.duty``) at the error it would see, less the one it sees.
        """
        settings = self.settings_of(servo)
        target = self.bank.target[servo.index] if self.bank.target is not None else 0.0
        position = round(float(self.d.qpos[servo.qadr]) * servo_facts.COUNTS_PER_RAD)
        error = round(target) - position
        seen = error - jitter * math.copysign(1.0, servo.scale)
        return servo_facts.duty(seen, settings) - servo_facts.duty(error, settings)

    def error_byte(self, servo: VirtualServo) -> int:
        """The servo's status error bits: injected ones, and the electrical model's.

        A stalled joint (fault ``stall``) is overloaded as soon as its load
        reaches Overload_Torque; any other load must stay there for Protection_Time.
        """
        regs = servo.regs
        overloaded = servo.protected or \
            (servo.overload_time >= 0.01 * regs[35] and servo.overload_time > 0)
        if servo.stalled_at is not None and abs(servo.load) >= 10 * regs[36]:
            overloaded = True
        bits = status_bits(servo.temperature, self.voltage, overloaded, regs[13],
                           (regs[15], regs[14]))
        return servo.error_bits | bits
