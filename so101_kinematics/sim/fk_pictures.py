"""The FK check's pictures: the cylinder in the gripper, the frames picture, the FK table.

What ``test_fk_mujoco.py`` draws: the course's red cylinder along the FK
object frame (:func:`show_cylinder`, :func:`render_screenshot`), every FK
frame's axes over a translucent arm (:func:`render_frames`,
``docs/fk_frames.png``) and the table of the model's numbers behind each
factor (:func:`fk_table_markdown`, ``docs/fk_table.md``).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.frames import (
    ARM_JOINTS,
    FIXED_TRANSFORMS,
    FRAMES,
    GRIPPER_MOUNT_TILT_DEG,
    Rx,
    Ry,
    Rz,
    get_frame_chain,
)
from so101_kinematics.markers import png_metadata
from so101_kinematics.outputs import atomic_output, write_png_atomic
from so101_kinematics.paths import DOCS_DIR, REPO
from so101_kinematics.sim.scene import (
    load_model,
    set_initial_pose,
)

__all__ = [
    "DEFAULT_SCREENSHOT", "FRAMES_PATH", "SCREENSHOT_CAMERA", "SCREENSHOT_SIZE", "TABLE_PATH",
    "fk_table_markdown", "project_to_pixels", "render_frames", "render_screenshot",
    "show_cylinder",
]

log = logging.getLogger("test_fk_mujoco")

# The course's show_cylinder: along the object frame's z axis, centred on it.
CYLINDER_RADIUS = 0.0245  # [m]
CYLINDER_HALF_HEIGHT = 0.05  # [m]
CYLINDER_RGBA = (1.0, 0.0, 0.0, 1.0)

SCREENSHOT_CAMERA = "gripper_closeup"  # in model/scene.xml
SCREENSHOT_SIZE = (640, 480)  # [px] width, height
DEFAULT_SCREENSHOT = REPO / "out" / "fk_test.png"

# The frames picture: a pose that spreads the frames out, seen from the side.
FRAMES_PATH = DOCS_DIR / "fk_frames.png"
FRAMES_CONFIGURATION = {
    "shoulder_pan": 0.0,
    "shoulder_lift": -30.0,
    "elbow_flex": 45.0,
    "wrist_flex": 30.0,
    "wrist_roll": 0.0,
    "gripper": 30.0,
}
FRAMES_SIZE = (1200, 900)  # [px]
FRAMES_CAMERA = {"lookat": (0.12, 0.0, 0.14), "distance": 0.55, "azimuth": -115.0,
                 "elevation": -15.0}  # free camera: [m], [m], [deg], [deg]
AXIS_LENGTH = 0.05  # [m]
AXIS_RADIUS = 0.0022  # [m]
ARM_ALPHA = 0.3  # opacity of the arm in the frames picture, so that frames inside it show
AXIS_RGBA = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.7, 0.1, 1.0), (0.1, 0.3, 0.95, 1.0))  # x, y, z

TABLE_PATH = DOCS_DIR / "fk_table.md"

log = logging.getLogger(Path(__file__).stem)


def add_geom(scene: mujoco.MjvScene, geom_type: int, size, position, rotation, rgba,
             label: str = "") -> None:
    """Append a decoration geom to a scene (a viewer's ``user_scn`` or a renderer's scene).

    Args:
        scene: the scene to draw into.
        geom_type: an ``mujoco.mjtGeom`` value.
        size: (3,) geom size [m].
        position: (3,) centre in the world [m].
        rotation: (3, 3) orientation in the world.
        rgba: colour, each channel in [0, 1].
        label: text MuJoCo draws next to the geom (empty for none).
    """
    if scene.ngeom >= scene.maxgeom:
        raise RuntimeError(f"The scene is full ({scene.maxgeom} geoms); cannot add more.")
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, geom_type, np.asarray(size, float), np.asarray(position, float),
                        np.asarray(rotation, float).flatten(), np.asarray(rgba, np.float32))
    geom.label = label
    scene.ngeom += 1


def show_cylinder(scene: mujoco.MjvScene, position, rotation) -> None:
    """Add the course's red cylinder along the z axis of the pose (position [m], rotation)."""
    add_geom(scene, mujoco.mjtGeom.mjGEOM_CYLINDER,
             (CYLINDER_RADIUS, CYLINDER_HALF_HEIGHT, 0.0), position, rotation, CYLINDER_RGBA)


