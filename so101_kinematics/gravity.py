"""Gravity on the SO-101's joints, and the goal offsets that cancel the sag it causes.

A position servo holds a load only by being off its goal: the STS3215 at
lerobot's P = 16 sags several degrees at the shoulder (``servo.holding_error``).
:func:`feedforward` offsets each goal by the error the servo will need there, so
the joint comes to rest at the goal itself. It needs no MuJoCo: the link masses and
centres of mass are the upstream model's (``model/so101.xml``, ``<inertial>``), the
frames the FK's (``frames.get_frame_chain``); a test checks both against MuJoCo's
``qfrc_bias``.

Example (the all-zero pose: the shoulder holds the stretched arm)::

    >>> cfg = dict.fromkeys(("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex",
    ...                      "wrist_roll", "gripper"), 0.0)
    >>> round(holding_torques(cfg)["shoulder_lift"], 3)  # [N m]
    -0.539
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from so101_kinematics import model_facts, servo
from so101_kinematics.frames import (
    ARM_JOINTS,
    BODY_OF_FRAME,
    FIXED_ROTATION,
    FIXED_TRANSFORMS,
    GRIPPER_RANGE,
    JOINT_RANGES_RAD,
    MOVING_JAW_BODY,
    Rx,
    pose,
    read_angles,
)

__all__ = ["Feedforward", "MAX_OFFSET_DEG", "feedforward", "holding_torques"]

GRAVITY = 9.81
"""[m/s^2], MuJoCo's default (the model sets none)."""

LINKS = {frame: (model_facts.link_mass(body), model_facts.centre_of_mass(body))
         for frame, body in BODY_OF_FRAME.items()}
"""The moving links carried by each joint frame (the base does not move): mass [kg] and
centre of mass in the body's frame [m], ``model/so101.xml`` ``<inertial>``."""

JAW = (model_facts.link_mass(MOVING_JAW_BODY), model_facts.centre_of_mass(MOVING_JAW_BODY),
       model_facts.body_position(MOVING_JAW_BODY))
"""The moving jaw: mass [kg], centre of mass in its body [m], its body's position in the
gripper body [m] (rotated Rx(90 deg), then by the gripper joint), ``model/so101.xml``."""

MAX_OFFSET_DEG = {"shoulder_pan": 3.0, "shoulder_lift": 12.0, "elbow_flex": 8.0,
                  "wrist_flex": 4.0, "wrist_roll": 2.0, "gripper": 0.0}
"""The largest feed-forward offset per joint [deg]: 1.5x the sag at the worst pose of the
kit's 5 V supply at P = 16 (shoulder 8.2, elbow 4.4, wrist 1.1 deg at the all-zero pose),
so a wrong voltage or P can at most double the sag it was meant to remove. The gripper
squeezes: no offset."""


_FIXED = [np.array(pose(FIXED_ROTATION[name], FIXED_TRANSFORMS[name][0]))
          for name in ("w1", "12", "23", "34", "45")]
_JAW_POS, _JAW_ROTATION = np.array(JAW[2]), Rx(90.0)
_COMS = [np.append(com, 1.0) for _, com in LINKS.values()]
_MASSES = [mass for mass, _ in LINKS.values()]


def holding_torques_rad(angles: Sequence[float], gripper_rad: float,
                        payload_kg: float = 0.0) -> list[float]:
    """:func:`holding_torques` of the five arm joints at angles [rad] (fast: no checks).

    Each joint holds the links beyond it: with ``a`` their mass-weighted centre less
    the total mass at the joint's origin, gravity (0, 0, -g) turns the joint by
    ``axis . (a x (0, 0, -g)) = -g (a_y axis_x - a_x axis_y)``; the servo gives its opposite.
    """
    frames = []
    g = np.eye(4)
    for fixed, theta in zip(_FIXED, angles, strict=True):
        c, s = math.cos(theta), math.sin(theta)
        g = g @ fixed @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        frames.append(g)
    weighted = [mass * (frame @ com)[:3] for mass, frame, com in zip(_MASSES, frames, _COMS,
                                                                     strict=True)]
    c, s = math.cos(gripper_rad), math.sin(gripper_rad)
    jaw = _JAW_POS + _JAW_ROTATION @ (np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
                                      @ np.array(JAW[1]))
    weighted.append(JAW[0] * (frames[4][:3, :3] @ jaw + frames[4][:3, 3]))
    masses = _MASSES + [JAW[0]]
    if payload_kg:
        tool = frames[4] @ np.append(FIXED_TRANSFORMS["5t"][0], 1.0)
        weighted.append(payload_kg * tool[:3])
        masses = masses + [payload_kg]
    torques = []
    for index, frame in enumerate(frames):
        a = sum(weighted[index:]) - sum(masses[index:]) * frame[:3, 3]
        torques.append(float(GRAVITY * (a[1] * frame[0, 2] - a[0] * frame[1, 2])))
    return torques


