"""The throwing scene: the course's arm, a ball held in the gripper, a cup on the table.

The scene is the course's (``model/scene.xml``) with:

- the ball: a free body (``ball.BALLS``) at the object frame, held there by a weld to the
  gripper body until the release. The jaws' grip on the ball is not simulated: the ball
  touches only the table and the cup (its contact bits match theirs alone), and it is let go
  when the moving jaw has opened ``RELEASE_OPENING_DEG`` beyond where it held the ball, the
  moment a real ball would slip out (:class:`Flight`). The air's drag is applied to it as a
  force at every physics step, the forward model's own (``ball.Ball.drag_force``);
- the cup: a bottom and ``CUP_WALLS`` wall boxes in a ring (MuJoCo has no hollow
  cylinder), ``CUP_INNER_DIAMETER`` wide inside and ``CUP_HEIGHT`` tall: a small plastic
  cup, about as wide as a beer-pong cup's mouth (95 mm) but half its height;
- the table's plane drawn 0.8 m around (its contact is infinite anyway).

Contacts keep MuJoCo's defaults (critically damped, 0.02 s): a ball that touches stays
nearly where it touched; a real ping-pong ball bounces (restitution about 0.9 on a table),
so "in the cup" here is where the ball first comes down, not where a bounce takes it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np

from so101_kinematics.frames import MOVING_JAW_BODY, TOOL_SITE
from so101_kinematics.model_facts import site_position
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sim import actuation
from so101_kinematics.sim.meshes import ensure_meshes
from so101_kinematics.throwing.ball import Ball

__all__ = [
    "BALL_CONTACT", "CUP_BOTTOM_THICKNESS", "CUP_HEIGHT", "CUP_INNER_DIAMETER", "CUP_WALLS",
    "CUP_WALL_THICKNESS",
    "Flight", "RELEASE_OPENING_DEG", "SIDE_CAMERA", "build_throw_model", "hold_ball", "in_cup",
    "place_cup", "throw_spec",
]

CUP_INNER_DIAMETER = 0.090
"""The cup's inside [m] at its mouth (a beer-pong cup's mouth is 95 mm)."""
CUP_HEIGHT = 0.060
"""The cup's height [m], bottom to rim."""
CUP_WALL_THICKNESS = 0.003
"""[m]"""
CUP_BOTTOM_THICKNESS = 0.008
"""[m]: thick enough that a ball falling 12 mm in a 4 ms step touches it before the table."""
CUP_WALLS = 16
"""Boxes in the cup's ring."""
BALL_CONTACT = 8
"""The contact bit the ball, the table and the cup share (the arm's are 1 and 2)."""
RELEASE_OPENING_DEG = 10.0
"""How far the moving jaw opens from its hold before the ball is free [deg]: at the
object frame's distance from the jaw's axis (about 0.09 m) 10 deg is 16 mm of gap, enough
for a ball held in the jaws' tips to leave."""
CUP_RGBA = (0.85, 0.15, 0.15, 1.0)
BALL_RGBA = (1.0, 0.55, 0.1, 1.0)
SIDE_CAMERA = "throw_side"
"""The throwing scene's camera: from the side (-y), the arm and the cups' whole range in view."""
TABLE_DRAWN = 0.8  # [m]: the plane's half size as drawn


def _add_cup(spec: mujoco.MjSpec) -> None:
    """The cup at the origin of a mocap body (``place_cup`` moves it)."""
    cup = spec.worldbody.add_body(name="cup", mocap=True, pos=[0.5, 0.0, 0.0])
    inner = CUP_INNER_DIAMETER / 2.0
    half_t = CUP_WALL_THICKNESS / 2.0
    common = dict(contype=BALL_CONTACT, conaffinity=BALL_CONTACT, condim=3, rgba=list(CUP_RGBA))
    bottom = CUP_BOTTOM_THICKNESS / 2.0
    cup.add_geom(name="cup_bottom", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                 size=[inner + CUP_WALL_THICKNESS, bottom, 0.0], pos=[0.0, 0.0, bottom], **common)
    # each wall box's width covers its share of the ring with a little overlap
    width = 2.0 * math.pi * (inner + half_t) / CUP_WALLS * 1.1
    for i in range(CUP_WALLS):
        angle = 2.0 * math.pi * i / CUP_WALLS
        centre = [(inner + half_t) * math.cos(angle), (inner + half_t) * math.sin(angle),
                  CUP_HEIGHT / 2.0]
        cup.add_geom(name=f"cup_wall_{i}", type=mujoco.mjtGeom.mjGEOM_BOX,
                     size=[half_t, width / 2.0, CUP_HEIGHT / 2.0], pos=centre,
                     quat=[math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)], **common)


def build_throw_model(ball: Ball, servo: Mapping | None = None,
                      spec: mujoco.MjSpec | None = None) -> mujoco.MjModel:
    """The course's scene with the ``ball`` welded in the gripper and the cup; the servo as asked.

    Args:
        ball: the ball (``ball.BALLS``).
        servo: ``actuation.use_servo``'s keywords (default: the faithful STS3215 at 12 V).
        spec: :func:`throw_spec`'s scene for this ball, which a caller added to (a camera, a
            tag: ``cup_camera.py``); default a new one.
    """
    m = (spec or throw_spec(ball)).compile()
    actuation.use_servo(m, **dict(servo or {}))
    return m


