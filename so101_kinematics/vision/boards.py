"""The ChArUco calibration board: its facts, its image, the simulator's copy and the printed page.

One source for every copy of the board, as :mod:`so101_kinematics.sim.tag_textures` is for the
tags: :func:`charuco_board` is OpenCV's ``cv2.aruco.CharucoBoard`` of :data:`CALIBRATION_BOARD`;
:func:`board_face_image` draws it with a white margin; the simulator's texture
(:func:`add_board`) and the printed page (:func:`write_board_sheet`, a PDF at 1:1) are that
image.

The facts, each written once here:

- the dictionary: the tags' own (``tags.TAG_DICTIONARY``, ``DICT_4X4_50``), the board's
  markers numbered from :data:`Board.first_id` = 10, so the cube's and the target's tags
  (ids 0 and 1) are never mistaken for the board's markers, nor the board's for them;
- 5 x 7 squares of 32 mm, markers of 24 mm (4 mm of white each side in a square, two-thirds
  of a cell), and 8 mm of white margin: 176 x 240 mm, on an A4 page with its text and scale
  bar. The camera sees its 4 x 6 = 24 inner corners (the chessboard's crossings), each found
  to a fraction of a pixel; a partly hidden board still gives those it sees.

The board's frame (:data:`G_BODY_BOARD`, what ``cv2.solvePnP`` on its corners estimates) is
OpenCV's for a ChArUco board: the origin at the top-left corner of the squares as the board is
drawn, x to the right, y *down*, z *into* the board (away from whoever reads it). The
simulator's board body has x right, y up and z out of the printed face (the tags' convention).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.markers import pdf_metadata
from so101_kinematics.opencv_import import require_opencv
from so101_kinematics.outputs import atomic_output
from so101_kinematics.sim.tag_textures import TAG_DICTIONARY
from so101_kinematics.vision.camera_model import BASE_BODY

__all__ = [
    "BOARD_BODY", "Board", "CALIBRATION_BOARD", "G_BODY_BOARD", "add_board", "board_face_image",
    "board_page", "charuco_board", "get_board_pose_base", "set_board_pose", "write_board_sheet",
]

BOARD_BODY = "charuco_board"
"""The simulator's board: a mocap body (posed by the program, no contact, no mass)."""


@dataclass(frozen=True)
class Board:
    """A ChArUco board.

    Attributes:
        squares: (columns, rows) of chessboard squares.
        square: a square's edge [m].
        marker: an ArUco marker's edge [m] (in the white squares).
        first_id: the id of its first marker in ``tags.TAG_DICTIONARY``.
        margin: the white border around the squares [m].
        thickness: the board's thickness in the simulator [m] (foam board).
    """

    squares: tuple[int, int] = (5, 7)
    square: float = 0.032
    marker: float = 0.024
    first_id: int = 10
    margin: float = 0.008
    thickness: float = 0.003

    @property
    def size(self) -> tuple[float, float]:
        """(width, height) of the squares [m] (the board frame's x and y extent)."""
        return self.squares[0] * self.square, self.squares[1] * self.square

    @property
    def face(self) -> tuple[float, float]:
        """(width, height) of the printed board with its margin [m]."""
        return tuple(edge + 2 * self.margin for edge in self.size)


CALIBRATION_BOARD = Board()
"""The project's board: 5 x 7 squares of 32 mm, 24 mm markers, ids 10 to 26, 176 x 240 mm."""


def _board_frame_in_body(board: Board) -> np.ndarray:
    width, height = board.size
    g = np.diag([1.0, -1.0, -1.0, 1.0])  # x right; y down and z into it (OpenCV's)
    g[:3, 3] = (-width / 2, height / 2, board.thickness / 2)  # top-left, on the printed face
    return g


G_BODY_BOARD = _board_frame_in_body(CALIBRATION_BOARD)
"""The board frame (OpenCV's ChArUco object frame) in the simulator's board body (4x4) [m]."""


@functools.lru_cache(maxsize=4)
def charuco_board(board: Board = CALIBRATION_BOARD):
    """OpenCV's ``cv2.aruco.CharucoBoard`` of ``board`` (the one object every copy comes from).

    Raises:
        OpenCVMissing: no OpenCV (one line with the fix).
    """
    cv2 = require_opencv()
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, TAG_DICTIONARY))
    markers = (board.squares[0] * board.squares[1]) // 2
    return cv2.aruco.CharucoBoard(board.squares, board.square, board.marker, dictionary,
                                  np.arange(board.first_id, board.first_id + markers))


def board_face_image(board: Board = CALIBRATION_BOARD, px_per_mm: float = 4.0) -> np.ndarray:
    """The printed board: OpenCV's drawing of the squares and markers in a white margin.

    Returns:
        H x W uint8 grey image (0 black, 255 white), row 0 the board's top.
    """
    width, height = (int(round(edge * 1000 * px_per_mm)) for edge in board.size)
    squares = charuco_board(board).generateImage((width, height), marginSize=0, borderBits=1)
    margin = int(round(board.margin * 1000 * px_per_mm))
    return np.pad(squares, margin, constant_values=255)