def holding_torques(cfg: Mapping[str, float], payload_kg: float = 0.0) -> dict[str, float]:
    """The torque [N m] each servo must give to hold the arm still at ``cfg``.

    MuJoCo's ``qfrc_bias`` at zero velocity (gravity only): positive turns the joint
    positive. The gripper's own joint is left out (0: it squeezes, it does not hold).

    Args:
        cfg: configuration [deg], gripper [0, 100] (default 50 when missing).
        payload_kg: a mass held at the object frame [kg] (a cube).
    """
    angles = [math.radians(a) for a in read_angles(cfg)]
    lower, upper = JOINT_RANGES_RAD["gripper"]
    opening = float(cfg.get("gripper", 50.0)) / (GRIPPER_RANGE[1] - GRIPPER_RANGE[0])
    torques = holding_torques_rad(angles, lower + (upper - lower) * opening, payload_kg)
    return {**dict(zip(ARM_JOINTS, torques, strict=True)), "gripper": 0.0}


def feedforward(cfg: Mapping[str, float], settings: servo.Settings | Mapping[str, servo.Settings],
                volts: float, variant: str | None = None,
                payload_kg: float = 0.0) -> dict[str, float]:
    """Goal offsets [deg] that cancel the static sag at ``cfg``, each bounded.

    The offset is the error at which the servo holds gravity's torque there
    (``servo.holding_error``), clipped to :data:`MAX_OFFSET_DEG`; none where the
    joint's own friction holds the load (less than the variant's Coulomb friction).

    Args:
        cfg: the configuration to hold [deg], gripper [0, 100].
        settings: the servos' registers (P, dead zone, startup force, torque limit):
            one for all joints, or joint -> registers.
        volts: the supply the servos report [V].
        variant: a key of ``servo.VARIANTS`` (default: what ``volts`` implies).
        payload_kg: a mass held at the object frame [kg].

    Returns:
        joint -> offset [deg] to add to the goal (0 for the gripper).
    """
    return dict(zip(ARM_JOINTS + ("gripper",), feedforward_offsets(
        holding_torques(cfg, payload_kg).values(), settings, volts, variant), strict=True))


def feedforward_offsets(torques, settings: servo.Settings | Mapping[str, servo.Settings],
                        volts: float, variant: str | None = None) -> list[float]:
    """:func:`feedforward` from holding torques [N m] (joints in ``JOINTS`` order): [deg]."""
    variant = variant or servo.default_variant(volts)
    friction = servo.VARIANTS[variant].coulomb
    offsets = []
    for joint, torque in zip(ARM_JOINTS + ("gripper",), torques, strict=False):
        limit = MAX_OFFSET_DEG[joint]
        if abs(torque) <= friction or not limit:
            offsets.append(0.0)
            continue
        registers = settings[joint] if isinstance(settings, Mapping) else settings
        error = servo.holding_error(torque, registers, volts, variant)
        degrees = limit if error is None else math.degrees(abs(error))
        offsets.append(math.copysign(min(degrees, limit), torque))
    return offsets


