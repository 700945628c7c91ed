"""The cup found by a fixed camera (part 1's pipeline): the throw aims at what the camera sees.

The part-1 overhead camera (``model/table.xml``: 0.55 m above (0.20, 0) m) sees the table
only to x = 0.50 m; the throw's cups stand 0.3-0.6 m from the base, 40 deg either side
(``throw_trials.cup_positions``): x from 0.23 to 0.60 m, y within +-0.39 m. So the throwing
scene gets its own fixed camera, :data:`CUP_CAMERA`: **the same webcam** (the overhead's
58 deg vertical field of view and orientation, read from its MJCF: image up = the base's +x,
image right = -y) on a higher mount, :data:`CUP_CAMERA_POS`: 0.75 m above (0.40, 0) m,
the middle of the cups' range. At 640 x 480 it sees the table from x = -0.01 to 0.81 m and
y from -0.55 to +0.55 m (0.75 m x tan(29 deg) = 0.416 m up and down the image, 4/3 of it
across): every seeded cup with its mat, 0.12 m of margin at the side edges. On the
real rig: a webcam on a ceiling mount or a boom stand, lens 75 cm above the table, pointing
down; its pose measured with the calibration (``calibrate_camera.py``), as the overhead's.

**The tag: on a mat under the cup**, not on the cup. A cup has no flat place for a 40 mm
tag that a camera above sees (its rim is 3 mm wide; its bottom is hidden by its wall, and
the ball lands there), so the cup stands on a printed mat: a circle for the cup and, beside
it, :data:`~so101_kinematics.sim.tag_textures.CUP_TAG` (part 1's ``DICT_4X4_50``, id 2, the
target tag's 40 mm marker on a 52 mm square), its centre :data:`CUP_TAG_OFFSET` from the
cup's axis, towards the tag's top as printed. A student prints the tag (``so101 tags``), glues
it on a card with a circle of the cup's foot 110 mm above the tag's centre, lays the card
with the tag on the arm's side of the cup, and stands the cup on its circle. In the
simulator the tag rides on the cup's (mocap) body, on its -x side: a paper-thin visual geom,
the physics unchanged.

The path is see_and_pick's: the rendered image, made webcam-like (``sim_camera.WEBCAM``),
goes through part 1's detector (``detect.find_tag``); the tag lies flat on the table, so its
pose is its corners' rays met with the table's plane (``detect.flat_pose``) through the
camera's pose in the base frame (the mount's, as a calibration would give it); the cup's
axis is the tag's centre plus :data:`CUP_TAG_OFFSET` along the tag's +y.

What the camera can resolve: 1 px is 1.7 mm on the table below the lens (0.75 m / 433 px of
focal length) and up to 2.0 mm at the farthest mat; the 40 mm marker is 20-23 px wide, its
cells 3.3-3.8 px (too few for ``detect.refine_corners``: the detector's corners stay). With
each corner within half a pixel, the tag's centre (the mean of four) is within 0.5 px, 1 mm;
its yaw, from edges about 20 px long whose ends are each half a pixel off, within
(0.5 + 0.5) / 20 rad = 2.9 deg, which moves the cup's axis 110 mm x 0.05 = 5.5 mm at worst.
:data:`CUP_FOUND_WITHIN` is that bound, 6 mm; measured on the seeded cups of seeds 0-2 with
:data:`LOOK_FRAMES` images each, 0.05-3.8 mm (one image's yaw 0-2.6 deg off). A cup's
margin for the ball is 25 mm (its 45 mm inner radius less the ball's 20).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics import servo
from so101_kinematics.errors import TagNotInView
from so101_kinematics.sim.scene import set_initial_pose
from so101_kinematics.sim.tag_textures import (
    CUP_TAG,
    TAG_DICTIONARY,
    TAG_THICKNESS,
    add_tag_geom,
    tag_geom_name,
)
from so101_kinematics.throwing.ball import Ball
from so101_kinematics.throwing.throw_plan import GRIPPER_HOLD
from so101_kinematics.throwing.throw_scene import (
    build_throw_model,
    hold_ball,
    place_cup,
    throw_spec,
)
from so101_kinematics.throwing.throw_trials import run_throws
from so101_kinematics.vision.detect import find_tag, flat_pose
from so101_kinematics.vision.see_and_pick import LOOK_POSE
from so101_kinematics.vision.sim_camera import WEBCAM, ImageEffects, SimCamera
from so101_kinematics.vision.tags import get_tag_pose_base

__all__ = [
    "CUP_CAMERA", "CUP_CAMERA_POS", "CUP_FOUND_WITHIN", "CUP_TAG_OFFSET", "CupSighting",
    "add_cup_camera", "build_cup_camera_model", "find_cup", "look_at_cup", "look_at_cups",
    "save_camera_image", "table_in_view", "throw_at_seen_cups",
]

CUP_CAMERA = "cup_camera"
"""The throwing scene's fixed camera that finds the cup (the module's docstring)."""
CUP_CAMERA_POS = (0.40, 0.0, 0.75)
"""[m] Its lens in the base frame: above the middle of the cups' x range (0.23-0.60 m), high
enough that the part-1 webcam's 58 deg lens frames y within +-0.55 m (the cups' +-0.39 m)."""
CUP_TAG_OFFSET = 0.110
"""[m] The cup's axis from the tag's centre on the mat, along the tag's +y (its top as
printed): the cup's foot radius (48 mm), the tag's half square (26 mm) and 36 mm of mat
between them, so that the 60 mm cup does not hide the tag from a camera at least
atan(60 / 36) = 59 deg above the table (the camera is 62 deg or more above every mat)."""
CUP_FOUND_WITHIN = 0.006
"""[m] The cup found within this of its axis: the bound of half-pixel corners (the module's
docstring)."""
LOOK_FRAMES = 5
"""Images read of the still scene, each with its own webcam noise; the cup is the mean of
those it is found in. Over 41 seeded cups the worst error fell from 6.6 mm (one image) to
5.0 mm (five), the mean from 2.8 to 2.4 mm; ten images gave 4.3 and 2.3 mm."""
PART1_CAMERA = "overhead"
"""Part 1's fixed camera (``model/table.xml``), whose lens and orientation this one copies."""
_TAG_YAW_DEG = -90.0  # on the cup's body: the tag's +y along the body's +x, to the cup's axis


