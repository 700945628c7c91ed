"""Which servo drives the simulated arm, and the physics step that applies it.

``d.ctrl`` stays what the course makes it: each joint's goal [rad]. How the arm
follows it depends on the model's servo (:func:`use_servo`):

- ``"sts3215"`` (the default of :func:`so101_kinematics.sim.scene.load_model`): the
  measured servo (``sim/sts3215.py``) at lerobot's registers, a supply and a variant.
  :func:`step` computes its torque each physics step and hands it to MuJoCo through
  the position actuators (gain 0, the torque as their bias), then puts the model's
  native actuators back, so a script's own ``mujoco.mj_step`` still drives the arm.
- ``"ideal"``: the upstream model's stiff position servo (``kp`` 998.22, ``kv`` 2.731,
  ``forcerange`` 3.35 N m; TheRobotStudio SO-ARM100 PR #141), kept for comparison.
- a model loaded by MuJoCo itself (the course's ``MjModel.from_xml_path``) gets the
  default at its first :func:`step` (the project's moves run what ``so101_utils`` runs on
  the arm); a script's own ``mujoco.mj_step`` drives the native actuators
  (``model/scene.xml``'s: the STS3215 linearised, see the comment there).
- a velocity model (``model/scene_with_velocity.xml``, the course's week 9: a position
  and a ``<joint>_vel`` velocity actuator per joint, 12 controls) keeps the course's
  own actuators: ``scene.load_model`` sets no servo on it (:func:`has_velocity_actuators`),
  and :func:`use_servo` refuses it, so the course's gains are what drives it.

A model with several arms (issue 38's two arms: joints ``left_shoulder_pan``, ...,
``right_gripper``, :func:`arm_prefixes`) gets one servo per joint of every arm, the
same registers on each, and each arm's own gravity feed-forward.
"""

from __future__ import annotations

import logging
import math
import weakref
from dataclasses import dataclass

import mujoco
import numpy as np

from so101_kinematics import gravity, servo
from so101_kinematics.errors import PlanError
from so101_kinematics.frames import JOINTS
from so101_kinematics.sim.sts3215 import ServoBank

__all__ = [
    "IDEAL_GAINS", "VELOCITY_SUFFIX", "arm_prefixes", "expected_sag", "forget",
    "has_velocity_actuators",
    "lerobot_settings", "servo_spec", "step", "use_servo", "velocity_actuators",
]

IDEAL_GAINS = (998.22, 2.731, 3.35, 0.60)
"""The upstream ideal servo: kp [N m/rad], kv [N m s/rad], force range [N m], joint damping
[N m s/rad]."""

DEFAULT_FEEDFORWARD = True
"""Goals are offset by the gravity feed-forward unless asked otherwise (``--no-gravity-ff``):
the real-arm path does the same by default, so the simulated arm is the arm you get."""

DEFAULT_VOLTS = servo.DEFAULT_SUPPLY_V
"""The simulator's supply by default [V]: the course's 12 V follower (``servo.DEFAULT_SUPPLY_V``),
with its C018 servos."""


@dataclass(frozen=True)
class ServoSpec:
    """A model's servo: mode, supply [V], variant, registers and the gravity feed-forward.

    ``settings`` holds one ``servo.Settings`` per joint; with ``feedforward`` each goal
    is offset by the sag ``so101_kinematics.gravity`` predicts there.
    """

    mode: str
    volts: float
    variant: str
    settings: tuple
    feedforward: bool = False

    def describe(self) -> str:
        """One line for a report: "STS3215 C001, P = 16, 5.0 V" or "ideal (kp 998)"."""
        if self.mode == "ideal":
            return f"ideal position servo (kp {IDEAL_GAINS[0]:g} N m/rad, upstream)"
        ff = "with" if self.feedforward else "without"
        return (f"STS3215 {self.variant}, P = {self.settings[0].p}, {self.volts:g} V, "
                f"{ff} gravity feed-forward")


logger = logging.getLogger(__name__)

_SPECS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # model -> ServoSpec
_BANKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # data -> (ServoBank, time)


def lerobot_settings(p: int | None = None, i: int = 0) -> tuple:
    """The registers lerobot writes, per joint (the gripper's torque cap), with P and I changed."""
    changes = {"i": int(i)} | ({} if p is None else {"p": int(p)})
    return tuple((servo.LEROBOT_GRIPPER if joint == "gripper" else servo.LEROBOT).with_(**changes)
                 for joint in JOINTS)


