"""The throw's inverse: a cup on the table -> the release pose and speed the servos can reach.

The throw is an overarm swing in the arm's vertical plane: ``shoulder_lift``, ``elbow_flex``
and ``wrist_flex`` turn forward together at the same rate (``SWING_JOINTS``), one cubic move
of the week-9 tools (``planning.profiles``) from a wind-up ``SWING_DEG`` behind the release
pose to a follow-through as far past it. The release pose (``RELEASE_DEG``) is in the middle,
where the cubic's speed peaks and its acceleration is zero; there the ball's velocity is the
Jacobian's column sum times the joints' rate, ``ELEVATION_DEG`` above the horizontal.
``shoulder_pan`` aims: it turns to the cup before the swing.

The inverse, for a cup at ``(x, y)``:

1. the pan angle, the release point (the FK) and the velocity's direction (the Jacobian);
2. the release speed whose flight (``ball.flight``, with drag) comes down at the cup's rim
   above its centre (bisection: the range grows with the speed);
3. the joints' rate, speed over ``|J c|``, checked against what each STS3215 can turn at the
   release with its load there (:func:`joint_speed_limits`: the servo model's duty cap, less
   the gravity torque and Coulomb friction, over its damping); the cubic's duration follows
   from the rate.

The servo lags its goal (``servo.lag``), so the command leads the plan by its lag time, and
the speed the servo reaches is found by rehearsing the swing in the simulator
(``throw_run``), the release timed on that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics import servo
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import TOOL_SITE
from so101_kinematics.planning.profiles import PROFILES
from so101_kinematics.throwing.ball import Ball, flight
from so101_kinematics.throwing.throw_scene import CUP_HEIGHT

__all__ = [
    "CUP_DISTANCE_RANGE", "ELEVATION_DEG", "GRIPPER_HOLD", "RELEASE_DEG", "SPEED_MARGIN",
    "SWING_DEG", "SWING_JOINTS", "ThrowPlan", "joint_speed_limits", "plan_throw",
    "release_state", "throwing_range",
]

SWING_JOINTS = ("shoulder_lift", "elbow_flex", "wrist_flex")
"""The joints that swing (each at the same rate), base to tip."""
RELEASE_DEG = {"shoulder_lift": -60.0, "elbow_flex": -60.0, "wrist_flex": -15.0,
               "wrist_roll": 0.0}
"""The release pose [deg] (with ``shoulder_pan`` the aim): the arm up and back, the ball
0.43 m above the table and 0.2 m behind the base. Chosen from a grid of poses for the
largest ball speed per joint rate (``|J c|`` 0.89 m/rad) with the velocity 35-50 deg up and
the wind-up and follow-through inside the joints' limits."""
ELEVATION_DEG = 42.25
"""The ball's velocity above the horizontal at the release pose [deg] (the Jacobian's)."""
SWING_DEG = 50.0
"""Each swinging joint turns this far [deg], half before the release and half after. 70 put
the wind-up's moving jaw 54 mm below the table top (``clearance.lowest_point``: a real arm
strikes the table; the simulated one passed through it, the table touching the ball
alone); at 50 the arm's lowest part is the shoulder's box, 16 mm above it. The cubic's peak
acceleration, ``6 SWING_DEG / T^2``, stays under the firmware's ramp at the course's
Acceleration 254 (2232 deg/s^2) to the range's far end (1760 deg/s^2 at 0.8 m, 12 V)."""
GRIPPER_HOLD = 20.0
"""The gripper's command while it holds the ball [0-100 %]."""
SPEED_MARGIN = 0.9
"""A joint's planned rate stays under this share of its servo's speed at the release: a
servo reaches its top speed only asymptotically."""
CUP_DISTANCE_RANGE = (0.25, 1.0)
"""The cup's distance from the base [m] that ``throw.py`` accepts before the servos' own
check: nearer, the cup stands against the arm's base; the far end is the servos'
(:func:`throwing_range`)."""