def add_cup_camera(spec: mujoco.MjSpec, mat_turn_deg: float = 0.0) -> mujoco.MjSpec:
    """Add :data:`CUP_CAMERA` and the cup's mat tag to :func:`throw_scene.throw_spec`'s scene.

    Args:
        spec: the throwing scene, not yet compiled.
        mat_turn_deg: the mat turned about the cup's axis [deg] (0: its tag on the cup's -x
            side, towards the arm; a student's mat lies at any turn).
    """
    part1 = spec.camera(PART1_CAMERA)
    spec.worldbody.add_camera(name=CUP_CAMERA, pos=list(CUP_CAMERA_POS), fovy=part1.fovy,
                              quat=list(part1.quat),
                              mode=mujoco.mjtCamLight.mjCAMLIGHT_FIXED)
    spec.camera(CUP_CAMERA).alt = part1.alt  # the overhead's orientation (its xyaxes)
    turn = math.radians(mat_turn_deg)
    add_tag_geom(spec, spec.body("cup"), CUP_TAG, tag_geom_name(CUP_TAG),
                 (-CUP_TAG_OFFSET * math.cos(turn), -CUP_TAG_OFFSET * math.sin(turn),
                  TAG_THICKNESS / 2), yaw_deg=_TAG_YAW_DEG + mat_turn_deg)
    return spec


def build_cup_camera_model(ball: Ball, servo_keywords=None) -> mujoco.MjModel:
    """The throwing scene (``throw_scene.build_throw_model``) with the cup's camera and tag."""
    return build_throw_model(ball, servo_keywords, spec=add_cup_camera(throw_spec(ball)))


@dataclass(frozen=True)
class CupSighting:
    """Where one image showed the cup.

    Attributes:
        xy: the cup's axis on the table (x, y) [m] in the base frame.
        g_bt: the tag's pose (4x4) [m], flat on the table.
        corners: the tag's four corner pixels (TL, TR, BR, BL) [px].
        frames: the images it is the mean of.
    """

    xy: tuple[float, float]
    g_bt: np.ndarray
    corners: np.ndarray
    frames: int = 1


