"""The simulated SO-101 behind ``interfaces.Arm``, and its cube behind ``interfaces.Sensor``.

:class:`SimArm` is the course's MuJoCo pair, ``m`` (the model) and ``d`` (the
data), as one object: its ``model`` and ``data`` are what ``so101_mujoco_utils``'s
helpers take (``move_to_pose(arm.model, arm.data, viewer, cfg, 2.0)``), and the
:class:`~so101_kinematics.interfaces.Arm` operations are the scene's own
(``scene.get_configuration``, ``scene.send_position_command``, the servo's
``actuation.step``). Two ``SimArm`` share nothing: each loads its own model and
data, and the servos' state is kept per model and per data
(``actuation.py``), so moving one leaves the other where it is (the two-arm
programs of issue 38; a scene with two arms in one model is issue 38's).

:class:`SimCubeSensor` reads a cube of the scene (``sim/cube.py``) as the
virtual lab's sensor reports it on the bus: the same
:class:`~so101_kinematics.sensors.cube_wire.CubeReading`, exact (not rounded
to the wire's 0.1 mm).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import mujoco

from so101_kinematics.frames import JOINTS
from so101_kinematics.inputs import check_number
from so101_kinematics.paths import SCENE_PATH
from so101_kinematics.sensors.cube_wire import CubeReading
from so101_kinematics.sim import actuation
from so101_kinematics.sim.cube import cube_name, cube_names, cube_state
from so101_kinematics.sim.scene import (
    get_configuration,
    load_model,
    send_position_command,
    set_initial_pose,
)

__all__ = ["SimArm", "SimCubeSensor"]

MAX_ADVANCE_S = 3600.0
"""The longest :meth:`SimArm.advance` in one call [s] (the course's longest hold, an hour)."""


class SimArm:
    """An SO-101 in MuJoCo (``interfaces.Arm``): the course's ``m, d`` with the arm's operations.

    Args:
        model: a loaded scene (default: :func:`~so101_kinematics.sim.scene.load_model` of
            ``path``, with the project's servo model).
        data: its data (default: a new ``mujoco.MjData(model)``).
        name: the arm's name.
        path: the scene to load when no ``model`` is given.
        pose: place the arm here at rest first ([deg], gripper [0, 100]; default: as loaded).
    """

    def __init__(self, model: mujoco.MjModel | None = None, data: mujoco.MjData | None = None,
                 *, name: str = "sim", path: str | Path = SCENE_PATH,
                 pose: Mapping[str, float] | None = None):
        self.model = model if model is not None else load_model(path)
        self.data = data if data is not None else mujoco.MjData(self.model)
        self.name = name
        if pose is not None:
            set_initial_pose(self.data, pose)
        else:
            mujoco.mj_forward(self.model, self.data)

    def read_positions(self) -> dict[str, float]:
        """The joints' positions now (``d.qpos``) [deg], gripper [0, 100]."""
        return get_configuration(self.model, self.data)

    def send_goal(self, goal: Mapping[str, float]) -> None:
        """The servos' goals (``d.ctrl``); a joint left out keeps its goal; refused off limits."""
        send_position_command(self.data, goal)

    def torque_enabled(self) -> dict[str, bool]:
        """Every joint holds: the simulated servos have no torque switch."""
        return dict.fromkeys(JOINTS, True)

    def advance(self, seconds: float) -> None:
        """Step the physics (the servo model) for ``seconds`` of simulated time, in whole steps."""
        seconds = check_number(seconds, f"{self.name}: advance", 0.0, MAX_ADVANCE_S, "s")
        steps = round(seconds / self.model.opt.timestep)
        if steps:
            actuation.step(self.model, self.data, steps)

    def close(self) -> None:
        """Forget the servos' state for this data (nothing else is held)."""
        actuation.forget(self.data)

    def cube_sensors(self) -> dict[str, SimCubeSensor]:
        """A sensor for every cube of the scene, by name (``{}`` when it has none)."""
        return {name: SimCubeSensor(self, index)
                for index, name in enumerate(cube_names(self.model))}

    def __repr__(self) -> str:
        return f"SimArm({self.name!r}, t={self.data.time:.3f} s)"


class SimCubeSensor:
    """Cube ``index`` of a :class:`SimArm`'s scene as the lab's sensor reads it (``Sensor``).

    Args:
        arm: the simulated arm whose scene holds the cube.
        index: which cube (0: ``"cube"``, 1: ``"cube_2"``, ...).
    """

    def __init__(self, arm: SimArm, index: int = 0):
        self._arm = arm
        self.index = index
        self.name = cube_name(index)

    def read(self) -> CubeReading | None:
        """The cube now: centre [m], tilt [deg], held; None if the scene has no such cube."""
        m, d = self._arm.model, self._arm.data
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, self.name) < 0:
            return None
        centre, tilt, held = cube_state(m, d, self.name)
        return CubeReading(tuple(float(v) for v in centre), float(tilt), bool(held))

    def close(self) -> None:
        """Nothing to let go: the scene belongs to the arm."""