def render_screenshot(m: mujoco.MjModel, d: mujoco.MjData, position, rotation, path: Path,
                      camera: str = SCREENSHOT_CAMERA, size=SCREENSHOT_SIZE) -> np.ndarray:
    """Render the scene with the cylinder from a model camera and save it as a PNG.

    Args:
        m: the model.
        d: the data, kinematics up to date.
        position: (3,) cylinder centre [m].
        rotation: (3, 3) cylinder orientation (its axis is the third column).
        path: output PNG.
        camera: name of a camera of the model.
        size: (width, height) [px].

    Returns:
        The (height, width, 3) image.
    """
    width, height = size
    with mujoco.Renderer(m, height, width) as renderer:
        renderer.update_scene(d, camera=camera)
        show_cylinder(renderer.scene, position, rotation)
        pixels = renderer.render()
    write_png_atomic(path, pixels, "test_fk_mujoco.py --screenshot")
    return pixels


def project_to_pixels(gl_camera, fovy_deg: float, size, points) -> np.ndarray:
    """Pixel coordinates of world points seen by a rendered camera (pinhole model).

    Args:
        gl_camera: ``scene.camera[0]`` after ``update_scene`` (position and axes).
        fovy_deg: vertical field of view [deg].
        size: (width, height) [px].
        points: (N, 3) world points [m].

    Returns:
        (N, 2) pixel coordinates (column, row), origin at the top-left corner.
    """
    width, height = size
    forward, up = np.asarray(gl_camera.forward), np.asarray(gl_camera.up)
    right = np.cross(forward, up)
    offset = np.atleast_2d(points) - np.asarray(gl_camera.pos)
    focal = 0.5 * height / math.tan(math.radians(fovy_deg) / 2.0)  # [px]
    depth = offset @ forward
    column = 0.5 * width + focal * (offset @ right) / depth
    row = 0.5 * height - focal * (offset @ up) / depth
    return np.column_stack([column, row])


