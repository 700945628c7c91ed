"""The arm's facts, read from their one home: ``model/so101.xml`` (no MuJoCo needed).

The MJCF states the SO-101's geometry (each body's position and orientation in its
parent), its joint ranges, its links' masses and centres of mass (``<inertial>``), its
collision boxes (classes ``collision`` and ``jaw_pad``) and its sites. The numbers there
are upstream's (TheRobotStudio's ``so101_new_calib``, SO-ARM100, Apache-2.0) or measured
from its meshes, each with a comment in the file. The kinematics (``frames.py``), the
clearance check and the gravity model read them here, with the standard library's XML
parser, so the core and the real-arm path know the arm without importing MuJoCo.

Example::

    >>> body_position("lower_arm")  # elbow_flex's frame in the upper arm's [m]
    (-0.11257, -0.028, 0.0)
    >>> link_mass("wrist")  # [kg]
    0.079
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ElementTree

from so101_kinematics.errors import KinematicsInputError
from so101_kinematics.paths import MODEL_DIR

__all__ = ["ARM_MODEL_PATH", "BOX_CLASSES", "body_position", "body_quaternion", "centre_of_mass",
           "collision_boxes", "joint_range", "link_mass", "site_position", "site_size"]

ARM_MODEL_PATH = MODEL_DIR / "so101.xml"
"""The arm's MJCF: the one home of its geometry, ranges, masses and collision boxes."""

BOX_CLASSES = ("collision", "jaw_pad")
"""The geom classes that are collision boxes (``jaw_pad`` is a ``collision`` box with the
gripping faces' friction)."""


@functools.cache
def _root() -> ElementTree.Element:
    """The parsed ``<mujoco>`` element (parsed once)."""
    return ElementTree.parse(ARM_MODEL_PATH).getroot()


def _numbers(text: str) -> tuple[float, ...]:
    """``"0.1 -2 3e-3"`` -> ``(0.1, -2.0, 0.003)``: an MJCF vector attribute."""
    return tuple(float(word) for word in text.split())


def _find(tag: str, name: str) -> ElementTree.Element:
    """The element ``<tag name=name>`` of the arm's model."""
    found = _root().find(f".//{tag}[@name='{name}']")
    if found is None:
        raise KinematicsInputError(f"{ARM_MODEL_PATH.name} has no {tag} named {name!r}. "
                                   f"Fix: use one of the model's {tag} names.")
    return found


def body_position(body: str) -> tuple[float, ...]:
    """The ``pos`` [m] of ``body`` in its parent body (MJCF's default: the origin)."""
    return _numbers(_find("body", body).get("pos", "0 0 0"))


def body_quaternion(body: str) -> tuple[float, ...]:
    """The ``quat`` (w, x, y, z) of ``body`` in its parent (MJCF's default: identity)."""
    return _numbers(_find("body", body).get("quat", "1 0 0 0"))


def joint_range(joint: str) -> tuple[float, float]:
    """The ``range`` [rad] of ``joint`` (the compiler's angle unit is radian)."""
    lower, upper = _numbers(_find("joint", joint).get("range"))
    return lower, upper


def link_mass(body: str) -> float:
    """The mass [kg] of ``body``'s ``<inertial>``."""
    return float(_find("body", body).find("inertial").get("mass"))


def centre_of_mass(body: str) -> tuple[float, ...]:
    """The centre of mass [m] of ``body`` in its own frame (``<inertial pos>``)."""
    return _numbers(_find("body", body).find("inertial").get("pos"))


def collision_boxes(body: str) -> tuple[tuple[str, tuple[float, ...], tuple[float, ...]], ...]:
    """``body``'s own collision boxes, in the file's order: (name, centre [m], half sizes [m]).

    Axis-aligned in the body's frame (none has a ``quat``); its child bodies' are not included.
    """
    return tuple((geom.get("name"), _numbers(geom.get("pos")), _numbers(geom.get("size")))
                 for geom in _find("body", body).findall("geom")
                 if geom.get("class") in BOX_CLASSES)


def site_position(site: str) -> tuple[float, ...]:
    """The ``pos`` [m] of ``site`` in its body."""
    return _numbers(_find("site", site).get("pos", "0 0 0"))


def site_size(site: str) -> tuple[float, ...]:
    """The ``size`` [m] of ``site`` (a box site: its half sizes)."""
    return _numbers(_find("site", site).get("size"))