def find_cup(image: np.ndarray, K: np.ndarray, g_bc: np.ndarray,
             camera: str = CUP_CAMERA) -> CupSighting:
    """The cup in one image (a real webcam's or the simulator's): its mat's tag, then its axis.

    Args:
        image: H x W x 3 uint8 RGB.
        K: the camera matrix [px].
        g_bc: the camera's OpenCV frame in the base frame [m] (the mount or a calibration).
        camera: the camera's name, for the message.

    Raises:
        TagNotInView: the tag not wholly in the image (one line with the fix).
    """
    seen = find_tag(image, K, CUP_TAG)
    if seen is None:
        raise TagNotInView(_not_seen(camera, table_in_view(K, g_bc, image.shape[:2])))
    g_bt = flat_pose(seen, K, g_bc, TAG_THICKNESS)
    axis = g_bt[:3, 3] + CUP_TAG_OFFSET * g_bt[:3, 1]
    return CupSighting((float(axis[0]), float(axis[1])), g_bt, seen.corners)


def table_in_view(K: np.ndarray, g_bc: np.ndarray, shape) -> tuple[tuple[float, float], ...]:
    """The table the camera sees: ((x min, x max), (y min, y max)) [m] in the base frame.

    The image's four corner pixels' rays met with the table's plane (a camera looking down,
    whose corners all meet it in front of it). ``shape``: the image's (height, width).
    """
    height, width = shape
    pixels = np.array([[0.0, 0.0, 1.0], [width - 1, 0.0, 1.0], [0.0, height - 1, 1.0],
                       [width - 1, height - 1, 1.0]])
    rays = np.linalg.solve(np.asarray(K, dtype=float), pixels.T).T @ g_bc[:3, :3].T
    points = g_bc[:3, 3] + ((TAG_THICKNESS - g_bc[2, 3]) / rays[:, 2])[:, None] * rays
    return ((float(points[:, 0].min()), float(points[:, 0].max())),
            (float(points[:, 1].min()), float(points[:, 1].max())))


def _not_seen(camera: str, field) -> str:
    (x0, x1), (y0, y1) = field
    return (f"the cup's tag (ArUco {TAG_DICTIONARY} id {CUP_TAG.tag_id}, "
            f"{CUP_TAG.size * 1000:.0f} mm, on the mat {CUP_TAG_OFFSET * 1000:.0f} mm from the "
            f"cup) is not in the view of the camera {camera!r} or is partly hidden, so nothing "
            f"was thrown. Fix: stand the cup on its mat within x {x0:.2f} to {x1:.2f} m and y "
            f"{y0:.2f} to {y1:.2f} m of the base (the camera's view of the table), the tag "
            "uncovered, or leave --find-cup out to throw at --cup.")


def look_at_cup(m: mujoco.MjModel, cup_xy, effects: ImageEffects | None = WEBCAM,
                frames: int = LOOK_FRAMES) -> tuple[CupSighting, np.ndarray, dict]:
    """Stand the cup at ``cup_xy`` (the truth), the arm still, and find it with the camera.

    The arm waits as part 1's does while its camera looks (``see_and_pick.LOOK_POSE``: the
    rest pose, its gripper turned up, the ball in it): at rest, its gripper hides the mat of
    a cup straight ahead at 0.3 m from the camera.

    Args:
        m: :func:`build_cup_camera_model`'s model.
        cup_xy: where the cup stands (x, y) [m]: the simulator's truth, not read by the look.
        effects: the webcam-like effects (None: the image as rendered).
        frames: images read (:data:`LOOK_FRAMES`).

    Returns:
        The sighting (the cup's mean over the images it was found in; the tag's pose and
        corners the first image's), that first image, and the truth (``tag``: its pose, ``K``,
        ``g_bc``) for scoring and drawing.

    Raises:
        TagNotInView: the tag in none of the frames.
    """
    d = mujoco.MjData(m)
    place_cup(m, d, *cup_xy)
    set_initial_pose(d, {**LOOK_POSE, "gripper": GRIPPER_HOLD})
    hold_ball(m, d)
    sightings, error = [], None
    with SimCamera(m, d, CUP_CAMERA, effects=effects) as camera:
        K, g_bc = camera.intrinsics(), camera.pose()
        for _ in range(frames):
            image = camera.read()
            try:
                sightings.append((find_cup(image, K, g_bc, CUP_CAMERA), image))
            except TagNotInView as not_seen:
                error = not_seen
    if not sightings:
        raise error or TagNotInView("no image was read")
    first, image = sightings[0]
    xy = np.mean([seen.xy for seen, _ in sightings], axis=0)
    sighting = replace(first, xy=(float(xy[0]), float(xy[1])), frames=len(sightings))
    truth = {"tag": get_tag_pose_base(m, d, tag_geom_name(CUP_TAG)), "K": K, "g_bc": g_bc}
    return sighting, image, truth


