"""The sag ``so101 compare`` reports at the pick and the place: the simulator's, table included.

Without the gravity feed-forward a joint holds its load only by erring from its goal
(``gravity.feedforward``: the free-air figure). At a low pose the jaw comes down onto
the table, which then carries part of the arm: the sag is what the simulator shows
there, the arm placed at the pose at rest, its servos (the log's supply and P, the
feed-forward off) holding it, on the course's scene with its table (``model/scene.xml``).
Measured 2026-12-03 at the course's pick (P = 16, 5 V): shoulder_lift 3.4, elbow_flex
1.4 deg with the jaw on the table (1.5 N), against 6.7 and 3.35 deg in free air (the
same simulation without the table: 6.8 and 3.0 deg).
"""

from __future__ import annotations

from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.servo import KIT_SUPPLY_V
from so101_kinematics.sim.table_contact import table_force_n

__all__ = ["describe_servo", "logged_supply"]

SETTLE_S = 1.5  # [s] held before the reading; the sag above settles within 0.5 s


def simulated_sag(cfg: dict[str, float], volts: float, p: int) -> tuple[dict[str, float], float]:
    """The arm's sag at ``cfg`` [deg] (arm joints) and its force on the table [N].

    Args:
        cfg: the pose ([deg], gripper [0, 100]); clamped to the model's limits.
        volts: the servos' supply [V].
        p: their P coefficient.
    """
    import mujoco

    from so101_kinematics.sim import actuation
    from so101_kinematics.sim.scene import (
        get_configuration,
        joint_limits,
        load_model,
        set_initial_pose,
    )

    m = load_model()
    actuation.use_servo(m, volts=volts, p=p, feedforward=False)
    limits = joint_limits(m)
    pose = {j: min(limits[j][1], max(limits[j][0], float(cfg[j]))) for j in JOINTS}
    d = mujoco.MjData(m)
    set_initial_pose(d, pose)
    actuation.step(m, d, round(SETTLE_S / m.opt.timestep))
    reached = get_configuration(m, d)
    return ({j: round(reached[j] - pose[j], 2) for j in ARM_JOINTS},
            round(table_force_n(m, d), 2))


def logged_supply(servo: dict) -> float:
    """The supply [V] a log's servo record names; a log that records none: the kit's 5 V."""
    return float(servo.get("supply_v", KIT_SUPPLY_V))


def describe_servo(result, servo: dict | None, roles) -> None:
    """``result.servo`` (the servo the log records) and the sag at the pick and the place."""
    if not isinstance(servo, dict):
        result.servo = "not recorded (a log from before the servo model): replayed as STS3215 " \
                       "at lerobot's P = 16 on 5 V, without the feed-forward"
        servo = {}
    volts, p = logged_supply(servo), int(servo.get("p", 16))
    if not result.servo:
        with_ff = "with" if servo.get("gravity_ff") else "without"
        result.servo = f"STS3215 at P = {p} on {volts:.1f} V, {with_ff} the gravity feed-forward"
    for role, step in zip(("pick", "place"), roles, strict=False):
        result.sag_deg[role], result.sag_table_n[role] = simulated_sag(step.configuration,
                                                                       volts, p)
