"""The STS3215's dynamics, for any number of servos at once: the simulator's and the virtual arm's.

Each physics step, for each servo (numbers and sources in ``so101_kinematics/servo.py``):

1. **Profile**: the firmware moves an internal target towards the goal (integer
   counts) at most at Goal_Velocity (0: 3400 counts/s) with Acceleration x 100
   counts/s^2 (0: no ramp), braking in time to stop on the goal: a triangular or
   trapezoidal profile [TEL]. In wheel mode (Operating_Mode 1) the target runs at
   the signed wheel speed instead.
2. **Loop**: the error (target - encoder, in whole counts) gives the duty by the
   [TEL] law: 0 inside the dead zone, else Minimum_Startup_Force + P/4 per count;
   plus D x (the error's rate times ``servo.D_SCALE_S``) / 4, the error taken unrounded
   (fitted to real arms' recordings, ``lab/replay.py``), and I x (the error integrated
   over 1 / I_RATE s) / 4 (a stated assumption); capped by
   Torque_Limit and 97 %. That duty is Present_Load. In PWM mode (Operating_Mode 2)
   the duty is the one written.
3. **Motor**: torque = (kt/R) V x duty, where the push is computed on the error less
   half the gear play (the motor crosses the play first). The back-EMF and viscous
   damping and the Coulomb friction are the joint's own ``damping`` and
   ``frictionloss`` in the model (BAM's numbers), so they also act on a limp joint.

Idealised: one voltage per bank (the virtual arm sags it with the bus's current), no
thermal derating of the torque, backlash lumped into the loop as above, the firmware's
integer arithmetic kept only where it shows (whole counts of error, 50 counts/s steps).
"""

from __future__ import annotations

import math

from so101_kinematics import servo

__all__ = ["ServoBank"]