@dataclass(frozen=True)
class ThrowPlan:
    """A planned throw.

    Attributes:
        pan_deg: ``shoulder_pan`` [deg]. release_point: (3,) [m]. release_velocity: (3,)
            [m/s]. rate: the swinging joints' rate at the release [rad/s]. duration: the
            cubic swing's duration [s]. target: the cup's (x, y) [m].
    """

    pan_deg: float
    release_point: np.ndarray
    release_velocity: np.ndarray
    rate: float
    duration: float
    target: tuple[float, float]

    def configuration(self, fraction: float) -> dict[str, float]:
        """The planned configuration [deg] at ``fraction`` of the swing (0.5: the release)."""
        cfg = {"shoulder_pan": self.pan_deg, **RELEASE_DEG, "gripper": GRIPPER_HOLD}
        share = PROFILES["cubic"](float(np.clip(fraction, 0.0, 1.0))) - 0.5
        for joint in SWING_JOINTS:
            cfg[joint] += SWING_DEG * share
        return cfg

    def rates_deg(self, fraction: float) -> dict[str, float]:
        """The swinging joints' planned rates [deg/s] at ``fraction`` of the swing."""
        if not 0.0 <= fraction <= 1.0:
            return dict.fromkeys(SWING_JOINTS, 0.0)
        rate = PROFILES["cubic"].velocity(fraction) * SWING_DEG / self.duration
        return dict.fromkeys(SWING_JOINTS, float(rate))


