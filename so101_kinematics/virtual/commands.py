"""The emulator's faults (injected, cleared) and the commands its parent sends (a mixin)."""

from __future__ import annotations

import logging
import os
import statistics
import time

from so101_kinematics.sensors import cube_wire as cube_sensor
from so101_kinematics.virtual.protocol import ADDR, EEPROM_END, ERROR_BITS, FIRMWARE
from so101_kinematics.virtual.servo_memory import FACTORY_ID, factory_eeprom

__all__ = ["ParentCommands"]

logger = logging.getLogger("virtual_so101")


class ParentCommands:
    """Faults and the parent's commands, applied to the emulator's servos and simulation.

    Expects the emulator's state on the instance (``servos``, ``by_joint``,
    ``m``, ``d``, ``smu``, ``goal_log``, the reply statistics, the pty and ``arm_time()``: an
    outage lasts its milliseconds on the arm's clock, wall or simulated).
    """

    def inject(self, faults: list[tuple]) -> None:
        """Apply parsed faults (``arm.parse_faults``): the bus, a servo, or the cable."""
        for kind, servo_id, arg in faults:
            if kind == "outage":
                self.outage_until = self.arm_time() + arg / 1000.0  # on the arm's clock
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

    def factory_reset(self) -> None:
        """Factory-fresh servos (ID 1, 1 Mbit/s, no offset, full range), none plugged in yet.

        They are plugged in one at a time in the order lerobot-setup-motors asks
        for them (gripper first, shoulder_pan last): the next one when the last
        one has been given a new ID and its baud rate, or on :meth:`plug_next`.
        """
        for servo in self.by_joint.values():
            servo.regs[:EEPROM_END] = factory_eeprom()
            servo.saved = bytes(servo.regs[:EEPROM_END])
            servo.load_torque_limit()
            servo.plugged = False
            servo.sync_cache()
        self.factory_queue = list(reversed(self.by_joint.values()))
        self.plug_next()

    def plug_next(self) -> str:
        """Plug the next factory servo into the bus; returns its joint's name."""
        if not self.factory_queue:
            raise ValueError("every servo is plugged in already")
        servo = self.factory_queue.pop(0)
        servo.plugged = True
        self.update_listening()
        logger.info("servo of %s plugged in (ID %d)", servo.joint, servo.id)
        return servo.joint

    def on_setup_write(self, servo) -> None:
        """After a Baud_Rate write: a renumbered servo is set up, the next one is plugged in."""
        if self.factory_queue and servo.id != FACTORY_ID:
            self.plug_next()

    def power_up(self, servo) -> None:
        """The servo's power cut and restored: RAM to factory values, EEPROM to what was saved.

        Torque_Limit is loaded from Max_Torque_Limit; the parameter backup (instruction
        0x09) is in flash and stays.
        """
        eeprom = servo.saved
        gains = servo.kp, servo.kv, servo.max_force  # the model's, before any torque change
        kept = servo.plugged, servo.temperature, servo.backup  # wiring; heat; flash
        servo.__init__(servo.joint, servo.cal, self.m)
        servo.kp, servo.kv, servo.max_force = gains
        servo.plugged, servo.temperature, servo.backup = kept
        servo.regs[:EEPROM_END] = eeprom
        servo.saved = eeprom
        servo.load_torque_limit()
        servo.sync_cache()
        self._apply_torque(servo)
        self.servos = {s.id: s for s in self.by_joint.values()}
        self.update_listening()

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
        for servo in self.by_joint.values():
            servo.error_bits = 0
            servo.drop = servo.corrupt = 0
            servo.removed = False
            servo.stalled_at = None
            servo.load = 0.0
            servo.regs[0], servo.regs[1] = FIRMWARE
        self.update_listening()

    # --- the cubes (when the arm was started with them) -----------------------------------
    def cube_reading(self, index: int = 0) -> bytes:
        """The cube sensor's reply data for cube ``index`` (``sensors/cube_wire.py``)."""
        if not self._has_cube(index):
            return cube_sensor.encode_absent()
        from so101_kinematics.sim.cube import cube_name, cube_state

        centre, tilt, held = cube_state(self.m, self.d, cube_name(index))
        return cube_sensor.encode(centre, tilt, held)

    def _cube_body(self, index: int) -> int:
        from so101_kinematics.sim.cube import cube_name

        return self.mujoco.mj_name2id(self.m, self.mujoco.mjtObj.mjOBJ_BODY, cube_name(index))

    def _has_cube(self, index: int = 0) -> bool:
        return self._cube_body(index) >= 0 and index not in getattr(self, "cubes_removed", ())

    def place_cube(self, x: float, y: float, yaw_deg: float = 0.0, index: int = 0) -> None:
        """Put cube ``index`` on the table at (x, y) [m], turned ``yaw_deg``, as a hand would."""
        from so101_kinematics.sim.cube import cube_name, cube_on_table, cube_state

        if self._cube_body(index) < 0:
            raise ValueError(f"This virtual arm has no cube {index + 1}. Fix: start it with "
                             "--cube X Y (once per cube).")
        if self._has_cube(index) and cube_state(self.m, self.d, cube_name(index))[2]:
            raise ValueError("The cube is in the jaws: open the gripper first.")
        joint = self.m.joint(cube_name(index))
        centre, quat = cube_on_table(x, y, yaw_deg, base_height=self.base_height)
        self.d.qpos[joint.qposadr[0]:joint.qposadr[0] + 7] = [*centre, *quat]
        self.d.qvel[joint.dofadr[0]:joint.dofadr[0] + 6] = 0.0
        self.m.body_gravcomp[self._cube_body(index)] = 0.0
        self.cubes_removed = set(getattr(self, "cubes_removed", ())) - {index}
        self.mujoco.mj_forward(self.m, self.d)

    def remove_cube(self, index: int = 0) -> None:
        """Take cube ``index`` away: it floats 5 m from the arm, out of every contact."""
        if self._cube_body(index) < 0:
            return
        joint = self.m.joint(self.m.body(self._cube_body(index)).name)
        self.d.qpos[joint.qposadr[0]:joint.qposadr[0] + 3] = (5.0, 5.0 + 0.1 * index, 1.0)
        self.d.qvel[joint.dofadr[0]:joint.dofadr[0] + 6] = 0.0
        self.m.body_gravcomp[self._cube_body(index)] = 1.0
        self.cubes_removed = set(getattr(self, "cubes_removed", ())) | {index}
        self.mujoco.mj_forward(self.m, self.d)

    def place_target(self, x: float, y: float, yaw_deg: float = 0.0, hidden: bool = False) -> None:
        """Lay the target tag at (x, y) [m], turned ``yaw_deg``, or hide it (the cameras')."""
        if self.cameras is None:
            raise ValueError("This virtual arm serves no camera: its target tag is drawn only "
                             "there. Fix: start it with --camera NAME --target X Y.")
        self.cameras.place_target(x, y, yaw_deg, hidden)

    def command(self, name: str, args: tuple):
        """Answer one command of the parent process (``VirtualSO101``'s methods)."""
        smu = self.smu
        if name == "cube":
            return cube_sensor.decode(self.cube_reading(*args))
        if name in ("place_cube", "remove_cube", "place_target"):
            return getattr(self, name)(*args)
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
            for servo in self.by_joint.values():
                if servo.stalled_at is not None:
                    servo.stalled_at = float(self.d.qpos[servo.qadr])
                self._hold(servo)
            self.rest_in_place()  # put down there: the torqued servos hold it without a sag
            return None
        if name == "set_torque":
            for servo in self.by_joint.values():
                if args[1] is None or servo.joint in args[1]:
                    self.write(servo, 40, bytes((int(args[0]),)))
            return None
        if name == "hand_move":
            return self.hand_move([smu.to_radians(self.m, w) for w in args[0]])
        if name == "hand_remaining":
            return self.hand_remaining()
        if name == "hand_release":
            return self.hand_release()
        if name == "plug":
            return self.plug_next()
        if name == "set_supply":
            self.supply = float(args[0])
            return None
        if name == "set_wire_timing":
            self.wire_timing = bool(args[0])
            return None
        if name == "registers":
            servo = self.by_joint[args[0]]
            self.refresh(servo)
            return {reg: servo.get(reg) for reg in ADDR}
        if name == "power_cycle":
            for servo in self.by_joint.values():
                self.power_up(servo)
            return None
        if name in ("camera_addresses", "camera_stats"):  # virtual/camera_server.py
            if self.cameras is None:
                return {}
            return self.cameras.addresses if name == "camera_addresses" else \
                self.cameras.camera_stats()
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

