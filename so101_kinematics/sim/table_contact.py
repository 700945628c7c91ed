"""Where the arm presses on the table, and how hard: the contacts between its links and it.

A sagging arm (the servos without the gravity feed-forward) can lower its jaw onto
the table at a low pose: the table then carries part of the arm's weight (its sag is
less than in free air), and a move that drags the jaw over it is an impact, not the
profile's motion. :func:`arm_table_contacts` lists those contacts at the current
step; ``model/table.xml`` names the table top's geom ``table``.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = ["arm_table_contacts", "table_force_n"]

TABLE_GEOM = "table"  # model/table.xml


@dataclass(frozen=True)
class TableContact:
    """One of the arm's geoms on the table: which, and the normal force [N]."""

    body: str
    geom: str
    force_n: float


def arm_table_contacts(m: mujoco.MjModel, d: mujoco.MjData) -> list[TableContact]:
    """The arm's geoms pressing on the table now (normal force > 0), largest first.

    The arm: every body of the tree that holds ``shoulder_pan`` but its base (bolted
    to the table); a free body (the cube) is not the arm.
    """
    table = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, TABLE_GEOM)
    if table < 0 or d.ncon == 0:
        return []
    root = m.body_rootid[m.jnt_bodyid[m.joint("shoulder_pan").id]]
    force = np.zeros(6)
    found = []
    for i in range(d.ncon):
        contact = d.contact[i]
        if table not in (contact.geom1, contact.geom2):
            continue
        other = contact.geom2 if contact.geom1 == table else contact.geom1
        body = m.geom_bodyid[other]
        if body == root or m.body_rootid[body] != root:
            continue
        mujoco.mj_contactForce(m, d, i, force)
        if force[0] > 0.0:
            found.append(TableContact(m.body(body).name, m.geom(other).name, float(force[0])))
    return sorted(found, key=lambda c: -c.force_n)


def table_force_n(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """The arm's total normal force on the table now [N] (0: it does not touch)."""
    return sum(c.force_n for c in arm_table_contacts(m, d))
