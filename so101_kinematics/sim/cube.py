"""The pick-and-place's world: the free cube, the scene built around it, and the cube watched.

One definition of the cube (size, mass, friction, contact) for every scene
that has one: :func:`build_model` adds it, with the target markers, to
``model/scene.xml``; :class:`CubeMonitor` follows it during a run (lifted,
held, dropped).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_SIZE
from so101_kinematics.errors import PlanError
from so101_kinematics.fast_fk import forward_kinematics as get_forward_kinematics
from so101_kinematics.frames import ARM_JOINTS, JOINT_LIMITS, TOOL_SITE
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.inputs import check_number
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.planning.cartesian_plan import CUBE_YAW_RANGE
from so101_kinematics.planning.motion import Plan
from so101_kinematics.planning.plans import default_plan, pick_and_place_steps
from so101_kinematics.sim import actuation
from so101_kinematics.sim.contact_pairs import use_explicit_contact_pairs
from so101_kinematics.sim.meshes import ensure_meshes
from so101_kinematics.sim.render import use_render_meshes
from so101_kinematics.sim.tag_textures import add_cube_tag, add_target_tag

__all__ = [
    "CUBE_OFFSET_RANGE_MM", "CubeMonitor", "CubeStart", "add_cube", "build_model",
    "check_cube_start",
    "cube_name", "cube_names", "cube_on_table", "cube_state", "scene_limits", "scene_model",
    "table_extent",
]

# The free cube: a 26 mm hardwood cube (17.6 cm^3 at ~0.7 g/cm^3 = 12 g).
# Sliding friction 0.5 is wood on wood or on PLA; where it touches a jaw pad,
# the pad's own contact parameters apply (model/so101.xml, class jaw_pad).
CUBE_MASS = 0.012  # [kg]
CUBE_FRICTION = (0.5, 0.005, 0.0001)  # sliding [-], torsional [m], rolling [m]
CUBE_RGBA = (0.25, 0.45, 0.85, 1.0)
HELD_DISTANCE = 0.015  # [m] cube centre this close to the object frame = in the grip
# A cube whose centre is this high above its start and not in the grip is
# falling (a cube tipping over on the table rises at most 5.4 mm).
AIRBORNE_HEIGHT = 0.010  # [m]
MONITOR_PERIOD = 0.01  # [s] of simulation time between checks of the cube
CUBE_OFFSET_RANGE_MM = (-100.0, 100.0)  # [mm] each of --cube-offset DX DY: a perturbation


@dataclass
class CubeStart:
    """Where the free cube starts: the pick position's FK, plus a perturbation.

    Attributes:
        offset: horizontal displacement (x, y) in the world frame [m].
        yaw: extra rotation about the vertical [deg].
    """

    offset: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0

    def pose(self, pick: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """Cube centre [m] and quaternion (w, x, y, z) for the pick configuration ``pick``.

        The cube stands on the table, turned about z as the FK object frame
        (so its faces are parallel to the jaws), then by ``yaw``.
        """
        position, rotation = get_forward_kinematics({j: pick[j] for j in ARM_JOINTS})
        centre = np.array([position[0] + self.offset[0], position[1] + self.offset[1],
                           0.5 * CUBE_SIZE])
        angle = math.atan2(rotation[1, 0], rotation[0, 0]) + math.radians(self.yaw)
        return centre, np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])


def build_model(plan: Plan | None = None, cube: CubeStart | None = None,
                render_meshes: bool = False, physics_only: bool = False,
                explicit_pairs: bool = True,
                cube_at: tuple[float, float, float] | None = None, *,
                cubes_at: Sequence[Sequence[float]] = (),
                base_height: float = 0.0, servo: dict | None = None, tagged: bool = False,
                target_at: Sequence[float] | None = None) -> mujoco.MjModel:
    """Compile the course scene, optionally with a free cube at the plan's pick position.

    Args:
        plan: gives the pick configuration (default: the built-in plan).
        cube: the cube's start; ``None`` for no cube.
        render_meshes: use the decimated render-only meshes (for a model that
            is only drawn; see ``so101_kinematics.sim.render.use_render_meshes``).
        physics_only: leave out the visual geoms and their meshes (for a run
            that is never drawn). They have no mass and no contact, so the
            physics is bit for bit the same; each step skips their poses.
        cube_at: instead of ``cube``: the cube resting on the table at (x [m], y [m],
            yaw [deg]) in the world (the virtual arm's ``--cube``).
        explicit_pairs: list the geom pairs that can touch instead of finding
            them every step (``so101_kinematics.sim.contact_pairs``; the same contacts, 6 %
            less work per step).
        cubes_at: instead of ``cube``: several cubes resting on the table, each
            (x [m], y [m][, yaw [deg]]); the first is body "cube", the others
            "cube_2", "cube_3", ... (the stacking run, the virtual arm's ``--cube``).
        base_height: the table top is this far below the base frame [m] (the
            lab's 15 mm mount); the arm stays where it is, the table moves.
        servo: keywords of ``actuation.use_servo`` (default: its defaults).
        tagged: print the cube tag on the first cube's top (``tag_textures.CUBE_TAG``;
            a visual-only geom, the physics unchanged; needs OpenCV to draw it).
        target_at: lay the target tag (``tag_textures.TARGET_TAG``) on the table at
            (x [m], y [m][, yaw [deg]]) in the base frame (visual only; needs OpenCV).

    Returns:
        The model. Sleeping is enabled: a cube at rest on the table costs no
        contact computation until the arm touches it.
    """
    ensure_meshes()
    spec = mujoco.MjSpec.from_file(str(SCENE_PATH))
    if physics_only:
        _remove_visuals(spec)
    elif render_meshes:
        use_render_meshes(spec)
    if base_height:
        spec.geom("table").pos[2] = -check_number(base_height, "base_height", 0.0, 0.05, "m")
    if cube is not None:
        pick, _ = pick_and_place_steps(plan or default_plan())
        centre, quat = cube.pose(pick.configuration)
        add_cube(spec, centre - [0.0, 0.0, base_height], quat)
    for index, place in enumerate([cube_at] if cube_at is not None else cubes_at):
        add_cube(spec, *cube_on_table(*place, base_height=base_height), name=cube_name(index))
    if tagged and spec.body(cube_name(0)) is not None:
        add_cube_tag(spec, cube_name(0))
    if target_at is not None:
        add_target_tag(spec, *target_at)
    if explicit_pairs:
        use_explicit_contact_pairs(spec)
    m = spec.compile()
    actuation.use_servo(m, **(servo or {}))
    return m


def cube_name(index: int) -> str:
    """The body, joint and geom name of the scene's cube ``index`` (0: "cube", 1: "cube_2")."""
    return "cube" if index == 0 else f"cube_{index + 1}"


def cube_names(m: mujoco.MjModel) -> list[str]:
    """The names of the model's free cubes, in order ("cube", "cube_2", ...)."""
    names = []
    while mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, cube_name(len(names))) >= 0:
        names.append(cube_name(len(names)))
    return names


def add_cube(spec: mujoco.MjSpec, centre, quat, name: str = "cube") -> None:
    """Add the course's free cube to a scene: the one definition every cube here uses.

    Args:
        spec: the scene being built.
        centre: the cube's centre [m] in the world.
        quat: its orientation (w, x, y, z).
        name: its body, joint and geom name (:func:`cube_name`).
    """
    body = spec.worldbody.add_body(name=name, pos=list(centre), quat=list(quat))
    body.add_freejoint(name=name)
    body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5 * CUBE_SIZE] * 3,
                  mass=CUBE_MASS, friction=list(CUBE_FRICTION), condim=3, rgba=list(CUBE_RGBA))
    spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP  # a cube at rest costs nothing