class Feedforward:
    """The gravity feed-forward of one arm: its servos' registers and supply, and a cache.

    Each goal is offset by the error at which its servo holds gravity there, plus, in
    the direction the joint last moved, the error its Coulomb friction leaves: a joint
    stops on the approach side, short by friction over stiffness ([TEL]: "unloaded moves
    stop 5-6 counts short of the goal on the approach side"; 0.5 deg at P = 16 on 5 V).

    Args:
        settings: joint -> the servo's registers (``servo.Settings``), as read from it.
        volts: the supply the servos report [V].
        variant: a key of ``servo.VARIANTS`` (default: what ``volts`` implies).
        enabled: add the offsets (``False``: :meth:`apply` changes nothing, and
            :meth:`expected_errors` counts the sag in).

    Example::

        >>> ff = Feedforward(dict.fromkeys(ARM_JOINTS + ("gripper",), servo.LEROBOT), 5.0)
        >>> cfg = dict.fromkeys(ARM_JOINTS, 0.0) | {"gripper": 50.0}
        >>> round(ff.apply(cfg)["shoulder_lift"], 1)  # the goal sent, to rest at 0 [deg]
        -5.3
    """

    REFRESH_DEG = 1.0
    """Offsets are recomputed when a joint has moved this far since [deg] (they change by
    at most 0.15 deg per degree of motion)."""

    def __init__(self, settings: Mapping[str, servo.Settings], volts: float,
                 variant: str | None = None, enabled: bool = True):
        self.enabled = bool(enabled)
        self.settings = dict(settings)
        self.volts = float(volts)
        self.variant = variant or servo.default_variant(self.volts)
        self._at: dict[str, float] | None = None
        self._offsets: dict[str, float] = {}
        friction = servo.VARIANTS[self.variant].coulomb
        self.friction = {j: math.degrees(friction / servo.stiffness(self.settings[j], self.volts,
                                                                    self.variant))
                         for j in ARM_JOINTS}
        """Joint -> the error [deg] its friction leaves on the approach side."""
        self._last: dict[str, float] | None = None
        self.direction = dict.fromkeys(ARM_JOINTS, 0.0)
        """Joint -> the sign of its last move (0 before any)."""

    def offsets(self, cfg: Mapping[str, float]) -> dict[str, float]:
        """Each joint's gravity offset [deg] at ``cfg`` (cached while no joint moved much)."""
        at = self._at
        if at is None or any(abs(cfg[j] - at[j]) > self.REFRESH_DEG for j in ARM_JOINTS):
            self._offsets = feedforward(cfg, self.settings, self.volts, self.variant)
            self._at = {j: float(cfg[j]) for j in ARM_JOINTS}
        return self._offsets

    def apply(self, cfg: Mapping[str, float]) -> dict[str, float]:
        """The goal that makes the arm rest at ``cfg``: each joint's offsets added.

        Called with each successive command (it learns each joint's direction of motion).
        """
        if not self.enabled:
            return dict(cfg)
        last, direction = self._last, self.direction
        if last is not None:
            for joint in ARM_JOINTS:
                change = cfg[joint] - last[joint]
                if abs(change) > 1e-6:
                    direction[joint] = 1.0 if change > 0 else -1.0
        self._last = {j: float(cfg[j]) for j in ARM_JOINTS}
        offsets = self.offsets(cfg)
        return {j: value + offsets.get(j, 0.0) + self.friction.get(j, 0.0) * direction.get(j, 0.0)
                for j, value in cfg.items()}

    def expected_errors(self, cfg: Mapping[str, float],
                        speeds: Mapping[str, float]) -> dict[str, float]:
        """How far [deg] each arm joint will be from ``cfg`` moving at ``speeds`` [deg/s].

        The servo's lag at that speed (``servo.lag``), plus the sag and the friction
        band where no offset cancels them: what a tracking check must allow before it
        calls a joint blocked.
        """
        offsets = self.offsets(cfg)
        return {j: math.degrees(servo.lag(math.radians(speeds.get(j, 0.0)), self.settings[j],
                                          self.volts, self.variant))
                + (0.0 if self.enabled else abs(offsets[j]) + self.friction[j])
                for j in ARM_JOINTS}

    def describe(self, cfg: Mapping[str, float]) -> str:
        """One line: the supply, P and each arm joint's offset at ``cfg``."""
        if not self.enabled:
            return (f"no gravity feed-forward ({self.variant} at {self.volts:.1f} V: the arm "
                    "sags)")
        offsets = self.offsets(cfg)
        p = sorted({s.p for s in self.settings.values()})
        gains = "/".join(str(v) for v in p)
        joints = ", ".join(f"{j} {offsets[j]:+.1f}" for j in ARM_JOINTS if offsets[j])
        friction = max(self.friction.values())
        return (f"gravity feed-forward ({self.variant}, P = {gains}, {self.volts:.1f} V): "
                f"{joints or 'no offsets'} deg, and up to {friction:.1f} deg of friction in "
                "the direction of motion")
