"""The instructions the virtual STS3215s obey, and the replies they put on the bus (a mixin).

Feetech protocol 0 as the servo's firmware answers it (Feetech's protocol page,
ftservo/ftservo-wiki ``docs/en/reference/protocol/ft-scs.md``, and its memory table
``docs/en/reference/parameter/memory-sts.md``); ``docs/virtual_arm_protocol.md`` has the
table of what is covered.

- PING, READ, WRITE, SYNC_READ, SYNC_WRITE; REG_WRITE (0x04) stores a write and sets
  the Registered flag (address 64), ACTION (0x05, broadcast or to one ID) applies it
  and clears the flag; RESET (0x06) restores every parameter but the ID from the
  backup image (the factory EEPROM until BACKUP, 0x09, replaces it); RESTART (0x08)
  is a power cycle of that servo, not answered (rule ``restart_reply``: answered);
  0x0A (clear the turn count) is answered and changes nothing (no multi-turn mode
  here); 0x0B sets the present position to the middle (2048) or to its parameter.
  Any other instruction, a malformed one, or one to an ID nobody has is ignored: no
  reply.
- Who answers: never a broadcast, except PING; PING and READ (and SYNC_READ) always;
  every other instruction only when the servo's Response_Status_Level (address 8)
  is 1 (the factory value), judged when the instruction arrives. A reply is built
  before the instruction acts, so it comes from the addressed ID.
- Servos sharing an ID all obey, and all answer at once: the host receives the
  collision of their replies on the half-duplex line (:func:`protocol.collide`).
  About 4 in 10 times (``GARBLED_FRACTION``, seeded) they start 2 us apart and even
  identical replies fail the checksum or lose the header; otherwise they start in
  step and only replies that differ collide.
"""

from __future__ import annotations

import logging
import os
import random
import time

from so101_kinematics.sensors import cube_wire as cube_sensor
from so101_kinematics.servo import COUNTS_PER_TURN
from so101_kinematics.virtual.protocol import (
    BITS_PER_BYTE,
    BROADCAST_ID,
    EEPROM_END,
    INST_ACTION,
    INST_BACKUP,
    INST_CALIBRATE,
    INST_PING,
    INST_READ,
    INST_REG_WRITE,
    INST_RESET,
    INST_RESET_TURNS,
    INST_RESTART,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    REGISTERED,
    collide,
    status_packet,
)
from so101_kinematics.virtual.sim_clock import LEROBOT_TIMEOUT_S

__all__ = ["BusInstructions"]

logger = logging.getLogger("virtual_so101")

LATE_REPLY = 0.045  # [s] after this, lerobot (50 ms timeout) may have given up
COLLISION_SKEW_S = 2e-6  # [s] between two same-ID servos' replies when they drift apart: one
# Return_Delay_Time unit (2 us, the memory table's); a choice: the firmware's jitter is
# not published.
GARBLED_FRACTION = 0.4
"""How often two same-ID servos' replies start far enough apart to garble even identical
replies: about 4 in 10 (the servolab client's measurement on a real bus, as issue 34 reports it).
The rest start within a fraction of a bit, so identical replies (PING, a WRITE's status) come
through intact; replies that differ (two READs of different positions) collide anyway."""
IN_STEP_BITS = 0.25  # [bits] most two in-step transmitters differ by (< half a bit: read alike)


