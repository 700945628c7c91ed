"""Two SO-101s in one MuJoCo model: their bases placed by a parameter, each arm prefixed.

The model is built from the course's own files, never a copy: ``model/table.xml`` gives
the table, the light and the cameras, and ``model/scene.xml``'s arm with its servos is
attached twice through ``mujoco.MjSpec``, with the prefixes ``left_`` and ``right_`` (the
key names of lerobot's bimanual robots, ``bi_so_follower``): ``left_shoulder_pan``, ...,
``right_gripper`` name the joints, the actuators and the bodies. The physics options
(the 4 ms step, ``implicitfast``, elliptic friction cones with ``impratio`` 100) are the
arm's (``model/so101.xml``), copied onto the parent so that attaching keeps them.

A base pose is (x [m], y [m], yaw [deg]) in the world, whose origin is on the table top:

- ``facing``: the arms face each other across the origin, ``spacing`` apart (left at
  ``(-spacing / 2, 0, 0)``, right at ``(spacing / 2, 0, 180)``);
- ``side``: side by side, both facing +x, ``spacing`` apart in y (left at +y).

Each arm keeps its pieces and parks on its own side: in ``facing`` its base frame's +y (the
two sides are opposite in the world), in ``side`` its outer side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import PlanError
from so101_kinematics.paths import MODEL_DIR, SCENE_PATH
from so101_kinematics.sim import actuation
from so101_kinematics.sim.cube import add_cube
from so101_kinematics.sim.meshes import ensure_meshes

__all__ = [
    "ARM_NAMES", "BASE_RADIUS", "GAME_CAMERA", "LAYOUTS", "LAYOUT_SPACING", "ArmBase", "Piece",
    "arm_bases", "base_from_world", "build_two_arm_model", "check_bases", "world_from_base",
]

ARM_NAMES = ("left", "right")
"""The arms' names; each arm's joints, actuators and bodies carry ``<name>_`` before the
course's names (lerobot's bimanual ``left_`` / ``right_`` keys)."""
LAYOUTS = ("facing", "side")
LAYOUT_SPACING = {"facing": 0.46, "side": 0.30}
"""[m] The bases' distance by default, per layout: facing across the board, its squares 0.136
to 0.252 m from each pan axis; side by side, the board's far corner 0.26 m from each pan axis
and the arms' boxes 26 mm apart at the closest (``game_board.LAYOUT_BOARDS``)."""
GAME_CAMERA = "two_arms"
"""The camera that films the game: 0.62 m in front of the board's centre (world -y), 0.50 m
up, looking down at the table's origin at 37 deg."""
BASE_RADIUS = 0.072
"""[m] The base's footprint, a circle about the base frame's origin: the farthest vertex of
the base body's meshes (``model/so101.xml``'s ``base_so101_v2``) is 0.0718 m from it. Two
bases closer than twice this overlap."""
_OPTIONS = ("timestep", "integrator", "cone", "impratio", "disableflags", "enableflags")
"""The physics options the arm's file sets, copied onto the two-arm model."""


@dataclass(frozen=True)
class ArmBase:
    """Where one arm's base stands: its name ("left" or "right") and pose in the world.

    ``x``, ``y`` [m] in the world; ``yaw`` [deg] about the vertical (0: the arm reaches along
    the world's +x); ``side`` +1 when the arm's own pieces and its park pose are on its base
    frame's +y, -1 on its -y (away from the other arm).
    """

    name: str
    x: float
    y: float
    yaw: float
    side: float = 1.0

    @property
    def prefix(self) -> str:
        """The prefix of this arm's names in the model (``"left_"``)."""
        return f"{self.name}_"


@dataclass(frozen=True)
class Piece:
    """A game piece: the course's free cube (``sim/cube.py``), named and coloured.

    ``name`` is its body, joint and geom name ("x_1", "o_2"); ``x``, ``y`` [m] its centre in
    the world; ``rgba`` its colour.
    """

    name: str
    x: float
    y: float
    rgba: tuple[float, float, float, float]


def arm_bases(layout: str = "facing", spacing: float | None = None) -> tuple[ArmBase, ArmBase]:
    """The two bases of a layout (see the module's docstring).

    Args:
        layout: one of ``LAYOUTS``.
        spacing: the bases' distance [m] (default: the layout's ``LAYOUT_SPACING``).

    Raises:
        PlanError: an unknown layout.

    Example:
        >>> arm_bases("facing", 0.4)[1]
        ArmBase(name='right', x=0.2, y=0.0, yaw=180.0, side=1.0)
    """
    if layout not in LAYOUTS:
        raise PlanError(f"layout {layout!r} is not one of {', '.join(LAYOUTS)}. Fix: use "
                        "--layout facing (across the board) or --layout side.")
    half = 0.5 * float(LAYOUT_SPACING[layout] if spacing is None else spacing)
    if layout == "facing":
        return ArmBase("left", -half, 0.0, 0.0), ArmBase("right", half, 0.0, 180.0)
    return ArmBase("left", 0.0, half, 0.0), ArmBase("right", 0.0, -half, 0.0, side=-1.0)