def throw_spec(ball: Ball) -> mujoco.MjSpec:
    """:func:`build_throw_model`'s scene, not yet compiled (for a caller to add to)."""
    ensure_meshes()
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    table = spec.geom("table")
    table.conaffinity = table.conaffinity | BALL_CONTACT
    table.contype = table.contype | BALL_CONTACT
    table.size = [TABLE_DRAWN, TABLE_DRAWN, table.size[2]]
    held = spec.worldbody.add_body(name="ball", pos=[0.0, 0.0, 0.5])
    held.add_freejoint(name="ball")
    held.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[ball.radius, 0.0, 0.0],
                  mass=ball.mass, contype=BALL_CONTACT, conaffinity=BALL_CONTACT, condim=3,
                  friction=[0.4, 0.005, 0.0001], rgba=list(BALL_RGBA))
    # the hollow ball's inertia: (2/3) m r^2 (the solid sphere MuJoCo would give is 2/5)
    held.inertia = [2.0 / 3.0 * ball.mass * ball.radius ** 2] * 3
    held.explicitinertial = True
    held.ipos = [0.0, 0.0, 0.0]
    held.mass = ball.mass
    # the weld's data: its anchor (the object frame in the gripper's frame: where the ball's
    # centre is held), the relative pose (none: the ball turned as the gripper), the torque's
    # scale; tests/throwing/test_throw_scene.py checks that the ball sits at the object frame
    spec.add_equality(type=mujoco.mjtEq.mjEQ_WELD, name="grip", name1="ball", name2="gripper",
                      objtype=mujoco.mjtObj.mjOBJ_BODY,
                      data=[*site_position(TOOL_SITE), 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0,
                            0.0])
    _add_cup(spec)
    spec.worldbody.add_camera(name=SIDE_CAMERA, pos=[0.25, -1.05, 0.33], fovy=45.0,
                              mode=mujoco.mjtCamLight.mjCAMLIGHT_FIXED,
                              quat=_looking_along_y(math.radians(8.0)))
    return spec


def _looking_along_y(down: float) -> list[float]:
    """A camera's quaternion: looking along +y, tilted ``down`` [rad] (x right, y up)."""
    # the camera looks along its -z: rotate the world's frame 90 deg about x, then tilt down
    angle = math.pi / 2.0 - down
    return [math.cos(angle / 2.0), math.sin(angle / 2.0), 0.0, 0.0]


def place_cup(m: mujoco.MjModel, d: mujoco.MjData, x: float, y: float) -> None:
    """Stand the cup on the table with its axis at (x, y) [m]."""
    d.mocap_pos[m.body("cup").mocapid[0]] = [x, y, 0.0]


def hold_ball(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """Put the ball where the weld holds it, the arm's pose in ``d`` as it is; ``mj_forward``.

    Its centre at the object frame, turned as the gripper.
    """
    mujoco.mj_forward(m, d)
    adr = m.joint("ball").qposadr[0]
    d.qpos[adr:adr + 3] = d.site(TOOL_SITE).xpos
    d.qpos[adr + 3:adr + 7] = d.body("gripper").xquat
    mujoco.mj_forward(m, d)


def in_cup(position, cup_xy, ball: Ball) -> bool:
    """Whether a ball whose centre is at ``position`` [m] lies inside the cup at ``cup_xy``."""
    p = np.asarray(position, dtype=float)
    radial = float(np.hypot(p[0] - cup_xy[0], p[1] - cup_xy[1]))
    return bool(radial < CUP_INNER_DIAMETER / 2.0 and p[2] < CUP_HEIGHT)


class Flight:
    """Steps a throw: keeps the ball on the weld until the jaw has opened, then drags it.

    Attributes:
        release: (time [s], position (3,) [m], velocity (3,) [m/s]) of the ball when it was
            let go, or None.
        touch: (time [s], position (3,) [m], geom name) of the ball's first contact after
            the release, or None.
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, ball: Ball, hold_angle: float):
        self.m, self.d, self.ball = m, d, ball
        self.body = m.body("ball").id
        self.geom = m.geom("ball").id
        self.weld = m.equality("grip").id
        self.jaw = m.joint("gripper").qposadr[0]
        self.free_at = hold_angle + math.radians(RELEASE_OPENING_DEG)
        self.release: tuple | None = None
        self.touch: tuple | None = None
        self._jaw_body = m.body(MOVING_JAW_BODY).id
        self._free = m.joint("ball").qposadr[0]
        self._free_dof = m.joint("ball").dofadr[0]

    def ball_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The ball's centre [m] and velocity [m/s] in the world."""
        adr, dof = self._free, self._free_dof
        return self.d.qpos[adr:adr + 3].copy(), self.d.qvel[dof:dof + 3].copy()

    def step(self) -> None:
        """One physics step: the release check, the drag, the first touch."""
        m, d = self.m, self.d
        if self.release is None and d.qpos[self.jaw] >= self.free_at:
            d.eq_active[self.weld] = 0
            self.release = (float(d.time), *self.ball_state())
        if self.release is not None:
            d.xfrc_applied[self.body, :3] = self.ball.drag_force(self.ball_state()[1])
        actuation.step(m, d, 1)
        if self.release is not None and self.touch is None:
            touched = []
            for i in range(d.ncon):
                pair = (int(d.contact[i].geom1), int(d.contact[i].geom2))
                if self.geom in pair:
                    touched.append(m.geom(pair[1] if pair[0] == self.geom else pair[0]).name)
            if touched:
                # a ball in the cup may reach through its bottom to the table within a step:
                # the cup, which it met first, is named
                cup = [name for name in touched if name.startswith("cup")]
                self.touch = (float(d.time), self.ball_state()[0], (cup or touched)[0])