class BusInstructions:
    """The protocol side of the emulator: one instruction packet in, the bus's replies out.

    Expects the emulator's state on the instance (``listening``, ``host_baud``,
    ``wire_timing``, ``wire_free``, ``master``, the reply statistics, ``sim_clock``) and the
    register methods of :class:`~so101_kinematics.virtual.registers.ServoRegisters`.
    """

    def handle(self, packet: bytes, t_seen: float) -> None:
        """Obey one instruction packet (checksum already checked) and send the replies."""
        target, inst, params = packet[2], packet[4], packet[5:-1]
        tpb = BITS_PER_BYTE / max(1, self.host_baud)
        if self.wire_timing:  # the request ends on the wire after its bytes (queued behind others)
            t_end = max(t_seen, self.wire_free) + len(packet) * tpb
            self.wire_free = t_end
        else:
            t_end = t_seen
        if target == cube_sensor.SENSOR_ID:  # the lab's cube sensor: READ only, never PING
            index = cube_sensor.index_of(*params) if inst == INST_READ and len(params) == 2 \
                else None
            if index is not None:
                self.send_sensor(self.cube_reading(index), t_end, tpb)
            return
        listening = self.listening
        broadcast = target == BROADCAST_ID
        replies: list[list[tuple]] = []  # groups of (servo, reply id, params) answering at once
        if inst == INST_PING:
            if broadcast:
                replies = [[(s, i, b"") for s in group] for i, group in sorted(listening.items())]
            elif target in listening:
                replies = [[(s, target, b"") for s in listening[target]]]
        elif inst == INST_READ:
            if len(params) == 2 and target in listening:
                replies = [[(s, target, self.read(s, params[0], params[1]))
                            for s in listening[target]]]
        elif inst == INST_SYNC_READ:
            if broadcast and len(params) >= 2:
                addr, size = params[0], params[1]
                for servo_id in params[2:]:
                    group = listening.get(servo_id, ())
                    if group:
                        replies.append([(s, servo_id, self.read(s, addr, size)) for s in group])
        elif inst == INST_SYNC_WRITE:
            if broadcast and len(params) >= 2:
                addr, size = params[0], params[1]
                body = params[2:]
                for i in range(0, len(body) - size, size + 1):
                    for servo in listening.get(body[i], ()):
                        self.write(servo, addr, body[i + 1:i + 1 + size])
        else:
            obey = self._obey(inst, params)
            if obey is None:  # not an instruction an STS3215 knows, or malformed: ignored
                logger.debug("instruction 0x%02x to %d ignored", inst, target)
                return
            if broadcast:
                addressed = [s for _, group in sorted(listening.items()) for s in group]
            else:
                addressed = list(listening.get(target, ()))
            silent = broadcast or (inst == INST_RESTART and self.rules["restart_reply"] == "none")
            answering = [] if silent else [(s, target, b"") for s in addressed if s.regs[8] != 0]
            for servo in addressed:
                obey(servo)
            replies = [answering] if answering else []
        if replies:
            self.send(replies, t_end, tpb)

    def _obey(self, inst: int, params: bytes):
        """What instruction ``inst`` does to one servo, or None if a servo ignores it."""
        if inst in (INST_WRITE, INST_REG_WRITE) and len(params) < 2:
            return None
        if inst == INST_WRITE:
            return lambda servo: self.write(servo, params[0], params[1:])
        if inst == INST_REG_WRITE:
            return lambda servo: self.register_write(servo, params[0], bytes(params[1:]))
        if inst == INST_ACTION and not params:
            return self.act
        if inst == INST_RESET and not params:
            return self.restore_parameters
        if inst == INST_BACKUP and not params:
            return lambda servo: setattr(servo, "backup", bytes(servo.regs[:EEPROM_END]))
        if inst == INST_RESTART and not params:
            return self.power_up
        if inst == INST_RESET_TURNS and not params:
            return lambda servo: None
        if inst == INST_CALIBRATE and len(params) in (0, 2):
            value = COUNTS_PER_TURN // 2 if not params else params[0] | params[1] << 8
            return lambda servo: self.set_present(servo, value)
        return None

    # --- what the instructions do to one servo ------------------------------------------------
    def register_write(self, servo, addr: int, data: bytes) -> None:
        """REG_WRITE: hold the write until ACTION; the Registered flag (64) reads 1."""
        servo.registered = (addr, data)
        servo.regs[REGISTERED] = 1

    def act(self, servo) -> None:
        """ACTION: apply the held write, if any; the Registered flag reads 0 again."""
        if servo.registered is not None:
            addr, data = servo.registered
            servo.registered = None
            servo.regs[REGISTERED] = 0
            self.write(servo, addr, data)

    def restore_parameters(self, servo) -> None:
        """RESET (0x06): every EEPROM parameter but the ID from the backup image.

        Feetech: "restore all servo parameters except the ID". The baud rate goes back
        too (a servo at 57 600 returns to 1 Mbit/s); the RAM registers stay. Saved
        when Lock = 0 ("unlock the EEPROM before restoring"), else until a power cycle.
        A servo with torque on holds where it is (its offset and limits changed).
        """
        image = bytearray(servo.backup)
        image[5] = servo.regs[5]
        servo.regs[:EEPROM_END] = image
        if servo.regs[55] == 0:
            servo.saved = bytes(image)
        servo.sync_cache()
        self._apply_torque(servo)
        if servo.torque:
            self._hold(servo)
        self.servos = {s.id: s for s in self.by_joint.values()}
        self.update_listening()

    # --- replies --------------------------------------------------------------------------
    def send_sensor(self, data: bytes, t_end: float, tpb: float) -> None:
        """The cube sensor's reply: no error bits, no servo faults (the bus-wide ones apply)."""
        packet = status_packet(cube_sensor.SENSOR_ID, 0, data)
        deadline = t_end + len(packet) * tpb
        if self.wire_timing:
            _wait_until(deadline)
        self._emit(packet, deadline, t_end)

    def send(self, replies: list[list[tuple]], t_end: float, tpb: float) -> None:
        """Send the replies, one after the other; a group of several collides on the line."""
        t_ready = t_end
        out = []
        for group in replies:
            packets = [p for p in (self._status(*reply) for reply in group) if p is not None]
            if not packets:
                continue
            packet = packets[0] if len(packets) == 1 else \
                collide(packets, self.host_baud, self.collision_skew())
            t_ready += group[0][0].return_delay + len(packet) * tpb
            out.append((t_ready, packet))
        if not out:
            return
        if self.latency_left > 0:  # late replies (injected): the whole batch waits
            self.latency_left -= 1
            if self.sim_clock is not None:  # the host waited that long, or gave up
                self.sim_clock.charge(min(self.latency, LEROBOT_TIMEOUT_S))
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

    def collision_skew(self) -> float:
        """[s] between two same-ID servos' replies: seeded, ``GARBLED_FRACTION`` drift apart."""
        rng = self.__dict__.setdefault("collisions", random.Random(254))
        if rng.random() < GARBLED_FRACTION:
            return COLLISION_SKEW_S
        return rng.uniform(0.0, IN_STEP_BITS) / max(1, self.host_baud)

    def _status(self, servo, reply_id: int, params: bytes) -> bytes | None:
        """One servo's status packet, or None when a fault drops it."""
        if servo.drop:
            servo.drop -= 1
            return None
        if servo.removed:
            return None
        packet = status_packet(reply_id, self.error_byte(servo), params)
        if servo.corrupt:
            servo.corrupt -= 1
            packet = packet[:-1] + bytes(((packet[-1] + 1) & 0xFF,))
        return packet

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


SPIN_S = float(os.environ.get("VIRTUAL_SO101_SPIN_S", "1e-4"))  # [s] busy-wait before a reply


def _wait_until(deadline: float) -> None:
    """Sleep, then spin the last ``SPIN_S``, until ``time.perf_counter() >= deadline``.

    The process runs with a 1 us timer slack (``emulator._tighten_timer_slack``),
    so a short sleep wakes within tens of microseconds; sleeping rather than
    spinning keeps the emulator a light, interactive task for the scheduler,
    which then wakes it promptly on a busy machine.
    """
    remaining = deadline - time.perf_counter()
    if remaining > SPIN_S:
        time.sleep(remaining - SPIN_S)
    while time.perf_counter() < deadline:
        pass