def check_bases(bases: tuple[ArmBase, ArmBase]) -> None:
    """Refuse two bases whose footprints overlap.

    Raises:
        PlanError: one line with the distance, the minimum and the fix.
    """
    left, right = bases
    distance = math.hypot(left.x - right.x, left.y - right.y)
    if distance < 2 * BASE_RADIUS:
        raise PlanError(f"the arms' bases are {distance:.3f} m apart: they overlap (each base "
                        f"is {BASE_RADIUS:g} m in radius: at least {2 * BASE_RADIUS:g} m apart). "
                        f"Fix: a larger --spacing, e.g. {LAYOUT_SPACING['facing']:g}.")


def world_from_base(base: ArmBase, point) -> np.ndarray:
    """A point (x, y, z) [m] in ``base``'s frame -> the world."""
    c, s = math.cos(math.radians(base.yaw)), math.sin(math.radians(base.yaw))
    x, y, z = (float(v) for v in point)
    return np.array([base.x + c * x - s * y, base.y + s * x + c * y, z])


def base_from_world(base: ArmBase, point) -> np.ndarray:
    """A point (x, y, z) [m] in the world -> ``base``'s frame.

    Example:
        >>> base = ArmBase("right", 0.2, 0.0, 180.0)
        >>> [round(float(v), 6) + 0.0 for v in base_from_world(base, (0.0, 0.05, 0.013))]
        [0.2, -0.05, 0.013]
    """
    c, s = math.cos(math.radians(base.yaw)), math.sin(math.radians(base.yaw))
    dx, dy, z = float(point[0]) - base.x, float(point[1]) - base.y, float(point[2])
    return np.array([c * dx + s * dy, -s * dx + c * dy, z])


def _arm_spec() -> mujoco.MjSpec:
    """The course's scene with only the arm and its servos kept (to be attached)."""
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    spec.delete(spec.geom("table"))
    for item in [*spec.lights, *spec.keys]:
        spec.delete(item)
    for camera in list(spec.cameras):
        if camera.parent.name == "world":  # the table's cameras stay the parent's
            spec.delete(camera)
    return spec


def build_two_arm_model(bases: tuple[ArmBase, ArmBase], pieces: tuple[Piece, ...] = (),
                        servo: dict | None = None,
                        lines: tuple[tuple[float, float, float, float], ...] = ()
                        ) -> mujoco.MjModel:
    """Compile the table with two arms at ``bases`` and free ``pieces`` on it.

    Args:
        bases: the two arms' bases (:func:`arm_bases`).
        pieces: cubes resting on the table.
        servo: keywords of ``actuation.use_servo`` (default: the faithful STS3215, the
            project's default), applied to both arms.
        lines: lines drawn on the table, each (x, y, half length along x, half along y) [m]
            (visual only: no contact, no mass; the physics unchanged).

    Returns:
        The model: 12 joints and actuators named ``left_*`` and ``right_*``, then the
        pieces' free joints.
    """
    ensure_meshes()
    parent = mujoco.MjSpec.from_file(str(MODEL_DIR / "table.xml"))
    for base in bases:
        arm = _arm_spec()
        for option in _OPTIONS:
            setattr(parent.option, option, getattr(arm.option, option))
        half = math.radians(base.yaw) / 2
        frame = parent.worldbody.add_frame(pos=[base.x, base.y, 0.0],
                                           quat=[math.cos(half), 0.0, 0.0, math.sin(half)])
        frame.attach_body(arm.body("base"), base.prefix, "")
    for piece in pieces:
        add_cube(parent, [piece.x, piece.y, CUBE_HALF_SIZE], [1.0, 0.0, 0.0, 0.0], name=piece.name)
        parent.geom(piece.name).rgba = list(piece.rgba)
    for x, y, half_x, half_y in lines:
        parent.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=[x, y, 0.0002],
                                  size=[half_x, half_y, 0.0002], contype=0, conaffinity=0,
                                  density=0.0, group=1, rgba=[0.2, 0.2, 0.2, 1.0])
    parent.worldbody.add_camera(name=GAME_CAMERA, pos=[0.0, -0.62, 0.50], fovy=50.0,
                                xyaxes=[1.0, 0.0, 0.0, 0.0, 0.6, 0.8])
    m = parent.compile()
    actuation.use_servo(m, **(servo or {}))
    return m