def _axis_rotation(direction) -> np.ndarray:
    """A rotation whose z axis is ``direction`` (for arrow geoms)."""
    z = np.asarray(direction, float) / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def render_frames(path: Path, configuration=FRAMES_CONFIGURATION, size=FRAMES_SIZE) -> Path:
    """Render the arm with every FK frame's axes drawn and labelled, and save it.

    The axes come from :func:`get_frame_chain` (x red, y green, z blue); the
    arm is drawn translucent (``ARM_ALPHA``) so that the frames inside it show.

    Args:
        path: output PNG.
        configuration: the arm pose ([deg], gripper [0, 100]).
        size: (width, height) [px].

    Returns:
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = load_model()
    for name in ("printed", "servo"):
        m.material(name).rgba[3] = ARM_ALPHA
    m.light_castshadow[:] = 0  # shadows of the axes would read as extra arrows
    d = mujoco.MjData(m)
    set_initial_pose(d, configuration)
    chain = get_frame_chain(configuration)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = FRAMES_CAMERA["lookat"]
    camera.distance = FRAMES_CAMERA["distance"]
    camera.azimuth = FRAMES_CAMERA["azimuth"]
    camera.elevation = FRAMES_CAMERA["elevation"]
    width, height = size
    with mujoco.Renderer(m, height, width) as renderer:
        renderer.update_scene(d, camera=camera)
        for frame in FRAMES:
            g = chain[frame]
            for axis, rgba in enumerate(AXIS_RGBA):
                add_geom(renderer.scene, mujoco.mjtGeom.mjGEOM_ARROW,
                         (AXIS_RADIUS, AXIS_RADIUS, AXIS_LENGTH), g[:3, 3],
                         _axis_rotation(g[:3, axis]), rgba)
                renderer.scene.geoms[renderer.scene.ngeom - 1].emission = 0.6
        pixels = renderer.render()
        origins = np.array([chain[frame][:3, 3] for frame in FRAMES])
        where = project_to_pixels(renderer.scene.camera[0], m.vis.global_.fovy, size, origins)

    dpi = 100
    fig = plt.figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(pixels)
    ax.set_axis_off()
    for frame, (column, row) in zip(FRAMES, where, strict=True):
        ax.annotate(frame, (column, row), xytext=(-22, 16), textcoords="offset points",
                    fontsize=18, fontweight="bold", ha="center", va="center",
                    bbox={"boxstyle": "round,pad=0.25", "fc": "white", "ec": "0.3", "alpha": 0.9},
                    arrowprops={"arrowstyle": "-", "color": "0.3", "lw": 1.0})
    angles = ", ".join(f"{configuration[j]:g}" for j in ARM_JOINTS)
    ax.text(0.015, 0.975, f"SO-101 FK frames at ({angles}) deg\n"
            "x red, y green, z blue; each joint turns about its frame's z",
            transform=ax.transAxes, fontsize=14, va="top",
            bbox={"boxstyle": "round", "fc": "white", "alpha": 0.85})
    try:
        with atomic_output(path) as temporary:
            fig.savefig(temporary, dpi=dpi, format="png",
                        metadata=png_metadata("test_fk_mujoco.py --frames"))
    finally:
        plt.close(fig)
    return path


def _format_vector(values) -> str:
    return "(" + ", ".join(f"{v + 0.0:.9g}" for v in values) + ")"


def _format_rotation(sequence) -> str:
    if not sequence:
        return "I"
    parts = []
    for axis, angle in sequence:
        text = f"{angle:.0f}" if float(angle).is_integer() else f"{angle:.10g}"
        parts.append(f"R{axis}({text})")
    return " ".join(parts)


def fk_table_markdown() -> str:
    """A markdown table of each ``g_xx``: displacement, fixed rotation and joint axis.

    Generated from the FK module's constants, so it cannot drift from the code.
    """
    names = (("gw1", "w1", "shoulder_pan"), ("g12", "12", "shoulder_lift"),
             ("g23", "23", "elbow_flex"), ("g34", "34", "wrist_flex"),
             ("g45", "45", "wrist_roll"), ("g5t", "5t", None))
    lines = [
        "Each factor is `g_ab(theta) = [[R_fixed Rz(theta), p], [0, 0, 0, 1]]`: frame b sits at "
        "displacement `p` in frame a, turned by the fixed rotation `R_fixed` (rotations about the "
        "named axes in degrees, applied left to right), then by the joint angle about its own z "
        "axis. The joint axis column is that z axis in frame a (the third column of `R_fixed`). "
        "`g5t` has no joint. The tilt in `g45` is `GRIPPER_MOUNT_TILT_DEG` = "
        f"{GRIPPER_MOUNT_TILT_DEG:.10g} deg, exactly the upstream gripper quaternion.",
        "",
        "| transform | frame b in frame a | joint | displacement p [m] | fixed rotation | "
        "joint axis (in a) |",
        "|---|---|---|---|---|---|",
    ]
    for function, key, joint in names:
        displacement, sequence = FIXED_TRANSFORMS[key]
        rotation = np.eye(3)
        for axis, angle in sequence:
            rotation = rotation @ {"x": Rx, "y": Ry, "z": Rz}[axis](angle)
        frame_a, frame_b = key[0], key[1]
        axis_text = _format_vector(np.round(rotation[:, 2], 9)) if joint else "-"
        lines.append(
            f"| `get_{function}` | {frame_b} in {frame_a} | {joint or '- (fixed)'} | "
            f"{_format_vector(displacement)} | {_format_rotation(sequence)} | {axis_text} |"
        )
    return "\n".join(lines) + "\n"

