"""What an FK's returns say beyond their accuracy: its form, NaN, a changed input.

Used by :mod:`.fk_compare` on the probe's results for ``get_forward_kinematics``. The course's
form is ``return position, rotation`` (the assignment's ``get_forward_kinematics``: ``position
= gwt[0:3, 3]``, ``rotation = gwt[0:3, 0:3]``; its test script unpacks the two).
"""

from __future__ import annotations

import numpy as np

__all__ = ["FOUR_BY_FOUR", "changed_cause", "form_cause", "nan_cause"]

FOUR_BY_FOUR = "returns one 4x4 matrix; the course's form is (position, rotation)"
"""The first words of the cause for an FK returning ``gwt`` itself (see :func:`form_cause`)."""


def form_cause(mm: np.ndarray, deg: np.ndarray) -> str:
    """A 4x4 return: the pose's own accuracy, and why the form still breaks the course's scripts."""
    pose = ("the pose in it is right" if mm.max() < 0.01 and deg.max() < 0.01 else
            f"the pose in it is up to {mm.max():.2f} mm, {deg.max():.2f} deg off")
    return (f"{FOUR_BY_FOUR} ({pose}), and the course's scripts unpack `position, rotation = "
            "get_forward_kinematics(cfg)`, which fails on a 4x4 (too many values to unpack). "
            "Fix: return gwt[0:3, 3], gwt[0:3, 0:3]")


def changed_cause(calls: list[dict]) -> str:
    """The FK changed the dict it was given: which keys, how, and at how many calls ('' if not)."""
    changed = [c["changed"] for c in calls if c.get("changed")]
    if not changed:
        return ""
    what = ", ".join(_change(key, before, after)
                     for key, (before, after) in list(changed[0].items())[:3])
    return (f"get_forward_kinematics changes the configuration it is given ({what}; in "
            f"{len(changed)} of {len(calls)} calls): the caller's dict is not its to change "
            "(the course's script moves the arm to that same dict afterwards). Fix: read the "
            "angles into new variables, or work on a copy: cfg = dict(position_dict)")


def nan_cause(positions, rotations, where) -> str:
    """NaN or infinite numbers returned: at how many configurations, and the first ('' if none).

    ``where(index)`` names configuration ``index`` in words.
    """
    bad = ~(np.isfinite(positions).all(axis=1) & np.isfinite(rotations).all(axis=(1, 2)))
    if not bad.any():
        return ""
    return (f"returns NaN or infinite numbers at {int(bad.sum())} of {len(bad)} configurations, "
            f"the first at {where(int(np.argmax(bad)))}: a value that is not a number (a NaN "
            "from sqrt, arccos or 0/0 of one of these angles?)")


def _change(key: str, before, after) -> str:
    """One key's change in words: "wrist_roll 157.0 -> 90.0", "gripper deleted"."""
    if after == "deleted":
        return f"{key} deleted"
    if before is None:
        return f"{key} added"
    return f"{key} {before:.1f} -> " + (f"{after:.1f}" if isinstance(after, float) else after)
