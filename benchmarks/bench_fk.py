"""Benchmark group "fk": FK per call and in batch, beside MuJoCo's own kinematics."""

from __future__ import annotations

import time

import numpy as np

from benchmarks.common import SEED, TEST_CONFIGURATION, per_call_us, summarize


# -- The assignment's style of FK, kept here only as a baseline. ---------------
def _rot(axis: str, thetadeg: float) -> np.ndarray:
    t = np.deg2rad(thetadeg)
    c, s = np.cos(t), np.sin(t)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _seed_style_forward_kinematics(cfg: dict) -> tuple[np.ndarray, np.ndarray]:
    """FK written as the course's starter code does: np.block per factor, every call."""
    from so101_kinematics.frames import FIXED_TRANSFORMS

    def factor(name, theta):
        displacement, rotations = FIXED_TRANSFORMS[name]
        rotation = np.eye(3)
        for axis, angle in rotations:
            rotation = rotation @ _rot(axis, angle)
        rotation = rotation @ _rot("z", theta)
        return np.block([[rotation, np.array(displacement).reshape(3, 1)], [0, 0, 0, 1]])

    g = (factor("w1", cfg["shoulder_pan"]) @ factor("12", cfg["shoulder_lift"])
         @ factor("23", cfg["elbow_flex"]) @ factor("34", cfg["wrist_flex"])
         @ factor("45", cfg["wrist_roll"]))
    displacement, rotations = FIXED_TRANSFORMS["5t"]
    rotation = np.eye(3)
    for axis, angle in rotations:
        rotation = rotation @ _rot(axis, angle)
    g = g @ np.block([[rotation, np.array(displacement).reshape(3, 1)], [0, 0, 0, 1]])
    return g[0:3, 3], g[0:3, 0:3]


def bench_fk(quick: bool) -> dict:
    """FK per call (seed style, the course's product, the closed form, MuJoCo) and in batch."""
    import mujoco

    import so101_forward_kinematics as fk
    import so101_mujoco_utils as utils
    from so101_kinematics.fast_fk import forward_kinematics

    calls, repeats = (2000, 5) if quick else (20000, 9)
    m = utils.load_model()
    d = mujoco.MjData(m)
    addresses = [int(m.joint(name).qposadr[0]) for name in fk.ARM_JOINTS]
    site = m.site(fk.TOOL_SITE).id
    q = np.radians([TEST_CONFIGURATION[name] for name in fk.ARM_JOINTS])

    def mujoco_fk():
        d.qpos[addresses] = q
        mujoco.mj_kinematics(m, d)
        return d.site_xpos[site].copy(), d.site_xmat[site].reshape(3, 3).copy()

    seed = per_call_us(lambda: _seed_style_forward_kinematics(TEST_CONFIGURATION), calls // 4,
                       repeats)
    product = per_call_us(lambda: fk.get_forward_kinematics(TEST_CONFIGURATION), calls // 4,
                          repeats)
    single = per_call_us(lambda: forward_kinematics(TEST_CONFIGURATION), calls, repeats)
    reference = per_call_us(mujoco_fk, calls, repeats)

    n = 100_000 if quick else 1_000_000
    rng = np.random.default_rng(SEED)
    lower = np.degrees([m.joint(name).range[0] for name in fk.ARM_JOINTS])
    upper = np.degrees([m.joint(name).range[1] for name in fk.ARM_JOINTS])
    angles = rng.uniform(lower, upper, size=(n, len(fk.ARM_JOINTS)))
    batch = []
    for _ in range(3 if quick else 5):
        start = time.perf_counter()
        fk.get_forward_kinematics_batch(angles)
        batch.append((time.perf_counter() - start) / n * 1e9)
    out = {
        "fk_seed_style_us": summarize(seed),
        "fk_product_us": summarize(product),
        "fk_single_us": summarize(single),
        "mujoco_kinematics_us": summarize(reference),
        "fk_batch_ns_per_config": summarize(batch),
    }
    out["fk_single_vs_mujoco"] = (out["fk_single_us"]["median"]
                                  / out["mujoco_kinematics_us"]["median"])
    out["fk_batch_speedup_vs_mujoco_loop"] = (
        out["mujoco_kinematics_us"]["median"] * 1e3 / out["fk_batch_ns_per_config"]["median"])
    out["fk_batch_configs"] = n
    return out