def add_board(spec: mujoco.MjSpec, board: Board = CALIBRATION_BOARD,
              name: str = BOARD_BODY) -> str:
    """Add the board as a mocap body of the scene being built, out of sight below the table.

    A textured box of the printed face's size: no mass, no contact (the physics is unchanged).
    :func:`set_board_pose` puts it where a view needs it.

    Returns:
        The body's name.
    """
    face = board_face_image(board)
    texture = spec.add_texture(name=name, type=mujoco.mjtTexture.mjTEXTURE_2D,
                               width=face.shape[1], height=face.shape[0], nchannel=3)
    texture.data = np.repeat(face[:, :, None], 3, axis=2).tobytes()
    material = spec.add_material(name=name)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = name
    body = spec.worldbody.add_body(name=name, mocap=True, pos=[0.0, 0.0, -1.0])
    width, height = board.face
    body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                  size=[width / 2, height / 2, board.thickness / 2], material=name,
                  contype=0, conaffinity=0, density=0.0, group=1)
    return name


def _base_in_world(d: mujoco.MjData) -> np.ndarray:
    g = np.eye(4)
    g[:3, :3] = np.asarray(d.body(BASE_BODY).xmat).reshape(3, 3)
    g[:3, 3] = d.body(BASE_BODY).xpos
    return g


def set_board_pose(m: mujoco.MjModel, d: mujoco.MjData, g_b_board: np.ndarray,
                   name: str = BOARD_BODY) -> None:
    """Put the board frame (:data:`G_BODY_BOARD`'s) at ``g_b_board`` in the base frame.

    Sets the mocap body's pose; the caller runs ``mj_forward`` before rendering.
    """
    g_w_body = _base_in_world(d) @ np.asarray(g_b_board, dtype=float) @ np.linalg.inv(
        G_BODY_BOARD)
    mocap = m.body(name).mocapid[0]
    d.mocap_pos[mocap] = g_w_body[:3, 3]
    quaternion = np.empty(4)
    mujoco.mju_mat2Quat(quaternion, g_w_body[:3, :3].ravel())
    d.mocap_quat[mocap] = quaternion


def get_board_pose_base(d: mujoco.MjData, name: str = BOARD_BODY) -> np.ndarray:
    """The simulator's truth: ``g_b_board``, the board frame in the base frame [m]."""
    g_w_body = np.eye(4)
    g_w_body[:3, :3] = np.asarray(d.body(name).xmat).reshape(3, 3)
    g_w_body[:3, 3] = d.body(name).xpos
    return np.linalg.inv(_base_in_world(d)) @ g_w_body @ G_BODY_BOARD


A4_MM = (210.0, 297.0)  # [mm] portrait
SCALE_BAR_MM = 50.0  # [mm] to check the print with a ruler
MM_PER_INCH = 25.4


def board_page(board: Board = CALIBRATION_BOARD):
    """The A4 page of :func:`write_board_sheet` as a matplotlib ``Figure`` (1 unit = 1 mm)."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(A4_MM[0] / MM_PER_INCH, A4_MM[1] / MM_PER_INCH))
    axes = figure.add_axes((0, 0, 1, 1))
    axes.set_axis_off()
    width, height = (edge * 1000.0 for edge in board.face)
    left, top = (A4_MM[0] - width) / 2, A4_MM[1] - 28.0
    columns, rows = board.squares
    axes.text(left, top + 14, f"so101-kinematics ChArUco board ({TAG_DICTIONARY}, ids "
              f"{board.first_id}-{board.first_id + columns * rows // 2 - 1}): {columns} x "
              f"{rows} squares of {board.square * 1000:.0f} mm, markers {board.marker * 1000:.0f}"
              " mm.", fontsize=7)
    axes.text(left, top + 8, f"Print at 100 % (actual size); the bar below must measure "
              f"{SCALE_BAR_MM:.0f} mm. Glue it flat on a stiff board.", fontsize=7)
    axes.imshow(board_face_image(board), cmap="gray", vmin=0, vmax=255, interpolation="nearest",
                extent=(left, left + width, top - height, top))
    bar = top - height - 8.0
    axes.plot([left, left + SCALE_BAR_MM], [bar, bar], color="k", linewidth=1.5)
    axes.text(left, bar - 5, f"{SCALE_BAR_MM:.0f} mm", fontsize=7)
    axes.set_xlim(0, A4_MM[0])  # imshow moved them to its extents: the page, 1 unit = 1 mm
    axes.set_ylim(0, A4_MM[1])
    return figure


def write_board_sheet(path: str | Path, board: Board = CALIBRATION_BOARD) -> Path:
    """A PDF page (A4) with the board at its true size, to print at 100 %.

    The same image as the simulator's texture, placed with its printed size exact.

    Returns:
        The path written.
    """
    from matplotlib.backends.backend_pdf import PdfPages

    figure = board_page(board)
    with atomic_output(path) as temporary, PdfPages(temporary, metadata=pdf_metadata(
            "ChArUco calibration board")) as pdf:
        pdf.savefig(figure)
    return Path(path)
