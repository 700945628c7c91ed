"""The ArUco tags in the vision layer: the simulator's truth of a tag's pose, the printable sheet.

The tags' facts and textures (``Tag``, ``CUBE_TAG``, ``TARGET_TAG``, ``add_cube_tag``, ...)
live in ``so101_kinematics.sim.tag_textures`` (the virtual arm's scene draws them too); the
printed page (:func:`write_tag_sheet`, a PDF drawn at 1:1) is the same image
(``tag_textures.tag_face_image``).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import mujoco
import numpy as np

from so101_kinematics.markers import pdf_metadata
from so101_kinematics.outputs import atomic_output
from so101_kinematics.sim.tag_textures import (
    TAG_DICTIONARY,
    TAGS,
    Tag,
    tag_face_image,
)
from so101_kinematics.vision.camera_model import BASE_BODY

__all__ = ["get_tag_pose_base", "tag_page", "write_tag_sheet"]


def get_tag_pose_base(m: mujoco.MjModel, d: mujoco.MjData, geom: str) -> np.ndarray:
    """The simulator's truth: ``g_bt``, a tag geom's tag frame in the base frame [m].

    The origin is the centre of the geom's top surface (the printed marker's centre).
    """
    g_wt = np.eye(4)
    g_wt[:3, :3] = np.asarray(d.geom(geom).xmat).reshape(3, 3)
    g_wt[:3, 3] = d.geom(geom).xpos + g_wt[:3, 2] * m.geom(geom).size[2]
    g_wb = np.eye(4)
    g_wb[:3, :3] = np.asarray(d.body(BASE_BODY).xmat).reshape(3, 3)
    g_wb[:3, 3] = d.body(BASE_BODY).xpos
    return np.linalg.inv(g_wb) @ g_wt


A4_MM = (210.0, 297.0)  # [mm] portrait
SCALE_BAR_MM = 50.0  # [mm] to check the print with a ruler
MM_PER_INCH = 25.4


def tag_page(tags: Iterable[Tag] = tuple(TAGS.values())):
    """The A4 page of :func:`write_tag_sheet` as a matplotlib ``Figure`` (1 unit = 1 mm)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    figure = Figure(figsize=(A4_MM[0] / MM_PER_INCH, A4_MM[1] / MM_PER_INCH))
    axes = figure.add_axes((0, 0, 1, 1))
    axes.set_axis_off()
    top = A4_MM[1] - 25.0
    axes.text(15, top + 8, f"so101-kinematics ArUco tags ({TAG_DICTIONARY}). Print at 100 % "
              f"(actual size); the bar below must measure {SCALE_BAR_MM:.0f} mm.", fontsize=8)
    for tag in tags:
        face_mm = tag.face * 1000.0
        axes.imshow(tag_face_image(tag), cmap="gray", vmin=0, vmax=255, interpolation="nearest",
                    extent=(15, 15 + face_mm, top - face_mm, top))
        axes.add_patch(Rectangle((15, top - face_mm), face_mm, face_mm, fill=False,
                                 linewidth=0.2, color="0.6"))
        axes.text(20 + face_mm, top - 5, f"{tag.name}: id {tag.tag_id}, black square "
                  f"{tag.size * 1000:.1f} mm (cut on the grey line: {face_mm:.1f} mm)",
                  fontsize=8)
        top -= face_mm + 12.0
    axes.plot([15, 15 + SCALE_BAR_MM], [top, top], color="k", linewidth=1.5)
    axes.text(15, top - 5, f"{SCALE_BAR_MM:.0f} mm", fontsize=8)
    axes.set_xlim(0, A4_MM[0])  # imshow moved them to its extents: the page, 1 unit = 1 mm
    axes.set_ylim(0, A4_MM[1])
    return figure


def write_tag_sheet(path: str | Path, tags: Iterable[Tag] = tuple(TAGS.values())) -> Path:
    """A PDF page (A4) with each tag at its true size, to print at 100 %.

    The tags are the same images as the simulator's textures, placed with their printed
    size exact (vector page, the image scaled to its millimetres), each with its name,
    id, dictionary and marker size, and a 50 mm scale bar to check with a ruler.

    Returns:
        The path written.
    """
    from matplotlib.backends.backend_pdf import PdfPages

    figure = tag_page(tags)
    with atomic_output(path) as temporary, PdfPages(temporary, metadata=pdf_metadata(
            "ArUco tags")) as pdf:
        pdf.savefig(figure)
    return Path(path)