def cube_on_table(x: float, y: float, yaw_deg: float = 0.0,
                  base_height: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Centre [m] and quaternion (w, x, y, z) of a cube resting on the table at (x, y), turned.

    The table is ``base_height`` [m] below the base frame: the centre is at
    ``-base_height + CUBE_SIZE / 2``.
    """
    half = math.radians(yaw_deg) / 2
    return (np.array([x, y, 0.5 * CUBE_SIZE - base_height]),
            np.array([math.cos(half), 0.0, 0.0, math.sin(half)]))


def cube_state(m: mujoco.MjModel, d: mujoco.MjData,
               name: str = "cube") -> tuple[np.ndarray, float, bool]:
    """Where a cube is: centre [m], tilt of its up axis from the vertical [deg], held or not.

    Held: its centre within ``HELD_DISTANCE`` of the object frame and off the table.
    """
    centre = d.body(name).xpos.copy()
    up = d.body(name).xmat.reshape(3, 3)[:, 2]
    tilt = math.degrees(math.acos(min(1.0, max(-1.0, float(up[2])))))
    held = (math.dist(centre, d.site(TOOL_SITE).xpos) <= HELD_DISTANCE
            and centre[2] > m.geom("table").pos[2] + 0.5 * CUBE_SIZE + 0.002)
    return centre, tilt, held


def _remove_visuals(spec: mujoco.MjSpec) -> None:
    """Delete the arm's visual geoms (class "visual": no contact, no mass) and the meshes."""
    for geom in list(spec.geoms):
        massless = geom.density == 0 and not geom.mass > 0  # mass is NaN when not given
        if (geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.contype == 0
                and geom.conaffinity == 0 and massless):
            spec.delete(geom)
    for mesh in list(spec.meshes):
        spec.delete(mesh)


@functools.lru_cache(maxsize=1)
def scene_model() -> mujoco.MjModel:
    """The scene without cube and visual meshes (for its limits, table and timestep)."""
    return build_model(physics_only=True)


def scene_limits() -> dict[str, tuple[float, float]]:
    """Joint limits of the scene's arm in user units ([deg], gripper [0, 100]): the model's."""
    return dict(JOINT_LIMITS)


def table_extent() -> tuple[tuple[float, float], tuple[float, float]]:
    """The table top's x and y ranges [m] in the world (the scene's geom "table")."""
    m = scene_model()
    centre, half = m.geom("table").pos, m.geom("table").size
    return ((float(centre[0] - half[0]), float(centre[0] + half[0])),
            (float(centre[1] - half[1]), float(centre[1] + half[1])))


def check_cube_start(plan: Plan, cube: CubeStart) -> np.ndarray:
    """Refuse a cube start that is off the table or out of the arm's reach, before the run.

    Args:
        plan: the plan (its pick step gives the nominal position).
        cube: the perturbation.

    Returns:
        The cube's start centre [m].

    Raises:
        so101_kinematics.planning.motion.PlanError: naming the position, the table or the
            reach, and the fix.
    """
    for axis, value in zip("xy", cube.offset, strict=True):
        check_number(value, f"cube offset {axis}", CUBE_OFFSET_RANGE_MM[0] / 1000.0,
                      CUBE_OFFSET_RANGE_MM[1] / 1000.0, "m")
    check_number(cube.yaw, "cube turn", *CUBE_YAW_RANGE, "deg")
    pick, _ = pick_and_place_steps(plan)
    centre, _ = cube.pose(pick.configuration)
    (x_low, x_high), (y_low, y_high) = table_extent()
    half = 0.5 * CUBE_SIZE
    where = (f"The cube would start at ({centre[0]:.3f}, {centre[1]:.3f}) m (waypoint "
             f"'{pick.name}' plus the offset ({cube.offset[0] * 1e3:g}, "
             f"{cube.offset[1] * 1e3:g}) mm)")
    if not (x_low + half <= centre[0] <= x_high - half and y_low + half <= centre[1] <= y_high
            - half):
        raise PlanError(f"{where}: off the table, which spans x in [{x_low:g}, {x_high:g}] m "
                        f"and y in [{y_low:g}, {y_high:g}] m. Fix: a smaller --cube-offset, or "
                        "a pick position on the table.")
    try:
        get_inverse_kinematics(centre, approach=None)
    except PlanError as error:
        reason = str(error).split(" Fix:")[0]
        raise PlanError(f"{where}: out of the arm's reach ({reason}). Fix: a smaller "
                        "--cube-offset, or a pick position the arm reaches.") from None
    return centre


class CubeMonitor:
    """Watches the cube during the run; a viewer wrapper for move_to_pose.

    It forwards ``sync()`` / ``is_running()`` to an inner viewer (passive
    viewer or video recorder) if there is one and takes its pacing flags.

    Args:
        m: the model (with a body "cube", or without: then it only forwards).
        d: the data.
        inner: the viewer to forward to, or ``None`` (headless).
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, inner=None):
        self.d, self.inner = d, inner
        self.offscreen = inner is None or getattr(inner, "offscreen", False)
        self.sync_every_step = inner is not None and getattr(inner, "sync_every_step", False)
        cube = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "cube")
        self.has_cube = cube >= 0
        self._next = d.time
        if self.has_cube:
            # Views into d (rows of its arrays): they follow the simulation.
            self._cube = d.xpos[cube]
            self._site = d.site_xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, TOOL_SITE)]
            self.start_height = float(self._cube[2])
        self.max_lift = 0.0  # [m]
        self.dropped = False

    def is_running(self) -> bool:
        """The inner viewer's state (always true headless)."""
        return self.inner is None or self.inner.is_running()

    def sync(self) -> None:
        """Check the cube (every MONITOR_PERIOD [s]), then forward."""
        if self.has_cube and self.d.time >= self._next - 1e-9:
            self._next = self.d.time + MONITOR_PERIOD
            self.check()
        if self.inner is not None:
            self.inner.sync()

    def check(self) -> None:
        """Update the lift height and note a drop: the cube in the air, out of the grip."""
        lift = float(self._cube[2]) - self.start_height
        self.max_lift = max(self.max_lift, lift)
        if lift > AIRBORNE_HEIGHT and math.dist(self._cube, self._site) > HELD_DISTANCE:
            self.dropped = True


