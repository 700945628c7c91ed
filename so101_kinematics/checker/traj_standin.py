"""The ``mujoco`` stand-in's model and data: MuJoCo's shapes, dtypes and named access.

Loaded by ``traj_probe.py`` (in the checker's child process: the standard library and numpy
only) before a student's module is imported. What a course utils reads of ``m`` and ``d``
reads as in MuJoCo: ``m.joint("elbow_flex").qposadr`` is an ``int32`` array of one (its
``id`` an int), ``m.jnt_qposadr`` an array of six, ``d.qpos``/``d.ctrl`` ``float64`` arrays,
an unknown name a ``KeyError`` and an index out of range an ``IndexError`` with MuJoCo's
words, ``mj_name2id`` -1 for a name it does not have. So this project's own
``so101_mujoco_utils`` (and a student's file calling it) runs on the stand-in.
"""

from __future__ import annotations

import math
import types

import numpy as np

__all__ = ["OBJ", "StandInData", "StandInModel", "mj_name2id"]

JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
"""The course's joint order in ``qpos`` and ``ctrl`` (its ``convert_to_list``)."""

SETTINGS = {"timestep": 0.004, "ranges": {joint: (-math.pi, math.pi) for joint in JOINTS}}
"""Updated from the request by ``traj_probe.py``: the timestep [s] and the joint ranges [rad]."""

OBJ = {"body": 1, "joint": 3, "dof": 4, "geom": 5, "site": 6, "actuator": 19}
"""MuJoCo's ``mjtObj`` numbers of the kinds the stand-in names (``mujoco.mjtObj.mjOBJ_JOINT``)."""


class _View:
    """One joint or actuator as MuJoCo's named access gives it (``m.joint("elbow_flex")``).

    ``id`` an int, ``name`` a str, and every other field an array (a view into the model's,
    so ``m.joint("elbow_flex").qposadr[0]`` and ``m.actuator(2).ctrlrange[1]`` read as in
    MuJoCo, and writes land).
    """

    def __init__(self, index: int, name: str, fields: dict):
        self.id, self.name = index, name
        for key, array in fields.items():
            setattr(self, key, array[index:index + 1] if array.ndim == 1 else array[index])


def _lookup(names: list[str], key, count: int | None = None) -> int:
    """The index of ``key`` (a name, or an index below ``count``), failing as MuJoCo does."""
    if isinstance(key, str):
        if key not in names:
            raise KeyError(f"Invalid name '{key}'. Valid names: {sorted(names)}")
        return names.index(key)
    index, count = int(key), len(names) if count is None else count
    if not 0 <= index < count:
        raise IndexError(f"Invalid index {index}. Valid indices from 0 to {count - 1}")
    return index


class StandInModel:
    """``m``: the timestep, the six hinge joints and their position actuators.

    MuJoCo's shapes and dtypes: addresses ``int32`` arrays, parameters ``float64`` ``(n, 10)``.

    The joint ranges are the request's: the arm's those of ``model/so101.xml``, the gripper's
    ``[0, pi]`` rad, so a utils that maps the gripper linearly over its range (this
    project's) commands what the course's ``value * pi / 100`` does. The ``<joint>_vel``
    actuators of the course's velocity scene are named too (``m.actuator("elbow_flex_vel")``)
    but not counted in ``nu``; ``d.ctrl`` grows to 12 when a student writes 12 values.
    """

    def __init__(self, timestep: float):
        n = len(JOINTS)
        self.opt = types.SimpleNamespace(timestep=timestep)
        self.nq = self.nv = self.njnt = self.nu = n
        self.nbody, self.nkey, self.nsite, self.ngeom = n + 1, 0, 0, 0
        self.jnt_qposadr = np.arange(n, dtype=np.int32)
        self.jnt_dofadr = np.arange(n, dtype=np.int32)
        self.jnt_type = np.full(n, 3, dtype=np.int32)  # mjJNT_HINGE
        self.jnt_range = np.array([SETTINGS["ranges"][j] for j in JOINTS], dtype=float)
        self.jnt_limited = np.ones(n, dtype=np.uint8)
        self.dof_damping = np.zeros(n)
        self.actuator_names = list(JOINTS) + [f"{joint}_vel" for joint in JOINTS]
        actuators = len(self.actuator_names)
        self._actuator = {  # all 12; the model's arrays are the first nu rows (views)
            "trnid": np.array([[i % n, -1] for i in range(actuators)], dtype=np.int32),
            # position: the joint's range; velocity: model/scene_with_velocity.xml's [rad/s]
            "ctrlrange": np.vstack([self.jnt_range, np.tile([-200.0, 200.0], (n, 1))]),
            "ctrllimited": np.ones(actuators, dtype=np.uint8),
            "forcerange": np.zeros((actuators, 2)), "gainprm": np.zeros((actuators, 10)),
            "biasprm": np.zeros((actuators, 10))}
        self._actuator["gainprm"][:, 0] = 1.0  # a unit position servo (ideal: mj_step
        self._actuator["biasprm"][:n, 1] = -1.0  # puts each joint where it is commanded)
        for key, array in self._actuator.items():
            setattr(self, f"actuator_{key}", array[:n])

    def joint(self, key):
        """``m.joint("elbow_flex")`` or ``m.joint(2)``: id, name, qposadr, dofadr, range, type."""
        index = _lookup(list(JOINTS), key)
        return _View(index, JOINTS[index], {
            "qposadr": self.jnt_qposadr, "dofadr": self.jnt_dofadr, "range": self.jnt_range,
            "type": self.jnt_type, "limited": self.jnt_limited})

    def actuator(self, key):
        """``m.actuator("elbow_flex")`` (or ``"elbow_flex_vel"``, or an index)."""
        index = _lookup(self.actuator_names, key, self.nu)
        return _View(index, self.actuator_names[index], self._actuator)

    @classmethod
    def from_xml_path(cls, path: str) -> StandInModel:
        """Any scene: the stand-in (its timestep from the request)."""
        return cls(SETTINGS["timestep"])


