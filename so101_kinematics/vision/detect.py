"""One detection path for every image: ArUco tags found, their poses in the robot's base frame.

The simulator's rendered images, the virtual arm's and a real webcam's go through the
same three steps:

1. **detect**: ``cv2.aruco.ArucoDetector`` (OpenCV 4.7 and newer, 5.0 included; never the
   old free functions ``cv2.aruco.detectMarkers`` / ``estimatePoseSingleMarkers``, gone
   from the main package), on the grey image of the ``interfaces.Camera``'s RGB (the
   RGB -> grey conversion is here, once); the corners then refined on the marker's edges
   (:func:`refine_corners`);
2. **pose in the camera**: ``cv2.solvePnP`` with ``SOLVEPNP_IPPE_SQUARE``, the marker's four
   corners in the order the detector gives them (top-left, top-right, bottom-right,
   bottom-left as drawn) matched to the square's corners in the tag frame
   (:func:`tag_corners`, OpenCV's documented order for that method); ``g_ct``;
3. **pose in the base**: ``g_bt = g_bc @ g_ct`` through the camera's pose in the base frame
   (the simulator's truth, or a calibration); for a tag known to lie flat at a known height
   (on the table, on a resting cube), :func:`flat_pose` instead meets the corners' rays with
   that plane: far better from a camera high above a small tag.

A tag that is not found, or only partly visible (a hidden corner: ArUco does not decode
it), gives ``None``: never a guessed pose. :func:`no_tag_message` says it in one line.

Example::

    with SimCamera(m, d, "overhead") as camera:
        seen = find_tag(camera.read(), camera.intrinsics(), CUBE_TAG, g_bc=camera.pose())
    print(no_tag_message(CUBE_TAG, "overhead") if seen is None else seen.g_bt[:3, 3])
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from so101_kinematics.errors import VisionError
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.sim.tag_textures import TAG_DICTIONARY, TAGS, Tag

__all__ = ["TagSighting", "detect_tags", "find_tag", "flat_pose", "grey_image",
           "no_tag_message", "refine_corners", "tag_corners"]


def tag_corners(size: float) -> np.ndarray:
    """The marker's corners in its tag frame [m], in the detector's order (TL, TR, BR, BL).

    OpenCV's order for ``SOLVEPNP_IPPE_SQUARE`` (its ``calib3d`` documentation).
    """
    half = size / 2.0
    return np.array([[-half, half, 0.0], [half, half, 0.0], [half, -half, 0.0],
                     [-half, -half, 0.0]])


@dataclass(frozen=True)
class TagSighting:
    """A tag found in an image.

    Attributes:
        tag: which tag (its id and size).
        corners: 4 x 2 corner pixels (u right, v down) [px], TL, TR, BR, BL as drawn.
        g_ct: the tag frame in the camera's OpenCV frame (4x4) [m].
        g_bt: the tag frame in the base frame [m] (None when no camera pose was given).
        reprojection_px: RMS distance of the corners from the pose's projection [px].
    """

    tag: Tag
    corners: np.ndarray
    g_ct: np.ndarray
    g_bt: np.ndarray | None
    reprojection_px: float


@functools.lru_cache(maxsize=4)
def _detector(dictionary: str):
    cv2 = require_opencv()
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    # Read each cell's bit from its middle 40 % (OpenCV: 74 %): a small tag's cells are a
    # few pixels, and a blurred cell's edges take grey from its neighbours. Only the bits'
    # reading changes (the corners do not); the overhead camera's 20 mm tag (2.7 px cells at
    # 640x480, with a webcam's blur and noise) was missed in 7 % of frames, none so since.
    parameters.perspectiveRemoveIgnoredMarginPerCell = 0.3
    return cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)), parameters)


def grey_image(image: np.ndarray) -> np.ndarray:
    """An ``interfaces.Camera`` image (H x W x 3 uint8 RGB) in grey; a grey image as it is."""
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3) or (
            image.ndim == 3 and image.shape[2] != 3):
        raise VisionError(f"An image must be H x W x 3 uint8 RGB (or H x W grey); got "
                          f"{image.dtype} {image.shape}. Fix: pass camera.read()'s image.")
    if image.ndim == 2:
        return image
    return require_opencv().cvtColor(image, require_opencv().COLOR_RGB2GRAY)


EDGE_SAMPLES = 12
"""Profiles across each of the marker's outer edges that :func:`refine_corners` reads."""
MIN_CELL_PX = 4.0
"""Below this many pixels a cell, the edge profiles are too short: the detector's corners stay."""


