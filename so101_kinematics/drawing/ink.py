"""A pen in the simulator that leaves ink: the holder and its pen, the page, the ink recorded.

The scene is the course's (``model/scene.xml``) with three things added:

- the holder: the course's cube (``constants.CUBE_SIZE``) at the object frame, welded to
  the gripper body (the jaws' grip on a cube is the pick-and-place's, checked there; a
  holder that slips in the jaws is not modelled);
- the pen: a body on a slide joint along the approach axis in the holder's bore, pushed
  down against its stop by a preloaded spring (``pen.PEN_SPRING``); its tip is a small
  sphere ``pen.PEN_TIP_BELOW_CENTRE`` below the holder's centre at the stop;
- the page: a box whose top is the paper's (``page.PAGE_THICKNESS`` above the table), which
  only the tip touches.

:class:`InkRecorder` steps the simulation and, after every physics step, records where the
tip touches the page and with what normal force (``mujoco.mj_contactForce``); ink is a
touch with at least ``INK_FORCE_N``.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.drawing.page import PAGE_THICKNESS, Page
from so101_kinematics.drawing.pen import (
    HOLDER_MASS,
    PEN_MASS,
    PEN_PRELOAD_M,
    PEN_SPRING,
    PEN_TIP_BELOW_CENTRE,
)
from so101_kinematics.frames import TOOL_SITE
from so101_kinematics.model_facts import site_position
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sim import actuation
from so101_kinematics.sim.meshes import ensure_meshes
from so101_kinematics.sim.scene import send_position_command

__all__ = [
    "INK_FORCE_N", "InkRecorder", "PEN_FRICTION", "PEN_TIP_RADIUS", "build_drawing_model",
]

PEN_TRAVEL_M = 0.010  # [m]: how far the pen can slide up into the holder
PEN_DAMPING = 1.0  # [N s/m]: the pen in its bore
PEN_TIP_RADIUS = 0.0005
"""The tip's radius [m]: a fine felt tip, a 1 mm line."""
PEN_FRICTION = 0.2
"""Sliding friction of the tip on paper [-] (felt on paper; a ballpoint's rolls less)."""
INK_FORCE_N = 0.02
"""The least normal force [N] that leaves ink (a felt tip marks at a touch)."""
PEN_BARREL = (0.005, 0.06)  # [m]: radius and half length of the pen's barrel (drawn only)
PAGE_RGBA = (1.0, 1.0, 1.0, 1.0)
PAGE_DEPTH = 0.01  # [m]: the page's box, from its top down into the table (only the top counts)


def build_drawing_model(page: Page, servo: Mapping | None = None) -> mujoco.MjModel:
    """The course's scene with the holder, the pen and the page; the servo as asked.

    Args:
        page: where the page lies.
        servo: keywords of ``actuation.use_servo`` (default: the faithful STS3215).
    """
    ensure_meshes()
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    gripper = spec.body("gripper")
    centre = list(site_position(TOOL_SITE))
    holder = gripper.add_body(name="pen_holder", pos=centre)
    holder.add_geom(name="pen_holder", type=mujoco.mjtGeom.mjGEOM_BOX, size=[CUBE_HALF_SIZE] * 3,
                    mass=HOLDER_MASS, contype=0, conaffinity=0, rgba=[0.9, 0.4, 0.1, 1.0])
    pen = holder.add_body(name="pen", pos=[0.0, 0.0, 0.0])
    pen.add_joint(name="pen_slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0.0, 0.0, 1.0],
                  range=[0.0, PEN_TRAVEL_M], limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                  stiffness=PEN_SPRING, springref=-PEN_PRELOAD_M, damping=PEN_DAMPING)
    barrel_centre = -PEN_TIP_BELOW_CENTRE + PEN_TIP_RADIUS + PEN_BARREL[1] + 0.002
    pen.add_geom(name="pen_barrel", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                 size=[PEN_BARREL[0], PEN_BARREL[1], 0.0], pos=[0.0, 0.0, barrel_centre],
                 mass=PEN_MASS, contype=0, conaffinity=0, rgba=[0.1, 0.2, 0.7, 1.0])
    pen.add_geom(name="pen_tip", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                 size=[PEN_TIP_RADIUS, 0.0, 0.0],
                 pos=[0.0, 0.0, -PEN_TIP_BELOW_CENTRE + PEN_TIP_RADIUS], mass=0.0005,
                 contype=4, conaffinity=4, condim=3, friction=[PEN_FRICTION, 0.005, 0.0001],
                 solref=[0.008, 1.0], rgba=[0.05, 0.05, 0.3, 1.0])
    # the page's box reaches PAGE_DEPTH into the table (which it does not touch): a thin box
    # lets a pressed tip pass through it within a step and press it from below
    # the box's x is the page's up (``page.Page.axes``), its y the page's left
    half = [page.size[1] / 2000.0, page.size[0] / 2000.0, PAGE_DEPTH / 2]
    yaw = np.radians(page.yaw)
    spec.worldbody.add_geom(name="page", type=mujoco.mjtGeom.mjGEOM_BOX, size=half,
                            pos=[*page.centre, PAGE_THICKNESS - PAGE_DEPTH / 2],
                            quat=[np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)],
                            contype=4, conaffinity=4, condim=3, rgba=list(PAGE_RGBA),
                            friction=[PEN_FRICTION, 0.005, 0.0001])  # MuJoCo takes the larger
    m = spec.compile()
    actuation.use_servo(m, **dict(servo or {}))
    return m


class InkRecorder:
    """Steps the simulation one control period at a time and records the tip's touches.

    Attributes:
        touches: rows (time [s], x [m], y [m], normal force [N]) of every physics step
            whose tip touched the page.
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData):
        self.m, self.d = m, d
        self.tip = m.geom("pen_tip").id
        self.page = m.geom("page").id
        self.touches: list[tuple[float, float, float, float]] = []
        self._force = np.zeros(6)

    def _record(self) -> None:
        d = self.d
        for i in range(d.ncon):
            contact = d.contact[i]
            if {int(contact.geom1), int(contact.geom2)} == {self.tip, self.page}:
                mujoco.mj_contactForce(self.m, d, i, self._force)
                self.touches.append((float(d.time), float(contact.pos[0]),
                                     float(contact.pos[1]), float(self._force[0])))

    def run(self, commands, steps_per_command: int) -> None:
        """Send each configuration [deg] for ``steps_per_command`` physics steps, recording."""
        for cfg in commands:
            send_position_command(self.d, cfg)
            for _ in range(steps_per_command):
                actuation.step(self.m, self.d, 1)
                self._record()

    def ink(self) -> np.ndarray:
        """(n, 4) rows of the touches that left ink (force at least ``INK_FORCE_N``)."""
        rows = np.array(self.touches, dtype=float).reshape(-1, 4)
        return rows[rows[:, 3] >= INK_FORCE_N]