class StandInData:
    """``d``: ``qpos``, ``qvel`` (float64, one per joint), ``ctrl``, ``time``, ``model``.

    ``ctrl`` has 6 controls, or 12 with velocities; ``d.joint(...)``/``d.actuator(...)`` are
    views as MuJoCo's.
    """

    def __init__(self, model: StandInModel | None = None):
        self.model = model or StandInModel(SETTINGS["timestep"])
        self.qpos = np.zeros(self.model.nq)
        self.qvel = np.zeros(self.model.nv)
        self.qacc = np.zeros(self.model.nv)
        self.qfrc_applied = np.zeros(self.model.nv)
        self._ctrl = np.zeros(self.model.nu)
        self.time = 0.0

    @property
    def ctrl(self):
        """The controls (writes into the array land, as in MuJoCo)."""
        return self._ctrl

    @ctrl.setter
    def ctrl(self, value):
        array = np.asarray(value, dtype=float).ravel()
        if array.size == 2 * len(JOINTS) and self._ctrl.size == len(JOINTS):
            self._ctrl = np.zeros(array.size)  # the velocity scene's 12 controls
        if array.size != self._ctrl.size:
            raise ValueError(f"could not broadcast input array from shape ({array.size},) into "
                             f"shape ({self._ctrl.size},)")
        self._ctrl[:] = array

    def joint(self, key):
        """``d.joint("elbow_flex")``: id, name, and ``qpos``/``qvel`` views."""
        index = _lookup(list(JOINTS), key)
        view = _View(index, JOINTS[index], {"qpos": self.qpos, "qvel": self.qvel,
                                            "qacc": self.qacc})
        return view

    def actuator(self, key):
        """``d.actuator("elbow_flex")``: id, name, and a ``ctrl`` view."""
        index = _lookup(self.model.actuator_names, key)
        if index >= self._ctrl.size:
            raise IndexError(f"Invalid index {index}. Valid indices from 0 to "
                             f"{self._ctrl.size - 1}")
        return _View(index, self.model.actuator_names[index], {"ctrl": self._ctrl})


class Constants(types.SimpleNamespace):
    """An enum namespace (``mujoco.mjtGeom``): the names given, any other name 0."""

    def __getattr__(self, name):  # mujoco.mjtGeom.mjGEOM_CYLINDER and the like: any integer
        return 0


def mj_name2id(m, kind, name) -> int:
    """A joint's or an actuator's index by name, -1 when there is none (as MuJoCo)."""
    names = list(JOINTS) if int(kind) == OBJ["joint"] else m.actuator_names[:m.nu] \
        if int(kind) == OBJ["actuator"] else []
    return names.index(name) if name in names else -1


def mj_id2name(m, kind, index):
    """A joint's or an actuator's name by index, None when there is none (as MuJoCo)."""
    names = list(JOINTS) if int(kind) == OBJ["joint"] else m.actuator_names[:m.nu] \
        if int(kind) == OBJ["actuator"] else []
    return names[index] if 0 <= index < len(names) else None