def release_state(m: mujoco.MjModel, pan_deg: float, rate: float = 1.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The object frame's position [m] and velocity [m/s] at the release pose, joints at ``rate``.

    Args:
        m: a model of the arm (the FK and the Jacobian are MuJoCo's).
        pan_deg: ``shoulder_pan`` [deg].
        rate: each swinging joint's rate [rad/s].
    """
    d = mujoco.MjData(m)
    for joint, value in {"shoulder_pan": pan_deg, **RELEASE_DEG}.items():
        d.qpos[m.joint(joint).qposadr[0]] = math.radians(value)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    jac = np.zeros((3, m.nv))
    site = m.site(TOOL_SITE).id
    mujoco.mj_jacSite(m, d, jac, None, site)
    dofs = [m.joint(j).dofadr[0] for j in SWING_JOINTS]
    return d.site_xpos[site].copy(), jac[:, dofs].sum(axis=1) * rate


def joint_speed_limits(m: mujoco.MjModel, pan_deg: float = 0.0, volts: float = 12.0,
                       variant: str = servo.DEFAULT_VARIANT) -> dict[str, float]:
    """Each swinging joint's top speed [rad/s] at the release pose, by the servo model.

    Full duty (``servo.DUTY_MAX``) at ``volts`` gives ``kt/R V 0.97``; less the gravity
    torque at the pose (MuJoCo's bias forces at rest) and the Coulomb friction, over the
    back-EMF and viscous damping: the speed where the motor's torque is all spent.
    """
    chosen = servo.VARIANTS[variant]
    d = mujoco.MjData(m)
    for joint, value in {"shoulder_pan": pan_deg, **RELEASE_DEG}.items():
        d.qpos[m.joint(joint).qposadr[0]] = math.radians(value)
    mujoco.mj_forward(m, d)
    limits = {}
    for joint in SWING_JOINTS:
        load = abs(float(d.qfrc_bias[m.joint(joint).dofadr[0]]))
        drive = chosen.stall_torque(volts) - load - chosen.coulomb
        limits[joint] = max(0.0, drive) / (chosen.emf_damping + chosen.viscous)
    return limits


def _speed_for(point, direction, ball: Ball, distance: float) -> tuple[float, float]:
    """The release speed [m/s] whose flight comes down at the rim ``distance`` [m] away; the reach.

    Returns:
        ``(speed, horizontal distance [m] reached at that speed)``.
    """
    low, high = 0.2, 8.0
    for _ in range(40):
        middle = 0.5 * (low + high)
        end = flight(point, direction * middle, ball, CUP_HEIGHT)[0]
        reached = math.hypot(end[0] - point[0], end[1] - point[1])
        low, high = (middle, high) if reached < distance else (low, middle)
    return high, reached


def throwing_range(m: mujoco.MjModel, ball: Ball, volts: float = 12.0,
                   variant: str = servo.DEFAULT_VARIANT) -> tuple[float, float, float]:
    """The cups' distances from the base [m] the servos can throw to, and the top speed [m/s].

    The farthest is the flight at the joints' top rate times ``SPEED_MARGIN`` (the release
    speed returned); the nearest is ``CUP_DISTANCE_RANGE``'s (the arm's base).

    Returns:
        ``(nearest [m], farthest [m], the release speed at the farthest [m/s])``.
    """
    point, per_rate = release_state(m, 0.0)
    rate = SPEED_MARGIN * min(joint_speed_limits(m, 0.0, volts, variant).values())
    end = flight(point, per_rate * rate, ball, CUP_HEIGHT)[0]
    return (CUP_DISTANCE_RANGE[0], min(CUP_DISTANCE_RANGE[1], float(end[0])),
            float(np.linalg.norm(per_rate)) * rate)


def _aim(m: mujoco.MjModel, x: float, y: float) -> tuple[float, np.ndarray, np.ndarray]:
    """The pan [deg] whose release heads at (x, y) [m]; the release point and velocity per rate.

    The pan axis is not the base frame's origin, nor the object frame in its plane, so the
    heading is corrected until the velocity's line passes over the cup (a few iterations).
    """
    pan = -math.degrees(math.atan2(y, x))  # a positive shoulder_pan turns the arm to -y
    for _ in range(6):
        point, per_rate = release_state(m, pan)
        wanted = math.atan2(y - point[1], x - point[0])
        heading = math.atan2(per_rate[1], per_rate[0])
        pan -= math.degrees(wanted - heading)
    point, per_rate = release_state(m, pan)
    return pan, point, per_rate


def plan_throw(m: mujoco.MjModel, target, ball: Ball, volts: float = 12.0,
               variant: str = servo.DEFAULT_VARIANT) -> ThrowPlan:
    """The planned throw at a cup whose axis stands at ``target`` (x, y) [m] on the table.

    Raises:
        PlanError: the cup out of throwing range, or the speed beyond the servos'.
    """
    x, y = (float(v) for v in target)
    distance = math.hypot(x, y)
    nearest, farthest, top_speed = throwing_range(m, ball, volts, variant)
    if not nearest <= distance <= farthest:
        why = ("nearer, the cup stands against the arm's base" if distance < nearest else
               f"farther needs a release faster than {top_speed:.2f} m/s: the swing above "
               f"{SPEED_MARGIN:.0%} of the STS3215 {variant}'s top speed at {volts:g} V")
        raise PlanError(f"cup at ({x:.3f}, {y:.3f}) m is {distance:.3f} m from the base, outside "
                        f"the {ball.name} ball's throwing range {nearest:.2f}-{farthest:.2f} m "
                        f"({why}). Fix: place the cup {nearest:.2f}-{farthest:.2f} m from the "
                        "base.")
    pan, point, per_rate = _aim(m, x, y)
    speed, _ = _speed_for(point, per_rate / np.linalg.norm(per_rate), ball,
                          math.hypot(x - point[0], y - point[1]))
    rate = speed / float(np.linalg.norm(per_rate))
    limits = joint_speed_limits(m, pan, volts, variant)
    for joint, top in limits.items():
        if rate > SPEED_MARGIN * top:
            raise PlanError(f"release speed {speed:.2f} m/s needs {joint} at {rate:.2f} rad/s; "
                            f"its STS3215 {variant} at {volts:g} V turns at most {top:.2f} rad/s "
                            f"there (planned up to {SPEED_MARGIN:.0%} of it). Fix: a nearer cup, "
                            f"or a higher supply (--supply).")
    duration = PROFILES["cubic"].peak_speed * math.radians(SWING_DEG) / rate
    return ThrowPlan(pan, point, per_rate * rate, rate, duration, (x, y))
