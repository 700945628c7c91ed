"""The two arms' shared workspace: the rule every planned path passes, and the run's watch.

The rule, checked on every planned move before it runs (:func:`check_shared_path`), at its goals
every ``PATH_SAMPLE_S`` along the path, the other arm where it is commanded:

1. one arm in the board's area at a time: the moving arm's object frame may enter the
   board's rectangle widened by ``ZONE_MARGIN`` only while the other arm's is outside it;
2. the two arms' collision geoms (``model/so101.xml``'s boxes) stay ``MIN_ARM_DISTANCE``
   apart (MuJoCo's ``mj_geomDistance``).

A violation is refused in one line, with the fix. During the run, :class:`ArmDistanceWatch`
(a viewer wrapper) measures the arms' distance in the simulation and counts collisions: the
times the two arms' geoms come to touch (the arms' geoms do not collide with each other in
MuJoCo, ``contype`` 2 / ``conaffinity`` 1, so touching is measured, never felt).
"""

from __future__ import annotations

import mujoco
import numpy as np

from so101_kinematics.errors import ClearanceError

__all__ = [
    "MIN_ARM_DISTANCE", "PATH_SAMPLE_S", "WATCH_EVERY", "ZONE_MARGIN", "ArmDistanceWatch",
    "arm_distance", "check_shared_path", "in_zone",
]

MIN_ARM_DISTANCE = 0.02
"""[m] The least distance between the two arms' collision boxes along a planned path."""
ZONE_MARGIN = 0.03
"""[m] The board's area: its rectangle widened by this on every side."""
PATH_SAMPLE_S = 0.04
"""[s] Between two checked goals along a planned path."""
WATCH_EVERY = 5
"""Physics steps between two measurements when a video syncs every step (20 ms)."""
_SEARCH = 0.1
"""[m] Pairs of geoms whose bounding spheres are farther apart than this are not measured."""


def arm_distance(m: mujoco.MjModel, d: mujoco.MjData, geoms_a: np.ndarray,
                 geoms_b: np.ndarray, cap: float = _SEARCH) -> float:
    """The least distance [m] between two sets of geoms at ``d``'s kinematics (capped at ``cap``).

    Negative when they overlap (the penetration depth).
    """
    centres = np.linalg.norm(d.geom_xpos[geoms_a][:, None, :] - d.geom_xpos[geoms_b][None, :, :],
                             axis=2)
    gap = centres - m.geom_rbound[geoms_a][:, None] - m.geom_rbound[geoms_b][None, :]
    least = cap
    for i, j in zip(*np.nonzero(gap < cap), strict=True):
        least = min(least, mujoco.mj_geomDistance(m, d, int(geoms_a[i]), int(geoms_b[j]), cap,
                                                  None))
    return float(least)


def in_zone(point, zone: tuple[float, float, float, float]) -> bool:
    """Whether (x, y, ...) [m] lies in the rectangle ``(x_low, x_high, y_low, y_high)``."""
    return zone[0] <= point[0] <= zone[1] and zone[2] <= point[1] <= zone[3]


def check_shared_path(m: mujoco.MjModel, scratch: mujoco.MjData, moving, other, rows: np.ndarray,
               other_goals: np.ndarray, zone, what: str) -> float:
    """Refuse a planned move that breaks the shared-workspace rule; the least distance [m].

    Args:
        m: the two-arm model.
        scratch: a data for the kinematics (the simulation's is left alone).
        moving: the moving arm (``scene_arm.SceneArm``).
        other: the other arm.
        rows: the moving arm's goals [rad], one row per physics step.
        other_goals: the other arm's goals [rad].
        zone: the board's area (:func:`in_zone`).
        what: the move, for the message ("left arm: carry x_1 to square 4").

    Raises:
        ClearanceError: one line: which rule, where along the path, the fix.
    """
    every = max(1, round(PATH_SAMPLE_S / m.opt.timestep))
    least = _SEARCH
    picks = list(range(0, len(rows), every)) + [len(rows) - 1]
    for k in picks:
        scratch.qpos[moving.qpos_addresses] = rows[k]
        scratch.qpos[other.qpos_addresses] = other_goals
        mujoco.mj_kinematics(m, scratch)
        at = f"{what}, {k * m.opt.timestep:.2f} s into the move"
        if (in_zone(scratch.site_xpos[moving.tool_site], zone)
                and in_zone(scratch.site_xpos[other.tool_site], zone)):
            raise ClearanceError(f"{at}: both arms would be in the board's area (one arm at a "
                                 f"time). Fix: move the {other.name} arm out of the board's "
                                 "area first (its park pose).")
        least = min(least, arm_distance(m, scratch, moving.geoms, other.geoms))
        if least < MIN_ARM_DISTANCE:
            raise ClearanceError(f"{at}: the arms would come {least * 1e3:.1f} mm apart (at "
                                 f"least {MIN_ARM_DISTANCE * 1e3:g} mm). Fix: park the "
                                 f"{other.name} arm first, or place the bases farther apart.")
    return least


class ArmDistanceWatch:
    """A viewer wrapper: at each ``sync()`` the arms' distance in the simulation.

    Args:
        m: the model.
        d: the data.
        arms: the two ``SceneArm``.
        inner: a viewer to forward to (a video recorder), or None.

    Attributes:
        collisions: how many times the arms came to touch.
        least_distance: [m] the least distance seen.
    """

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, arms, inner=None):
        self.m, self.d, self.arms, self.inner = m, d, arms, inner
        self.sync_every_step = inner is not None and getattr(inner, "sync_every_step", False)
        self.collisions = 0
        self.least_distance = _SEARCH
        self._touching = False
        self._calls = 0

    def is_running(self) -> bool:
        """The inner viewer's state (always true without one)."""
        return self.inner is None or self.inner.is_running()

    def sync(self) -> None:
        """Measure (every ``WATCH_EVERY`` calls when synced every step), count a touch, forward."""
        self._calls += 1
        if not self.sync_every_step or self._calls % WATCH_EVERY == 0:
            self._measure()
        if self.inner is not None:
            self.inner.sync()

    def _measure(self) -> None:
        """The arms' distance now; a new touch is a collision."""
        distance = arm_distance(self.m, self.d, self.arms[0].geoms, self.arms[1].geoms)
        self.least_distance = min(self.least_distance, distance)
        touching = distance <= 0.0
        if touching and not self._touching:
            self.collisions += 1
        self._touching = touching