def look_at_cups(m: mujoco.MjModel, cups, seed: int = 0,
                 effects: ImageEffects | None = WEBCAM) -> list[tuple[CupSighting, np.ndarray,
                                                                        dict]]:
    """:func:`look_at_cup` at each cup, the webcam's noise seeded per cup from ``seed``.

    Raises:
        TagNotInView: a cup not seen, its position in the message (nothing was thrown).
    """
    looks = []
    for index, cup in enumerate(cups):
        noise = None if effects is None else replace(effects, seed=seed * 1000 + index)
        try:
            looks.append(look_at_cup(m, cup, noise))
        except TagNotInView as error:
            raise TagNotInView(f"cup {index + 1} at ({cup[0]:.3f}, {cup[1]:.3f}) m: "
                               f"{error}") from None
    return looks


def throw_at_seen_cups(m: mujoco.MjModel, ball: Ball, cups, seed: int = 0,
                       volts: float = servo.DEFAULT_SUPPLY_V,
                       variant: str = servo.DEFAULT_VARIANT, looks=None) -> dict:
    """Find every cup with the camera first, then throw at each where the camera saw it.

    Args:
        m: :func:`build_cup_camera_model`'s model.
        ball: its ball.
        cups: where the cups truly stand (x, y) [m].
        seed: the webcam noise's seed.
        volts: the servos' supply [V].
        variant: the servos' variant.
        looks: :func:`look_at_cups`'s result, when already looked.

    Returns:
        ``throw_trials.run_throws``'s report, each trial with ``cup_seen_xy``,
        ``cup_true_xy`` and ``cup_seen_error_mm``; ``cup_seen_error_mm``'s mean and worst.

    Raises:
        TagNotInView: a cup not seen (before anything is thrown).
        PlanError: a seen cup out of the throw's range.
    """
    looks = look_at_cups(m, cups, seed) if looks is None else looks
    seen = [look[0].xy for look in looks]
    report = run_throws(m, ball, cups, volts, variant, aims=seen)
    errors = []
    for trial, cup, xy in zip(report["trials"], cups, seen, strict=True):
        error = 1000 * math.dist(cup, xy)
        errors.append(error)
        trial.update(cup_seen_xy=[round(v, 4) for v in xy],
                     cup_true_xy=[round(float(v), 4) for v in cup],
                     cup_seen_error_mm=round(error, 2))
    report["cup_seen_error_mm"] = {"mean": round(float(np.mean(errors)), 2),
                                   "worst": round(float(np.max(errors)), 2)}
    report["camera"] = {"name": CUP_CAMERA, "pos_m": list(CUP_CAMERA_POS),
                        "tag": {"dictionary": TAG_DICTIONARY, "id": CUP_TAG.tag_id,
                                "size_m": CUP_TAG.size},
                        "found_within_mm": CUP_FOUND_WITHIN * 1000,
                        "webcam_effects": {"blur_px": WEBCAM.blur_px,
                                           "noise_levels": WEBCAM.noise_levels}}
    return report


def save_camera_image(path: Path, look, cup_xy) -> None:
    """A PNG of the camera's view: the found tag outlined, the cup's axis as seen and as true."""
    from matplotlib.figure import Figure

    from so101_kinematics.markers import png_metadata
    from so101_kinematics.outputs import atomic_output
    from so101_kinematics.vision.camera_model import project_points

    sighting, image, truth = look
    figure = Figure(figsize=(6.4, 5.2), dpi=100)
    axes = figure.add_axes((0.0, 0.08, 1.0, 0.92))
    axes.imshow(image)
    axes.axis("off")
    outline = np.vstack([sighting.corners, sighting.corners[:1]])
    axes.plot(outline[:, 0], outline[:, 1], color="lime", linewidth=1.2)
    points = project_points(truth["K"], truth["g_bc"], [[*sighting.xy, 0.0], [*cup_xy, 0.0]])
    axes.plot(*points[0], marker="+", color="lime", markersize=14, mew=1.5)
    axes.plot(*points[1], marker="x", color="blue", markersize=9, mew=1.2)
    error = 1000 * math.dist(sighting.xy, cup_xy)
    figure.text(0.5, 0.04, f"{CUP_CAMERA}: the tag found (green); the cup's axis seen (+), "
                f"{error:.1f} mm from the truth (x)",
                ha="center", va="center", fontsize=8)
    with atomic_output(Path(path)) as temporary:
        figure.savefig(temporary, format="png", metadata=png_metadata("throw.py"))
