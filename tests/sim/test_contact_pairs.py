"""Explicit contact pairs: the same contacts, with the parameters MuJoCo itself would mix."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import run_default_plan

import pick_place_sim
from pick_place_sim import CubeStart, run_pick_place
from so101_kinematics.sim.contact_pairs import (
    collidable_geom_pairs,
    mixed_contact_parameters,
    use_explicit_contact_pairs,
)

# A plane and two free boxes stacked on it, each with its own contact
# parameters. The plane and the lower box have equal priority (MuJoCo mixes
# their parameters); the upper box has a higher one (its own govern).
MIXING_SCENE = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1" friction="0.7 0.02 0.001"
          solref="0.03 0.8" solimp="0.8 0.9 0.002 0.4 3" solmix="3"/>
    <body name="low" pos="0 0 0.0495">
      <freejoint/>
      <geom name="low" type="box" size="0.05 0.05 0.05" condim="4" friction="0.4 0.03 0.0002"
            solref="0.01 1.2" solimp="0.9 0.95 0.001 0.5 2" solmix="1"/>
    </body>
    <body name="high" pos="0 0 0.149">
      <freejoint/>
      <geom name="high" type="box" size="0.04 0.04 0.05" condim="6" priority="2"
            friction="0.9 0.01 0.0003" solref="0.005 1" solimp="0.95 0.99 0.001 0.5 2"/>
    </body>
  </worldbody>
</mujoco>
"""


def contact_parameters_seen(m, d):
    """{(geom name, geom name): parameters} of the contacts in ``d``, as MuJoCo mixed them."""
    seen = {}
    for contact in d.contact[:d.ncon]:
        names = tuple(sorted((m.geom(contact.geom1).name, m.geom(contact.geom2).name)))
        seen[names] = dict(condim=int(contact.dim), friction=list(contact.friction),
                           solref=list(contact.solref), solimp=list(contact.solimp))
    return seen


def assert_matches_mujoco(m, d):
    seen = contact_parameters_seen(m, d)
    assert seen, "the scene has no contacts to compare"
    for (name_a, name_b), actual in seen.items():
        expected = mixed_contact_parameters(m, m.geom(name_a).id, m.geom(name_b).id)
        for key, value in expected.items():
            np.testing.assert_allclose(actual[key], value, rtol=1e-12,
                                       err_msg=f"{name_a}/{name_b}: {key}")


def test_mixed_parameters_are_the_ones_mujoco_uses_for_dynamic_contacts():
    m = mujoco.MjModel.from_xml_string(MIXING_SCENE)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert len(contact_parameters_seen(m, d)) == 2  # floor/low (mixed), low/high (priority)
    assert_matches_mujoco(m, d)


def test_mixed_parameters_match_every_contact_of_the_pick_and_place():
    m = pick_place_sim.build_model(cube=CubeStart(), physics_only=True, explicit_pairs=False)
    d = mujoco.MjData(m)
    pairs = set()

    def check_contacts():
        if d.ncon:
            assert_matches_mujoco(m, d)
            pairs.update(contact_parameters_seen(m, d))

    run_default_plan(m, d, check_contacts)
    assert pairs == {("cube", "fixed_jaw_pad"), ("cube", "moving_jaw_pad"), ("cube", "table")}


def test_pairs_are_the_geom_pairs_the_model_lets_touch():
    m = pick_place_sim.build_model(cube=CubeStart(), physics_only=True, explicit_pairs=False)
    pairs = {tuple(sorted((m.geom(a).name, m.geom(b).name))) for a, b in collidable_geom_pairs(m)}
    arm = [m.geom(g).name for g in range(m.ngeom) if m.geom(g).name not in ("table", "cube")]
    assert len(arm) == 13
    # Every arm geom meets the table and the cube; the cube meets the table;
    # arm geoms never meet each other.
    expected = {tuple(sorted((geom, other))) for geom in arm for other in ("table", "cube")}
    assert pairs == expected | {("cube", "table")}


def test_pick_and_place_is_bit_for_bit_the_same_with_dynamic_contacts(monkeypatch):
    explicit = run_pick_place()
    build_model = pick_place_sim.build_model
    monkeypatch.setattr(pick_place_sim, "build_model",
                        lambda *args, **kwargs: build_model(*args, **kwargs, explicit_pairs=False))
    dynamic = run_pick_place()
    assert dynamic.cube_final_position_m == explicit.cube_final_position_m
    assert dynamic.waypoint_errors_deg == explicit.waypoint_errors_deg
    assert dynamic.max_lift_m == explicit.max_lift_m


def test_explicit_pairs_replace_the_dynamic_filter():
    m = pick_place_sim.build_model(cube=CubeStart(), physics_only=True)
    assert m.npair == 27
    assert not np.any(m.geom_contype) and not np.any(m.geom_conaffinity)


def test_unnamed_colliding_geom_is_a_clear_error():
    spec = mujoco.MjSpec.from_string(MIXING_SCENE)
    spec.geom("high").name = ""
    with pytest.raises(ValueError, match=r"bodies: high\) can collide but have no name"):
        use_explicit_contact_pairs(spec)


def test_geom_with_a_margin_is_refused():
    spec = mujoco.MjSpec.from_string(MIXING_SCENE)
    spec.geom("low").margin = 0.001
    with pytest.raises(ValueError, match="Geoms low have a contact margin or gap"):
        use_explicit_contact_pairs(spec)


def test_scene_with_pairs_already_is_refused():
    spec = mujoco.MjSpec.from_string(MIXING_SCENE)
    use_explicit_contact_pairs(spec)
    with pytest.raises(ValueError, match="already has 3 contact pairs"):
        use_explicit_contact_pairs(spec)