def use_servo(m: mujoco.MjModel, mode: str = "sts3215", volts: float = DEFAULT_VOLTS,
              variant: str | None = None, p: int | None = None,
              feedforward: bool = DEFAULT_FEEDFORWARD, i: int = 0) -> ServoSpec:
    """Choose the servo that drives ``m`` (see the module's docstring).

    Args:
        m: the model (its position actuators are adjusted in place).
        mode: one of ``servo.SIMULATED_SERVOS``.
        volts: the supply [V], in (0, 14].
        variant: a key of ``servo.VARIANTS`` (default: what ``volts`` implies).
        p: P_Coefficient (default lerobot's 16), 1-255.
        feedforward: offset each goal by the sag the servo will have there
            (``gravity.feedforward``), as the real-arm path does with ``--gravity-ff``.
        i: I_Coefficient (lerobot's 0), 0-255.

    Raises:
        PlanError: an unknown mode or variant, a voltage or P out of range.
    """
    if has_velocity_actuators(m):
        raise PlanError("a velocity model (position and <joint>_vel actuators) runs on the "
                        "course's own gains; the STS3215 model drives position actuators only. "
                        "Fix: load model/scene.xml for the servo model.")
    if mode not in servo.SIMULATED_SERVOS:
        raise PlanError(f"servo {mode!r} is not one of {', '.join(servo.SIMULATED_SERVOS)}. "
                        "Fix: use --servo sts3215 (the measured servo) or --servo ideal.")
    if not 0.0 < float(volts) <= 14.0:
        raise PlanError(f"supply {volts} V is outside (0, 14] V (the STS3215's rated range). "
                        "Fix: give the supply your servos run on, e.g. 5 or 7.4 or 12.")
    variant = variant or servo.default_variant(volts)
    if variant not in servo.VARIANTS:
        raise PlanError(f"servo variant {variant!r} is not one of "
                        f"{', '.join(servo.VARIANTS)}. Fix: use C001 (7.4 V) or C018 (12 V).")
    problem = servo.supply_problem(variant, float(volts))
    if problem:
        raise PlanError(problem)
    if p is not None and not 1 <= int(p) <= 255:
        raise PlanError(f"P coefficient {p} is outside [1, 255]. Fix: lerobot uses 16.")
    if not 0 <= int(i) <= 255:
        raise PlanError(f"I coefficient {i} is outside [0, 255]. Fix: lerobot uses 0.")
    spec = ServoSpec(mode, float(volts), variant, lerobot_settings(p, i), bool(feedforward))
    _SPECS[m] = spec
    acts = _actuators(m)
    dofs = [int(m.joint(p + j).dofadr[0]) for p in arm_prefixes(m) for j in JOINTS]
    if mode == "ideal":
        kp, kv, force, damping = IDEAL_GAINS
        m.actuator_gainprm[acts, 0] = kp
        m.actuator_biasprm[acts, 1] = -kp
        m.actuator_biasprm[acts, 2] = -kv
        m.actuator_forcerange[acts] = (-force, force)
        m.dof_damping[dofs] = damping
    else:
        bank = ServoBank(spec.settings * len(arm_prefixes(m)), spec.volts, variant)
        kp = np.array(bank.stiffness())
        chosen = servo.VARIANTS[variant]
        m.actuator_gainprm[acts, 0] = kp
        m.actuator_biasprm[acts, 1] = -kp
        m.actuator_biasprm[acts, 2] = 0.0
        limit = np.minimum(bank.torque_limit, servo.DUTY_MAX) / 1000.0
        force = chosen.torque_per_volt * spec.volts * limit
        m.actuator_forcerange[acts] = np.stack([-force, force], axis=1)
        m.dof_damping[dofs] = chosen.emf_damping + chosen.viscous
    _PLANTS.pop(m, None)
    return spec


VELOCITY_SUFFIX = "_vel"
"""A velocity actuator is its joint's name with this suffix (the course's ``shoulder_pan_vel``)."""


def _is_arm(m: mujoco.MjModel) -> bool:
    """Whether ``m`` has the SO-101's six position servos, named as their joints, and no more."""
    try:
        return m.nu == len(JOINTS) and all(m.actuator(j).trnid[0] == m.joint(j).id
                                           for j in JOINTS)
    except KeyError:
        return False