class ServoBank:
    """``n`` STS3215 servos' registers and state, stepped together.

    Plain Python floats, one list entry per servo: for six servos a scalar loop is
    several times faster than numpy on arrays of six (about 15 us a step here).

    Args:
        settings: one ``servo.Settings`` per servo.
        volts: the supply [V].
        variant: a key of ``servo.VARIANTS``.
        backlash_deg: gear play [deg] (``servo.BACKLASH_DEG``).
    """

    _REGISTERS = ("p", "d", "i", "min_startup", "dead_zone", "acceleration", "goal_velocity",
                  "torque_limit")

    def __init__(self, settings, volts: float, variant: str = "C001",
                 backlash_deg: float = servo.BACKLASH_DEG):
        self.n = n = len(settings)
        self.variant = servo.VARIANTS[variant]
        self.volts = float(volts)
        self.backlash_half = math.radians(backlash_deg) / 2 * servo.COUNTS_PER_RAD  # [counts]
        self.torque_on = [True] * n
        self.mode = [0] * n
        self.pwm = [0.0] * n  # [0.1 %] signed, Operating_Mode 2
        self.wheel_speed = [0.0] * n  # [counts/s] signed, Operating_Mode 1
        for name in self._REGISTERS:
            setattr(self, name, [float(getattr(s, name)) for s in settings])
        self.target: list[float] | None = None  # [counts] the profile's, set on the first step
        self.target_speed = [0.0] * n  # [counts/s]
        self.integral = [0.0] * n  # [counts s]
        self.last_error = [0.0] * n  # [counts] whole
        self.last_exact = [None] * n  # [counts] the unrounded error, for the D term
        self.duty = [0.0] * n  # [0.1 %] the last step's, signed: Present_Load
        self._derive()

    def set(self, index: int, settings: servo.Settings) -> None:
        """Load one servo's registers (after a write)."""
        for name in self._REGISTERS:
            getattr(self, name)[index] = float(getattr(settings, name))
        self._derive()

    def _derive(self) -> None:
        """The per-servo constants of the hot loop, from the registers (and a fresh cache)."""
        self._push = [0.0] * self.n  # [0.1 %] the last push before D, reused while the error stands
        self._p_duty = [0.0] * self.n  # [0.1 %] the same for the duty (Present_Load)
        self._cached_on = [None] * self.n  # the torque state it was computed for (None: none)
        self._fixed = list(zip(
            [v or servo.TARGET_RATE_MAX for v in self.goal_velocity],  # [counts/s]
            [a * servo.ACCELERATION_UNIT or math.inf for a in self.acceleration],  # [counts/s^2]
            self.dead_zone, [p / 4.0 for p in self.p], self.min_startup,
            [d / 4.0 for d in self.d], [min(t, servo.DUTY_MAX) for t in self.torque_limit],
            strict=True))

    def reset_target(self, index: int, position_counts: float) -> None:
        """Put the profile's target on the joint (torque just switched on): no jump, no ramp."""
        if self.target is not None:
            self.target[index] = float(position_counts)
            self.target_speed[index] = 0.0
            self.integral[index] = 0.0
            self.last_error[index] = 0.0
            self.last_exact[index] = None
            self._cached_on[index] = None
    def stiffness(self) -> list[float]:
        """Each servo's linearised stiffness [N m/rad] at its P and this bank's supply."""
        per_duty = self.variant.torque_per_volt * self.volts / 4000.0 * servo.COUNTS_PER_RAD
        return [per_duty * p for p in self.p]

    def torques(self, goal_rad, q, dt: float) -> list[float]:
        """One step: the torque [N m] each servo applies, given goals and joint angles [rad].

        Args:
            goal_rad: Goal_Position of each servo, as a joint angle [rad].
            q: each joint's angle [rad] (the encoder reads it in whole counts).
            dt: the step [s].
        """
        cpr = servo.COUNTS_PER_RAD
        if self.target is None:
            self.target = [float(round(x * cpr)) for x in q]
        newtons = self.variant.torque_per_volt * self.volts / 1000.0  # [N m per 0.1 %]
        half_play, rate = self.backlash_half, servo.D_SCALE_S / dt
        targets, speeds, last, duties = self.target, self.target_speed, self.last_error, self.duty
        exact_last, p_duties = self.last_exact, self._p_duty
        pushes, cached = self._push, self._cached_on
        modes, on, i_gain = self.mode, self.torque_on, self.i
        sqrt, copysign = math.sqrt, math.copysign
        out = []
        for k, (vmax, accel, zone, p4, startup, d4, cap) in enumerate(self._fixed):
            target, speed, mode = targets[k], speeds[k], modes[k]
            goal = round(goal_rad[k] * cpr)
            if mode == 1:  # wheel: the target runs at the signed speed
                wanted = max(-vmax, min(vmax, self.wheel_speed[k]))
                kick = accel * dt
                speed += max(-kick, min(kick, wanted - speed))
                target += speed * dt
                targets[k], speeds[k] = target, speed
            elif speed or target != goal:  # the fastest speed that still stops on the goal
                distance = goal - target
                wanted = copysign(min(vmax, sqrt(2 * accel * abs(distance)), abs(distance) / dt),
                                  distance)
                kick = accel * dt
                speed += max(-kick, min(kick, wanted - speed))
                step = speed * dt
                if step * distance > 0 and abs(step) >= abs(distance):
                    target, speed = float(goal), 0.0  # lands on the goal
                else:
                    target += step
                targets[k], speeds[k] = target, speed
            counts = q[k] * cpr
            exact = target - counts  # unrounded, for the D term
            before = exact_last[k]
            exact_last[k] = exact
            error = round(target) - round(counts)
            if error == last[k] and cached[k] == on[k] and mode == 0 and not i_gain[k]:
                # the same error: the same P duty, plus the D term on the error's rate
                if before is None or not on[k]:
                    out.append(newtons * pushes[k])
                    continue
                damp = d4 * (exact - before) * rate
                push, duty = pushes[k] + damp, p_duties[k] + damp
                if push > cap:
                    push = cap
                elif push < -cap:
                    push = -cap
                if duty > cap:
                    duty = cap
                elif duty < -cap:
                    duty = -cap
                duties[k] = duty
                out.append(newtons * push)
                continue
            damp = 0.0 if before is None or not on[k] else d4 * (exact - before) * rate
            size = error if error >= 0 else -error
            if size > zone:
                duty = startup + p4 * (size - zone)
                size -= half_play
                push = startup + p4 * (size - zone) if size > zone else 0.0
                if error < 0:
                    duty, push = -duty, -push
            else:
                duty = push = 0.0
            extra = 0.0
            last[k] = error
            if i_gain[k]:
                limit = servo.DUTY_MAX * 4.0 / (i_gain[k] * servo.I_RATE)
                self.integral[k] = max(-limit, min(limit, self.integral[k] + error * dt))
                extra += i_gain[k] / 4.0 * self.integral[k] * servo.I_RATE
            if mode == 2:  # PWM: the duty written, open loop
                duty, push, extra, damp = self.pwm[k], self.pwm[k], 0.0, 0.0
            if not on[k]:
                duty = push = 0.0
            else:
                duty += extra
                push += extra
            p_duties[k], pushes[k] = duty, push  # before the D term (reused above)
            duty += damp
            push += damp
            # the firmware's cap on every duty: P, I and D, and a PWM write alike
            if duty > cap:
                duty = cap
            elif duty < -cap:
                duty = -cap
            if push > cap:
                push = cap
            elif push < -cap:
                push = -cap
            duties[k], cached[k] = duty, on[k]
            out.append(newtons * push)
        return out

    def current(self, index: int, velocity: float) -> float:
        """Servo ``index``'s motor current [A] at joint speed ``velocity`` [rad/s], last duty."""
        chosen = self.variant
        volts = self.volts * self.duty[index] / 1000.0
        emf = chosen.emf_damping / chosen.torque_per_volt * velocity  # kt w [V]
        return abs(volts - emf) * chosen.torque_per_volt / chosen.kt
