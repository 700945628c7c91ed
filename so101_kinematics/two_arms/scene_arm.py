"""One arm of the two-arm model, with the course's helpers' call shapes.

``so101_mujoco_utils`` drives the course's one arm: ``move_to_pose(m, d, viewer, cfg,
duration)``, ``hold_position(m, d, viewer, duration)``, ``get_configuration(m, d)``,
``pick_up_block(m, d, viewer, block_position, move_to_duration)``. A :class:`SceneArm` has
the same methods with the same arguments, for the arm whose names carry its prefix
(``left_`` or ``right_``), so a course script's calls work on either arm::

    left, right = SceneArm(m, bases[0]), SceneArm(m, bases[1])
    left.move_to_pose(m, d, viewer, cfg, 2.0)   # the right arm holds its command

Positions are in the arm's own base frame, as for one arm; the joints in [deg], the gripper
in [0, 100], converted by ``sim/scene.py``'s one conversion (the one-arm model's ranges:
both arms are that arm). Only the moving arm's goals change; the other's servos keep
holding theirs, both stepped by the same servo model (``sim/actuation.py``).
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from so101_kinematics.frames import JOINTS, TOOL_SITE
from so101_kinematics.ik.blocks import pick_up_moves, place_moves
from so101_kinematics.inputs import Configuration, check_duration
from so101_kinematics.planning.motion import Trajectory
from so101_kinematics.sim import actuation, scene
from so101_kinematics.sim.cube import scene_model
from so101_kinematics.two_arms.two_arm_scene import ArmBase

__all__ = ["CHECK_EVERY", "SceneArm", "advance"]

CHECK_EVERY = 5
"""Physics steps between two calls of the viewer's ``sync()`` headless (20 ms at the 4 ms
step): where the run's monitor checks the arms' distance; a video syncs every step."""


def advance(m: mujoco.MjModel, d: mujoco.MjData, viewer, steps: int, rows=None,
            actuators=None) -> None:
    """Step both arms ``steps`` times, syncing ``viewer`` (None: headless) as it goes.

    Args:
        m: the two-arm model.
        d: its data.
        viewer: None or an object with ``sync()`` (a video recorder, the run's monitor).
        steps: physics steps.
        rows: optional goals [rad], one row per step, for ``actuators``.
        actuators: the controls ``rows`` sets (one arm's).
    """
    every = 1 if viewer is not None and getattr(viewer, "sync_every_step", False) else CHECK_EVERY
    done = 0
    while done < steps:
        n = min(every, steps - done)
        if rows is None:
            actuation.step(m, d, n)
        else:
            actuation.step(m, d, n, commands=rows[done:done + n], actuators=actuators)
        done += n
        if viewer is not None:
            viewer.sync()


class SceneArm:
    """One arm of a two-arm model, driven as the course drives its one arm.

    Args:
        m: the two-arm model (``two_arm_scene.build_two_arm_model``).
        base: this arm's base (its name gives the prefix).
    """

    def __init__(self, m: mujoco.MjModel, base: ArmBase):
        self.base, self.name, self.prefix = base, base.name, base.prefix
        self.actuators = np.array([m.actuator(self.prefix + j).id for j in JOINTS])
        self.qpos_addresses = np.array([m.joint(self.prefix + j).qposadr[0] for j in JOINTS])
        self.tool_site = m.site(self.prefix + TOOL_SITE).id
        bodies = {m.body(self.prefix + "base").id}
        for body in range(m.nbody):  # the base's subtree: this arm's bodies
            if m.body_parentid[body] in bodies:
                bodies.add(body)
        self.geoms = np.array([g for g in range(m.ngeom) if m.geom_bodyid[g] in bodies
                               and m.geom_contype[g] != 0])
        self._one_arm = scene_model()

    def _radians(self, cfg: Mapping[str, float], where: str) -> np.ndarray:
        """A full configuration ([deg], gripper [0, 100]) -> this arm's goals [rad]."""
        angles = scene.to_radians(self._one_arm, scene.held_at_limits(self._one_arm, cfg, where))
        return np.array([angles[j] for j in JOINTS])

    def get_configuration(self, m: mujoco.MjModel, d: mujoco.MjData) -> Configuration:
        """This arm's measured configuration ([deg], gripper [0, 100])."""
        angles = dict(zip(JOINTS, d.qpos[self.qpos_addresses].tolist(), strict=True))
        return scene.from_radians(self._one_arm, angles)

    def get_command(self, m: mujoco.MjModel, d: mujoco.MjData) -> Configuration:
        """This arm's commanded configuration ([deg], gripper [0, 100])."""
        angles = dict(zip(JOINTS, d.ctrl[self.actuators].tolist(), strict=True))
        return scene.from_radians(self._one_arm, angles)

    def set_initial_pose(self, d: mujoco.MjData, cfg: Mapping[str, float]) -> None:
        """Place this arm at ``cfg`` at rest and command it there (before the run starts)."""
        goals = self._radians(cfg, f"{self.name} set_initial_pose")
        d.qpos[self.qpos_addresses] = goals
        d.qvel[[d.model.jnt_dofadr[d.model.actuator_trnid[a, 0]] for a in self.actuators]] = 0.0
        d.ctrl[self.actuators] = goals
        actuation.forget(d)
        mujoco.mj_forward(d.model, d)

    def send_position_command(self, d: mujoco.MjData, cfg: Mapping[str, float]) -> None:
        """Command this arm's servos to the full configuration ``cfg``."""
        d.ctrl[self.actuators] = self._radians(cfg, f"{self.name} send_position_command")

    def path(self, m: mujoco.MjModel, d: mujoco.MjData, cfg: Mapping[str, float],
             duration: float) -> np.ndarray:
        """The goals [rad] of a move from the last command to ``cfg``: one row per step."""
        duration = check_duration(duration, f"{self.name} move_to_pose duration")
        start, goal = d.ctrl[self.actuators].copy(), self._radians(cfg, f"{self.name} target")
        steps = max(1, round(duration / m.opt.timestep))
        trajectory = Trajectory({"s": 0.0}, {"s": 1.0}, steps * m.opt.timestep)
        fractions = trajectory.fractions(np.arange(1, steps + 1) * m.opt.timestep)
        return start + fractions[:, None] * (goal - start)

    def move_to_pose(self, m: mujoco.MjModel, d: mujoco.MjData, viewer,
                     cfg: Mapping[str, float], duration: float) -> None:
        """Move this arm from its last command to ``cfg`` in ``duration`` [s] (minimum jerk)."""
        rows = self.path(m, d, cfg, duration)
        advance(m, d, viewer, len(rows), rows, self.actuators)

    def hold_position(self, m: mujoco.MjModel, d: mujoco.MjData, viewer,
                      duration: float) -> None:
        """Keep every command for ``duration`` [s] (both arms hold)."""
        duration = check_duration(duration, f"{self.name} hold_position duration")
        advance(m, d, viewer, round(duration / m.opt.timestep))

    def pick_up_block(self, m: mujoco.MjModel, d: mujoco.MjData, viewer, block_position,
                      move_to_duration: float) -> None:
        """Assignment 8's pick (``ik/blocks.py``), ``block_position`` in this arm's base frame."""
        for cfg, duration in pick_up_moves(block_position, move_to_duration):
            self.move_to_pose(m, d, viewer, cfg, duration)

    def place_block(self, m: mujoco.MjModel, d: mujoco.MjData, viewer, target_position,
                    move_to_duration: float) -> None:
        """Assignment 8's place (``ik/blocks.py``), ``target_position`` in this arm's base frame."""
        for cfg, duration in place_moves(target_position, move_to_duration):
            self.move_to_pose(m, d, viewer, cfg, duration)