def has_velocity_actuators(m: mujoco.MjModel) -> bool:
    """Whether ``m`` has the course's ``<joint>_vel`` velocity actuator for every joint."""
    names = {m.actuator(i).name for i in range(m.nu)}
    return all(joint + VELOCITY_SUFFIX in names for joint in JOINTS)


def velocity_actuators(m: mujoco.MjModel, wanted: bool | None, joints) -> np.ndarray | None:
    """The ``<joint>_vel`` actuator ids of ``joints`` if velocities are to be fed, else None.

    Args:
        m: the model.
        wanted: True (feed them; a PlanError if the model has none), False, or None
            (feed them when the model has them).
        joints: the joints moving, in the order of the move's goals.
    """
    present = has_velocity_actuators(m)
    if wanted and not present:
        raise PlanError("velocity feed-forward needs the course's velocity actuators "
                        "(<joint>_vel); this model has position actuators only. Fix: load "
                        "model/scene_with_velocity.xml, or leave the velocity out.")
    if not present or wanted is False:
        return None
    return np.array([int(m.actuator(j + VELOCITY_SUFFIX).id) for j in joints])


def expected_sag(m: mujoco.MjModel, command) -> dict[str, float]:
    """How far [deg] each arm joint of ``m`` rests from ``command`` with no feed-forward on.

    The sag and the friction band the model's servo leaves (0 with the feed-forward, or an
    ideal servo): what a check comparing a measured start with a command must allow.
    """
    spec = _SPECS.get(m)
    if spec is None or spec.mode == "ideal" or spec.feedforward:
        return {}
    feedforward = gravity.Feedforward(dict(zip(JOINTS, spec.settings, strict=True)),
                                      spec.volts, spec.variant, enabled=False)
    return feedforward.expected_errors(command, {})


def servo_spec(m: mujoco.MjModel) -> ServoSpec | None:
    """The servo set on ``m`` by :func:`use_servo`, or ``None``."""
    return _SPECS.get(m)


_PLANTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def arm_prefixes(m: mujoco.MjModel) -> tuple[str, ...]:
    """The prefixes of the arms in ``m``: ``("",)`` for the course's one arm.

    Two arms attached with a prefix (each joint named prefix + joint) give e.g.
    ``("left_", "right_")``.

    Example:
        >>> import mujoco
        >>> xml = '<mujoco><worldbody><body><joint name="left_shoulder_pan"/><geom size="1"/>'
        >>> arm_prefixes(mujoco.MjModel.from_xml_string(xml + '</body></worldbody></mujoco>'))
        ('left_',)
    """
    first = JOINTS[0]
    names = [m.joint(i).name for i in range(m.njnt)]
    return tuple(name[:-len(first)] for name in names if name.endswith(first)) or ("",)


def _actuators(m: mujoco.MjModel) -> np.ndarray:
    return np.array([int(m.actuator(p + j).id) for p in arm_prefixes(m) for j in JOINTS])


def _index(values: list[int]):
    """A slice when ``values`` are consecutive (plain row copies: faster), else the list."""
    if values == list(range(values[0], values[0] + len(values))):
        return slice(values[0], values[0] + len(values))
    return np.array(values)


class _Plant:
    """Per-model indices (slices when consecutive) and the controls' ranges."""

    def __init__(self, m: mujoco.MjModel):
        prefixes = arm_prefixes(m)
        self.arms = len(prefixes)
        self.acts = _index([int(m.actuator(p + j).id) for p in prefixes for j in JOINTS])
        self.qadr = _index([int(m.joint(p + j).qposadr[0]) for p in prefixes for j in JOINTS])
        self.lower = m.actuator_ctrlrange[self.acts, 0].tolist()
        self.upper = m.actuator_ctrlrange[self.acts, 1].tolist()


FEEDFORWARD_REFRESH_DEG = 0.5
"""The feed-forward is re-evaluated when a goal moved this far [deg] (its gravity offsets
change by at most 0.15 deg per degree; a joint's direction is seen that late)."""


def forget(d: mujoco.MjData) -> None:
    """Drop the servos' state for ``d`` (the arm was placed: targets restart where it is)."""
    _BANKS.pop(d, None)


def bank_of(m: mujoco.MjModel, d: mujoco.MjData) -> ServoBank | None:
    """The servos stepping ``d`` (after a first :func:`step`), for readings like Present_Load."""
    entry = _BANKS.get(d)
    return None if entry is None else entry[0]


