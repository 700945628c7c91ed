"""The ArUco tags' facts and their textures in the simulator's scene.

One source for every copy of a tag: :func:`tag_face_image` draws a tag's printed square
(the black marker and its white quiet zone) from OpenCV's dictionary; the simulator's
texture (:func:`add_cube_tag`, :func:`add_target_tag`) is that image, and so is the printed
page (``vision/tags.py``'s ``write_tag_sheet``). The textures live here, under the vision
layer, so that the virtual arm's scene (``virtual/``, which imports ``sim/`` and never
``vision/``) draws the same tags its served cameras then see.

The facts, each written once here:

- the dictionary, :data:`TAG_DICTIONARY`: OpenCV's ``DICT_4X4_50`` (50 markers of 4 x 4
  bits; Garrido-Jurado et al., "Automatic generation and detection of highly reliable
  fiducial markers under occlusion", Pattern Recognition 47(6), 2014). 4 x 4 bits give the
  biggest cells a 26 mm cube face can carry: with the one-cell black border a marker is
  6 cells wide (:data:`MARKER_CELLS`);
- each tag's id and sizes (:data:`TAGS`): the cube's marker is 20 mm on its 26 mm top face
  (``constants.CUBE_SIZE``), leaving 3 mm of white (about one cell, the quiet zone the
  detector needs); the target's is 40 mm on a 52 mm square, for the table; the cup's (the
  throw's, ``throwing/cup_camera.py``) the target's size, printed on a mat the cup stands on.

A tag's frame (the pose ``vision/detect.py`` estimates) is OpenCV's for a square marker: its
origin at the marker's centre on the printed surface, x to the right and y up as the marker
is drawn (:func:`tag_face_image`'s first row is its top), z out of the surface towards
whoever reads it. On the cube and the table that is the body's own x, y and up.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE, CUBE_SIZE
from so101_kinematics.opencv_import import require_opencv

__all__ = [
    "CUBE_TAG", "MARKER_CELLS", "TAGS", "TAG_DICTIONARY", "TAG_THICKNESS", "TARGET_TAG", "Tag",
    "CUP_TAG", "add_cube_tag", "add_tag_geom", "add_target_tag", "tag_face_image",
    "tag_geom_name",
]

TAG_DICTIONARY = "DICT_4X4_50"
"""OpenCV's predefined ArUco dictionary every tag of ours is from (``cv2.aruco.DICT_4X4_50``)."""
MARKER_CELLS = 6
"""A 4 x 4-bit marker's width in cells: the bits and a one-cell black border each side."""
TAG_THICKNESS = 0.0002
"""The printed tag's thickness in the simulator [m]: paper (a visual-only geom)."""


@dataclass(frozen=True)
class Tag:
    """One ArUco tag of ours.

    Attributes:
        name: what it marks ("cube", "target").
        tag_id: its id in :data:`TAG_DICTIONARY`.
        size: the black marker's edge [m] (what pose estimation needs).
        face: the printed square's edge, the white quiet zone included [m].
    """

    name: str
    tag_id: int
    size: float
    face: float


CUBE_TAG = Tag("cube", 0, 0.020, CUBE_SIZE)
"""On the top face of the course's cube: a 20 mm marker on the 26 mm face."""
TARGET_TAG = Tag("target", 1, 0.040, 0.052)
"""Where the cube goes, on the table: a 40 mm marker on a 52 mm square."""
CUP_TAG = Tag("cup", 2, 0.040, 0.052)
"""On the mat the throw's cup stands on (``throwing/cup_camera.py``): the target's sizes, its
own id (a cup is not the pick-and-place's target)."""
TAGS = {tag.tag_id: tag for tag in (CUBE_TAG, TARGET_TAG, CUP_TAG)}
"""Every tag of ours by id."""


def tag_face_image(tag: Tag, px_per_cell: int = 30) -> np.ndarray:
    """The tag's printed square: the marker from OpenCV's dictionary in its white border.

    Args:
        tag: which tag.
        px_per_cell: pixels per marker cell (the marker is ``MARKER_CELLS`` cells wide).

    Returns:
        N x N uint8 grey image (0 black, 255 white), row 0 the tag's top.

    Raises:
        OpenCVMissing: no OpenCV (one line with the fix).
    """
    cv2 = require_opencv()
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, TAG_DICTIONARY))
    marker_px = MARKER_CELLS * px_per_cell
    marker = cv2.aruco.generateImageMarker(dictionary, tag.tag_id, marker_px, borderBits=1)
    margin = int(round((tag.face - tag.size) / 2 / tag.size * marker_px))
    face = np.full((marker_px + 2 * margin,) * 2, 255, dtype=np.uint8)
    face[margin:margin + marker_px, margin:margin + marker_px] = marker
    return face


def tag_geom_name(tag: Tag, on: str = "") -> str:
    """The name of a tag's geom: ``cube_tag`` on the body "cube", ``target_tag`` on the table."""
    return f"{on or tag.name}_tag"


def add_tag_geom(spec: mujoco.MjSpec, body, tag: Tag, name: str, pos,
                 yaw_deg: float = 0.0) -> None:
    """Print ``tag`` on ``body`` (an ``MjsBody`` of the spec) at ``pos`` [m], face up, turned.

    A paper-thin textured box: no mass, no contact (the physics is unchanged); ``yaw_deg``
    [deg] turns it about the body's z (0: the tag's top towards the body's +y).
    """
    texture_name = f"aruco_{tag.tag_id}"
    if spec.texture(texture_name) is None:
        face = tag_face_image(tag)
        texture = spec.add_texture(name=texture_name, type=mujoco.mjtTexture.mjTEXTURE_2D,
                                   width=face.shape[1], height=face.shape[0], nchannel=3)
        texture.data = np.repeat(face[:, :, None], 3, axis=2).tobytes()
        material = spec.add_material(name=texture_name)
        material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texture_name
    body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                  size=[tag.face / 2, tag.face / 2, TAG_THICKNESS / 2], pos=list(pos),
                  material=texture_name, contype=0, conaffinity=0, density=0.0, group=1,
                  quat=_yaw_quat(yaw_deg))


def _yaw_quat(yaw_deg: float) -> list[float]:
    """MuJoCo's quaternion (w, x, y, z) of a turn by ``yaw_deg`` [deg] about z."""
    half = np.radians(yaw_deg) / 2
    return [float(np.cos(half)), 0.0, 0.0, float(np.sin(half))]


def add_cube_tag(spec: mujoco.MjSpec, body: str = "cube", tag: Tag = CUBE_TAG) -> str:
    """Print ``tag`` on the top face of a cube of the scene being built (``sim/cube.py``'s).

    Returns:
        The tag geom's name (:func:`tag_geom_name`).
    """
    name = tag_geom_name(tag, body)
    add_tag_geom(spec, spec.body(body), tag, name, (0.0, 0.0, CUBE_HALF_SIZE + TAG_THICKNESS / 2))
    return name


def add_target_tag(spec: mujoco.MjSpec, x: float, y: float, yaw_deg: float = 0.0,
                   tag: Tag = TARGET_TAG) -> str:
    """Lay ``tag`` on the table at (x, y) [m] in the base frame, turned by ``yaw_deg`` [deg].

    Returns:
        The tag geom's name.
    """
    name = tag_geom_name(tag)
    table_z = float(spec.geom("table").pos[2])
    body = spec.worldbody.add_body(name=name, pos=[x, y, table_z],
                                   quat=_yaw_quat(yaw_deg))
    add_tag_geom(spec, body, tag, name, (0.0, 0.0, TAG_THICKNESS / 2))
    return name