def _edge_line(grey: np.ndarray, start: np.ndarray, end: np.ndarray, reach: float):
    """A point and a direction of the line where one dark-to-light edge crosses half-grey.

    Profiles across the edge (from ``reach`` px inside the marker to ``reach`` outside),
    each one's half-way crossing between its dark and light ends; a line through them
    (total least squares). None when the profiles show no edge.
    """
    cv2 = require_opencv()
    along = end - start
    normal = np.array([along[1], -along[0]]) / np.linalg.norm(along)  # outwards (TL->TR: up)
    fractions = np.linspace(0.15, 0.85, EDGE_SAMPLES)
    offsets = np.linspace(-reach, reach, int(4 * reach) + 1)
    points = start + fractions[:, None] * along
    samples = points[:, None, :] + offsets[None, :, None] * normal
    profiles = cv2.remap(grey, samples[..., 0].astype(np.float32),
                         samples[..., 1].astype(np.float32), cv2.INTER_LINEAR)
    crossings = []
    for point, profile in zip(points, profiles, strict=True):
        dark, light = profile[: len(offsets) // 4].mean(), profile[-(len(offsets) // 4):].mean()
        if light - dark < 30.0:
            continue
        above = np.nonzero(profile >= (dark + light) / 2)[0]
        above = above[above > 0]
        if len(above) == 0:
            continue
        i = above[0]
        fraction = ((dark + light) / 2 - profile[i - 1]) / (profile[i] - profile[i - 1])
        crossings.append(point + (offsets[i - 1] + fraction * (offsets[1] - offsets[0])) * normal)
    if len(crossings) < EDGE_SAMPLES // 2:
        return None
    crossings = np.array(crossings)
    centre = crossings.mean(axis=0)
    direction = np.linalg.svd(crossings - centre)[2][0]
    return centre, direction


def refine_corners(grey: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """The marker's corners as the crossings of its four outer edges' lines [px].

    The detector's sub-pixel corners sit about 0.15 px inside a blurred square's corners
    (its refinement is made for the saddle points of a chessboard, not a square's
    corners): 2 mm at 30 cm on a 20 mm tag. Lines fitted to where each edge crosses
    half-way between black and white do not move under a symmetric blur (measured in
    ``tests/vision/test_detect.py``). Corners of a marker whose cells are smaller than
    ``MIN_CELL_PX``, or whose edges do not show, are returned as they came.
    """
    side = np.mean(np.linalg.norm(corners - np.roll(corners, -1, axis=0), axis=1))
    cell = side / 6.0
    if cell < MIN_CELL_PX:
        return corners
    grey = np.asarray(grey, dtype=np.float32)
    lines = [_edge_line(grey, corners[i], corners[(i + 1) % 4], 0.8 * cell) for i in range(4)]
    if any(line is None for line in lines):
        return corners
    refined = np.empty_like(corners)
    for i in range(4):
        (p, u), (q, v) = lines[i - 1], lines[i]
        a = np.column_stack([u, -v])
        if abs(np.linalg.det(a)) < 1e-6:
            return corners
        s = np.linalg.solve(a, q - p)[0]
        refined[i] = p + s * u
    if np.max(np.linalg.norm(refined - corners, axis=1)) > 1.0:
        return corners  # not the square the detector found: keep its corners
    return refined


def _pose(corners: np.ndarray, tag: Tag, K: np.ndarray, dist) -> tuple[np.ndarray, float]:
    """``g_ct`` and the RMS reprojection error [px] of one marker's corners.

    ``SOLVEPNP_IPPE_SQUARE``; where it fails (OpenCV 4.12 returns NaN for a square seen
    exactly face-on at the principal point: the overhead camera over a tag in the middle of
    its image) ``SOLVEPNP_SQPNP``, which needs no such case.
    """
    cv2 = require_opencv()
    obj = tag_corners(tag.size)
    ok, rvec, tvec = cv2.solvePnP(obj, corners, K, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not (ok and np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
        ok, rvec, tvec = cv2.solvePnP(obj, corners, K, dist, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        raise VisionError(f"solvePnP found no pose for tag {tag.tag_id}'s corners {corners}.")
    g_ct = np.eye(4)
    g_ct[:3, :3] = cv2.Rodrigues(rvec)[0]
    g_ct[:3, 3] = tvec.ravel()
    projected = cv2.projectPoints(obj, rvec, tvec, K, dist)[0].reshape(4, 2)
    return g_ct, float(np.sqrt(np.mean(np.sum((projected - corners) ** 2, axis=1))))


def detect_tags(image: np.ndarray, K: np.ndarray, dist=None, g_bc: np.ndarray | None = None,
                tags: dict[int, Tag] = TAGS) -> list[TagSighting]:
    """Every tag of ``tags`` in the image, each with its pose.

    Args:
        image: H x W x 3 uint8 RGB (``interfaces.Camera.read()``), or H x W grey.
        K: the camera matrix [px].
        dist: OpenCV's distortion coefficients (None: none, as the simulator's cameras).
        g_bc: the camera's OpenCV frame in the base frame (4x4) [m]; None: poses in the
            camera only.
        tags: the tags to look for, by id (markers of other ids are ignored).

    Returns:
        The sightings, by tag id (the same id twice: both).
    """
    grey = grey_image(image)
    corners_list, ids, _ = _detector(TAG_DICTIONARY).detectMarkers(grey)
    if ids is None:
        return []
    K = np.asarray(K, dtype=float)
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float)
    sightings = []
    for corners, tag_id in sorted(zip(corners_list, ids.ravel(), strict=True),
                                  key=lambda pair: int(pair[1])):
        tag = tags.get(int(tag_id))
        if tag is None:
            continue
        corners = refine_corners(grey, np.asarray(corners, dtype=float).reshape(4, 2))
        g_ct, error = _pose(corners, tag, K, dist)
        g_bt = None if g_bc is None else np.asarray(g_bc, dtype=float) @ g_ct
        sightings.append(TagSighting(tag, corners, g_ct, g_bt, error))
    return sightings


def find_tag(image: np.ndarray, K: np.ndarray, tag: Tag, dist=None,
             g_bc: np.ndarray | None = None) -> TagSighting | None:
    """The one tag ``tag`` in the image, or None when it is not (wholly) in view.

    Seen twice (two printed copies), the one with the smaller reprojection error.
    """
    found = detect_tags(image, K, dist, g_bc, {tag.tag_id: tag})
    return min(found, key=lambda s: s.reprojection_px) if found else None


def flat_pose(sighting: TagSighting, K: np.ndarray, g_bc: np.ndarray, height: float,
              dist=None) -> np.ndarray:
    """``g_bt`` of a tag known to lie face up at ``height``: its corners' rays met by that plane.

    A tag on the table or on a cube resting there lies flat at a known height; what a camera
    far above it measures poorly (its tilt, its distance: a few pixels of outline) is then
    given, and what it measures well (where the corners are in the image) fixes the rest:
    each corner's ray meets the plane ``z = height`` of the base frame, the tag's centre is
    the mean of the four points, its yaw the direction of its top and bottom edges.

    Args:
        sighting: the tag as :func:`detect_tags` found it.
        K: the camera matrix [px].
        g_bc: the camera's OpenCV frame in the base frame [m].
        height: the tag's printed surface above the base frame's origin [m] (a cube's tag:
            the table's z + ``CUBE_SIZE`` + ``tags.TAG_THICKNESS``).
        dist: OpenCV's distortion coefficients (None: none).

    Returns:
        4x4 pose [m]: z up, x and y the tag's own (as printed).

    Raises:
        VisionError: a corner's ray that does not meet the plane in front of the camera.
    """
    cv2 = require_opencv()
    g_bc = np.asarray(g_bc, dtype=float)
    corners = np.asarray(sighting.corners, dtype=np.float64).reshape(-1, 1, 2)
    normalised = cv2.undistortPoints(corners, np.asarray(K, dtype=float),
                                     np.zeros(5) if dist is None else np.asarray(dist, float))
    rays_b = np.column_stack([normalised.reshape(-1, 2), np.ones(4)]) @ g_bc[:3, :3].T
    scale = (height - g_bc[2, 3]) / rays_b[:, 2]
    if np.any(~np.isfinite(scale)) or np.any(scale <= 0.0):
        raise VisionError(f"The {sighting.tag.name} tag's corners do not look down onto the "
                          f"plane z = {height:.3f} m. Fix: give the height of the tag's surface "
                          "in the base frame, for a camera above it.")
    points = g_bc[:3, 3] + scale[:, None] * rays_b  # TL, TR, BR, BL on the plane
    across = (points[1] - points[0]) + (points[2] - points[3])  # the tag's +x
    yaw = np.arctan2(across[1], across[0])
    g_bt = np.eye(4)
    g_bt[:3, :3] = [[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0],
                    [0.0, 0.0, 1.0]]
    g_bt[:3, 3] = points.mean(axis=0)
    return g_bt


def no_tag_message(tag: Tag, camera: str) -> str:
    """One line for a tag not in view, ending with what to do."""
    return (f"The {tag.name} tag (ArUco {TAG_DICTIONARY} id {tag.tag_id}, "
            f"{tag.size * 1000:.0f} mm) is not in the {camera} camera's view, or partly "
            "hidden. Fix: bring all four of its corners into view (move the arm or the "
            "object), and check the light.")