def step(m: mujoco.MjModel, d: mujoco.MjData, n: int = 1, commands=None,
         actuators=slice(None)) -> None:
    """``n`` physics steps with the model's servo (``mujoco.mj_step`` when it has none).

    Args:
        m: the model.
        d: the data.
        n: steps.
        commands: optional rows of goals [rad], one per step, written to
            ``d.ctrl[actuators]`` before it (a move's path, in one call).
        actuators: the controls ``commands`` sets.
    """
    spec = _SPECS.get(m)
    if spec is None and _is_arm(m):  # loaded by MuJoCo itself: the project's default servo
        spec = use_servo(m)
        logger.info("A model loaded without the project's load_model: its moves run the "
                    "default servo (%s), as so101_utils runs the arm.", spec.describe())
    if spec is None or spec.mode == "ideal":
        if commands is None:
            mujoco.mj_step(m, d, n)
            return
        for row in commands[:n]:
            d.ctrl[actuators] = row
            mujoco.mj_step(m, d)
        return
    plant = _PLANTS.get(m)
    if plant is None:
        plant = _PLANTS[m] = _Plant(m)
    entry = _BANKS.get(d)
    if entry is None or entry[1] != d.time:  # new, or stepped or reset by someone else
        entry = [ServoBank(spec.settings * plant.arms, spec.volts, spec.variant), d.time, None,
                 None, None]
        _BANKS[d] = entry
    bank, feedforward = entry[0], spec.feedforward
    acts, qadr, dt = plant.acts, plant.qadr, m.opt.timestep
    gains = m.actuator_gainprm[acts, 0].copy()
    bias = m.actuator_biasprm[acts, :3].copy()
    m.actuator_gainprm[acts, 0] = 0.0
    m.actuator_biasprm[acts, 1:3] = 0.0
    ctrl, qpos, bias_column = d.ctrl, d.qpos, m.actuator_biasprm[:, 0]
    lower, upper, torques, physics = plant.lower, plant.upper, bank.torques, mujoco.mj_step
    rows = iter(commands) if commands is not None else None
    try:
        for _ in range(n):
            if rows is not None:
                ctrl[actuators] = next(rows)
            goal = ctrl[acts].tolist()
            for k, (value, lo, hi) in enumerate(zip(goal, lower, upper, strict=True)):
                if not lo <= value <= hi:  # the servo clamps to its position limits
                    goal[k] = lo if value < lo else hi
            if feedforward:
                goal = _offset(entry, spec, goal)
            bias_column[acts] = torques(goal, qpos[qadr].tolist(), dt)
            physics(m, d)
    finally:
        m.actuator_gainprm[acts, 0] = gains
        m.actuator_biasprm[acts, :3] = bias
        entry[1] = d.time


def _offset(entry: list, spec: ServoSpec, goal: list[float]) -> list[float]:
    """``goal`` [rad] plus the gravity feed-forward (``gravity.Feedforward``, as on the arm).

    The offsets are re-evaluated when a goal moved ``FEEDFORWARD_REFRESH_DEG``; between,
    the last ones are added to the goal as it moves. ``goal`` holds six joints per arm;
    each arm has its own feed-forward, evaluated on its own six (so an arm beside another
    moves as it would alone).
    """
    size = len(JOINTS)
    if entry[2] is None:
        arms = len(goal) // size
        entry[2], entry[3], entry[4] = [None] * arms, [None] * arms, [None] * arms
    out = []
    for k, (at, deltas) in enumerate(zip(entry[2], entry[3], strict=True)):
        own = goal[k * size:(k + 1) * size]
        if at is None or max(abs(g - a) for g, a in zip(own, at, strict=True)) > _REFRESH_RAD:
            feedforward = entry[4][k]
            if feedforward is None:
                feedforward = entry[4][k] = gravity.Feedforward(
                    dict(zip(JOINTS, spec.settings, strict=True)), spec.volts, spec.variant)
            cfg = {j: math.degrees(g) for j, g in zip(JOINTS, own, strict=True)}
            cfg["gripper"] = 50.0  # the jaw's weight barely moves with the opening
            sent = feedforward.apply(cfg)
            deltas = entry[3][k] = [math.radians(sent[j] - cfg[j]) for j in JOINTS[:5]] + [0.0]
            entry[2][k] = own
        out += [g + o for g, o in zip(own, deltas, strict=True)]
    return out


_REFRESH_RAD = math.radians(FEEDFORWARD_REFRESH_DEG)
