"""Stand-ins for the hardware tests that need no lerobot: a fake clock and a fake Feetech bus."""

from __future__ import annotations

import types

from so101_forward_kinematics import JOINTS
from so101_kinematics.calibration import MOTOR_IDS
from so101_kinematics.constants import HOME_POSE
from so101_kinematics.hw.control import ArmSession

HOME = HOME_POSE  # the virtual arm powers up there


class FakeClock:
    """Deterministic time: sleep advances it; each read advances 1 us (so spinning ends)."""

    def __init__(self):
        self.now = 1000.0
        self.sleeps = []

    def clock(self) -> float:
        self.now += 1e-6
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += max(0.0, seconds)


class FakeBus:
    """Enough of lerobot's FeetechMotorsBus for a session: servos follow goals instantly.

    ``stalled`` joints never move; ``fail_reads`` makes the next N sync_reads raise
    ConnectionError as lerobot does when a servo does not answer, and
    ``fail_until`` every read before that time of ``clock`` (an outage);
    ``status`` holds each servo's Status register (error bits); ``garbled_reads`` makes the
    next N position reads a misparsed reply (every arm joint about -2900 deg).
    """

    def __init__(self, calibration, pose, stalled=()):
        self.calibration = calibration
        self.motors = {j: types.SimpleNamespace(id=MOTOR_IDS[j]) for j in JOINTS}
        self.pose = dict(pose)
        self.stalled = set(stalled)
        self.goals: list[dict] = []
        self.torque = dict.fromkeys(JOINTS, True)
        self.fail_reads = 0
        self.fail_until = 0.0
        self.garbled_reads = 0  # the next N position reads come back misparsed
        self.clock = None
        self.status = dict.fromkeys(JOINTS, 0)
        self.reads = 0
        self.silent: set[str] = set()
        self.port_handler = types.SimpleNamespace(clearPort=lambda: None, is_using=False)

    def sync_write(self, name, values, normalize=True):
        assert name == "Goal_Position"
        self.goals.append(dict(values))
        for joint, value in values.items():
            if joint not in self.stalled:
                self.pose[joint] = value

    def sync_read(self, name, motors=None, *, normalize=True, num_retry=0):
        assert name in ("Present_Position", "Status", "Torque_Enable")
        outage = self.clock is not None and self.clock.now < self.fail_until
        if self.fail_reads > 0 or outage:
            self.fail_reads = max(0, self.fail_reads - 1)
            raise ConnectionError(f"Failed to sync read '{name}' on ids=[1, 2, 3, 4, 5, 6] after "
                                  f"{num_retry + 1} tries. [TxRxResult] There is no status packet!")
        if name == "Status":
            return dict(self.status)
        if name == "Torque_Enable":
            return {joint: int(on) for joint, on in self.torque.items()}
        self.reads += 1
        if self.garbled_reads > 0:  # as seen once through lerobot: IDs in the high byte
            self.garbled_reads -= 1
            return {j: -2925.7 + 22.5 * k if j != "gripper" else 0.0 for k, j in enumerate(JOINTS)}
        return dict(self.pose)

    def disable_torque(self, motors=None, num_retry=0):
        for joint in [motors] if isinstance(motors, str) else (motors or JOINTS):
            self.write("Torque_Enable", joint, 0)

    def write(self, name, motor, value, normalize=True, num_retry=0):
        if motor in self.silent:
            raise ConnectionError(f"{motor}: There is no status packet!")
        if name == "Torque_Enable":
            self.torque[motor] = bool(value)

    def ping(self, motor, num_retry=0, raise_on_error=False):
        """lerobot's contract: no reply -> ConnectionError, an error bit in the reply ->
        RuntimeError (both None unless ``raise_on_error``); else the model number."""
        if motor in self.silent or self.status[motor]:
            if raise_on_error:
                raise (ConnectionError if motor in self.silent else RuntimeError)(motor)
            return None
        return 777


def make_session(calibration, clock, pose=HOME, stalled=(), **kwargs):
    """An ArmSession on a FakeBus at ``pose``, timed by ``clock``; returns (session, bus)."""
    bus = FakeBus(calibration, pose, stalled)
    bus.clock = clock
    return ArmSession(bus, clock=clock.clock, sleep=clock.sleep, **kwargs), bus
