"""The emulator's faults (injected, cleared) and the commands its parent sends (a mixin)."""

from __future__ import annotations

import logging
import os
import statistics
import time

from so101_kinematics import cube_sensor
from so101_kinematics.virtual.protocol import ADDR, EEPROM_END, ERROR_BITS, FIRMWARE

logger = logging.getLogger("virtual_so101")


class ParentCommands:
    """Faults and the parent's commands, applied to the emulator's servos and simulation.

    Expects the emulator's state on the instance (``servos``, ``by_joint``,
    ``m``, ``d``, ``smu``, ``goal_log``, the reply statistics and the pty).
    """

    def inject(self, faults: list[tuple]) -> None:
        """Apply parsed faults (``arm.parse_faults``): the bus, a servo, or the cable."""
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
        """Remove every fault that can be undone (not an unplugged cable)."""
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

    # --- the cube (when the arm was started with one) ------------------------------------
    def cube_reading(self) -> bytes:
        """The cube sensor's reply data (see ``so101_kinematics.cube_sensor``)."""
        if not self._has_cube():
            return cube_sensor.encode_absent()
        from so101_kinematics.sim.cube import cube_state

        centre, tilt, held = cube_state(self.m, self.d)
        return cube_sensor.encode(centre, tilt, held)

    def _has_cube(self) -> bool:
        return (self.mujoco.mj_name2id(self.m, self.mujoco.mjtObj.mjOBJ_BODY, "cube") >= 0
                and not getattr(self, "cube_removed", False))

    def place_cube(self, x: float, y: float, yaw_deg: float = 0.0) -> None:
        """Put the cube on the table at (x, y) [m], turned ``yaw_deg``, as a hand would."""
        from so101_kinematics.sim.cube import cube_on_table, cube_state

        if self.mujoco.mj_name2id(self.m, self.mujoco.mjtObj.mjOBJ_BODY, "cube") < 0:
            raise ValueError("This virtual arm has no cube. Fix: start it with --cube X Y.")
        if self._has_cube() and cube_state(self.m, self.d)[2]:
            raise ValueError("The cube is in the jaws: open the gripper first.")
        joint = self.m.joint("cube")
        centre, quat = cube_on_table(x, y, yaw_deg)
        self.d.qpos[joint.qposadr[0]:joint.qposadr[0] + 7] = [*centre, *quat]
        self.d.qvel[joint.dofadr[0]:joint.dofadr[0] + 6] = 0.0
        self.m.body_gravcomp[self.m.body("cube").id] = 0.0
        self.cube_removed = False
        self.mujoco.mj_forward(self.m, self.d)

    def remove_cube(self) -> None:
        """Take the cube away: it floats 5 m from the arm, out of every contact."""
        if self.mujoco.mj_name2id(self.m, self.mujoco.mjtObj.mjOBJ_BODY, "cube") < 0:
            return
        joint = self.m.joint("cube")
        self.d.qpos[joint.qposadr[0]:joint.qposadr[0] + 3] = (5.0, 5.0, 1.0)
        self.d.qvel[joint.dofadr[0]:joint.dofadr[0] + 6] = 0.0
        self.m.body_gravcomp[self.m.body("cube").id] = 1.0
        self.cube_removed = True
        self.mujoco.mj_forward(self.m, self.d)

    def command(self, name: str, args: tuple):
        """Answer one command of the parent process (``VirtualSO101``'s methods)."""
        smu = self.smu
        if name == "cube":
            return cube_sensor.decode(self.cube_reading())
        if name == "place_cube":
            return self.place_cube(*args)
        if name == "remove_cube":
            return self.remove_cube()
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

