"""A hand on the virtual arm: moves limp joints as a student's hand does (a mixin of the emulator).

The hand grips the joints it moves and guides each towards a target that
travels along a path of waypoints (joint space, a smooth start and stop per
segment, at most :data:`HAND_SPEED` on the joint that moves most). The grip is
a guiding spring at the joint: the servo's own actuator with the servo's
stiffness and force limit (3.35 N m, what a hand easily applies at a joint) while
its Torque_Enable stays 0, plus the hand carrying the arm's weight (gravity
compensation on the gripped joints). So joint limits and the table stop the
hand as they stop the arm; the registers say "limp" throughout (Present_Load 0,
Goal_Position following Present_Position); the host's view is exactly that of
a limp servo moved from outside.

Rules:
- The hand moves only limp joints: a torqued servo holds its goal (enabling
  torque on a gripped joint makes the hand let go of it).
- Targets are checked against the joint limits; the whole path is checked
  against the table before the hand moves, by the project's one clearance
  check (``so101_kinematics/clearance.py``, the same as every commanded move):
  a path that brings a link, a jaw or the object frame within its margin of
  the table (or lower than it already is) is refused.
- After its path the hand keeps holding the joints where it put them (a limp
  arm would otherwise sag under gravity) until :meth:`hand_release`.
"""

from __future__ import annotations

import math

from so101_kinematics.clearance import check_path
from so101_kinematics.errors import ClearanceError

__all__ = ["Hand"]

HAND_SPEED = math.radians(90.0)  # [rad/s] average speed of the joint that moves most
MIN_SEGMENT_S = 0.3  # [s] shortest hand move


class HandError(ValueError):
    """The hand cannot do that (a torqued joint, a limit, the table); the message says why."""


class Hand:
    """The hand's state and motion (a mixin of the emulator).

    Expects ``m``, ``d``, ``by_joint`` and ``arm_time()`` (the arm's clock, wall or simulated).
    """

    hand_path: list[tuple[float, dict[str, float]]]  # (time [s, the arm's clock], targets)
    hand_grip: dict[str, float]  # joint -> current target [rad]

    def hand_move(self, waypoints: list[dict[str, float]]) -> float:
        """Move the named joints through ``waypoints`` (joint -> [rad]); returns the duration [s].

        Raises:
            HandError: a joint is torqued or unknown, a target outside its limits,
                or the path goes into the table. Nothing moves then.
        """
        joints = sorted({j for w in waypoints for j in w})
        for joint in joints:
            servo = self.by_joint.get(joint)
            if servo is None:
                raise HandError(f"unknown joint {joint!r}; joints are {list(self.by_joint)}")
            if servo.torque:
                raise HandError(f"{joint} is torqued (Torque_Enable = 1): its servo holds it and "
                                "a hand cannot move it; release torque first (`limp`)")
            lo, hi = (float(x) for x in self.m.joint(joint).range)
            for w in waypoints:
                if joint in w and not lo - 1e-9 <= w[joint] <= hi + 1e-9:
                    raise HandError(f"{joint} = {math.degrees(w[joint]):.1f} deg is outside its "
                                    f"limits [{math.degrees(lo):.1f}, {math.degrees(hi):.1f}]")
        start = {j: self.hand_grip.get(j, float(self.d.qpos[self.by_joint[j].qadr]))
                 for j in self.by_joint}
        points = [start]
        for w in waypoints:
            points.append(dict(points[-1], **w))
        self._check_table(points)
        now = self.arm_time()
        path = [(now, points[0])]
        for a, b in zip(points, points[1:], strict=False):
            span = max(abs(b[j] - a[j]) for j in a)
            path.append((path[-1][0] + max(MIN_SEGMENT_S, 1.5 * span / HAND_SPEED), b))
        self.hand_path = path
        for joint in self.by_joint:  # the hand takes the whole (limp) arm
            servo = self.by_joint[joint]
            if not servo.torque:
                self.hand_grip[joint] = start[joint]
                self._apply_torque(servo)
        return path[-1][0] - now

    def hand_remaining(self) -> float:
        """[s] until the hand's path ends (0 when it holds still)."""
        if not self.hand_path:
            return 0.0
        return max(0.0, self.hand_path[-1][0] - self.arm_time())

    def hand_release(self, joint: str | None = None) -> None:
        """The hand lets go (of ``joint``, default all): those joints are free (limp) again."""
        for name in [joint] if joint else list(self.hand_grip):
            self.hand_grip.pop(name, None)
            self.d.qfrc_applied[self.by_joint[name].dofadr] = 0.0
            self._apply_torque(self.by_joint[name])
        if not self.hand_grip:
            self.hand_path = []

    def step_hand(self, due: int) -> None:
        """Set the gripped joints' spring targets for now, and carry the arm's weight."""
        if not self.hand_grip:
            return
        now = self.arm_time()
        path = self.hand_path
        targets = path[-1][1] if path else {}
        for (t0, a), (t1, b) in zip(path, path[1:], strict=False):
            if now < t1:
                s = max(0.0, (now - t0) / (t1 - t0))
                s = s * s * (3.0 - 2.0 * s)  # smooth start and stop
                targets = {j: a[j] + s * (b[j] - a[j]) for j in a}
                break
        d = self.d
        for joint in self.hand_grip:
            servo = self.by_joint[joint]
            target = targets.get(joint, self.hand_grip[joint])
            self.hand_grip[joint] = target
            d.ctrl[servo.act] = target
            d.qfrc_applied[servo.dofadr] = d.qfrc_bias[servo.dofadr]

    def _check_table(self, points: list[dict[str, float]]) -> None:
        """Raise HandError if the path goes into the table (``clearance.check_path``)."""
        lo, hi = (float(x) for x in self.m.joint("gripper").range)

        def user(q: dict[str, float]) -> dict[str, float]:  # [rad] -> [deg], gripper [0, 100]
            return {j: 100.0 * (v - lo) / (hi - lo) if j == "gripper" else math.degrees(v)
                    for j, v in q.items()}

        # Answer the bus between segments, as the servos would: lerobot's 1-try reads
        # time out after ~34 ms while a tool (lerobot-calibrate) reads during a sweep.
        try:
            check_path([user(q) for q in points], [f"hand waypoint {i + 1}" for i in
                                                   range(len(points) - 1)],
                       base_height=getattr(self, "base_height", 0.0),
                       between=getattr(self, "serve_serial", None),
                       fix="move the arm up first or choose another pose")
        except ClearanceError as error:
            raise HandError(str(error)) from None
