"""A controlled stop with a cube in the jaws: put it down, open the jaws, then return.

Without this, a stop after the grasp carried the cube back to the folded rest,
and the return sent the gripper to its starting opening (9 % on the virtual
arm), narrower than the cube (the jaws stop at about 23 %): the gripper
squeezed it until the servo reported overload, the torque was released there,
and the cube ended jammed in the limp jaws, tilted 42 deg (issue 33).

The fault policy (docs/hardware_safety.md), for a stop whose ending is the
slow return (Ctrl-C, SIGTERM, SIGHUP, a fault the arm recovers from):

1. Whether the jaws hold something is read from the servos, as on a real arm
   (``hw/grip.py``'s :func:`held_grip`: the gripper still, more than
   ``HELD_MARGIN_PCT`` wider than its command); the controlled stop keeps such a
   gripper's command, so the squeeze goes on while the arm stops.
2. Held, the cube is put down at the slow return speed: after a stop signal
   at the plan's own place (the plan's holding waypoints up to the one where
   it opens the jaws), when every move there is inside the limits and clear
   of the table; otherwise (after a fault, or the place refused) straight
   down where it is: the grasp's pose (the goal of the last move that closed
   the jaws, the plan's or a course script's ``move_to_pose``: where the cube
   stood on the table, so the clearance rules hold there) turned to the arm's
   present pan and roll.
   The jaws never close further than the grasp's command while holding.
3. The jaws open as wide as they were before they closed on the cube (at the
   place: the plan's opening there), the arm rises back along the
   way it came down, and only then does the slow return to the start begin.
4. If no put-down is possible (no move closed the jaws, every route refused), the return
   keeps the jaws at least as wide as the cube they hold: never the start's
   narrower opening.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

from so101_kinematics.clearance import check_path
from so101_kinematics.errors import PlanError, StopRequested
from so101_kinematics.hw.control import RETURN_MIN_DURATION_S, RETURN_SPEED_DEG_S
from so101_kinematics.hw.grip import HELD_MARGIN_PCT
from so101_kinematics.hw.timing import MAX_GRIPPER_SPEED_PCT_S, speed_caps
from so101_kinematics.inputs import Configuration, check_configuration
from so101_kinematics.planning.motion import Plan

__all__ = ["put_down"]

logger = logging.getLogger("pick_place_hw")

def put_down(session, plan: Plan | None, held: tuple[float, float] | None,
             error: BaseException | None, start: Mapping[str, float]) -> Configuration:
    """Put a held cube down and open the jaws; returns the pose the return must go to.

    Args:
        session: the stopped session (``ArmSession``; its command is the stop pose).
        plan: the plan that was running, or None (a course script: straight down only).
        held: :func:`held_grip` before the stop, or None (nothing held: nothing done).
        error: why the run stopped (None: the script's end): a stop signal puts the cube
            at the plan's place, anything else straight down where it is.
        start: the starting pose.

    Returns:
        ``start``, or ``start`` with the gripper kept as wide as the held cube
        when the cube could not be put down.

    Raises:
        As ``ArmSession.move`` during a put-down move (the caller holds there).
    """
    target = dict(start)
    if held is None:
        return target
    command, width = held
    steps = plan.steps if plan is not None else []
    index = next((k for k, s in enumerate(steps) if s.name == session.step), None)
    stopped = isinstance(error, (KeyboardInterrupt, StopRequested))
    routes = [_at_the_place(session, steps, index, command)] if stopped and index is not None \
        else []
    routes.append(_straight_down(session, command))
    for route in filter(None, routes):
        lower, opened, above, where = route
        try:
            _check(session, [session.command, *lower, opened, above])
        except PlanError as refused:  # nothing moved: the next route
            logger.warning("Cannot put the cube down %s: %s", where, refused)
            continue
        logger.warning("The jaws hold something (gripper at %.1f %%, commanded %.1f %%): "
                       "putting it down %s and opening the jaws before the return.",
                       width, command, where)
        slow = speed_caps(RETURN_SPEED_DEG_S, RETURN_SPEED_DEG_S)  # the return's "slowly"
        session.move(dict(session.command, gripper=command), 0.1, step="put_down_grip",
                     max_speed=dict(slow, gripper=MAX_GRIPPER_SPEED_PCT_S))
        for pose in lower:
            session.move(pose, RETURN_MIN_DURATION_S, step="put_down", max_speed=slow)
        session.move(opened, RETURN_MIN_DURATION_S, step="put_down_open", max_speed=slow)
        session.move(above, RETURN_MIN_DURATION_S, step="put_down_rise", max_speed=slow)
        return target
    logger.warning("The jaws hold something and it cannot be put down: the return keeps them "
                   "at %.1f %% (the start's %.1f %% would squeeze it).", width, start["gripper"])
    target["gripper"] = max(start["gripper"], width)
    return target


def _check(session, poses) -> None:
    """PlanError if a pose is outside the calibrated range or a move goes into the table."""
    for pose in poses[1:]:
        check_configuration(pose, session.limits, "put-down pose (calibrated range)")
    check_path(poses, ["put_down"] * (len(poses) - 1), base_height=session.base_height,
               rest=session.rest_pose)


def _closes(steps, k: int, command: float) -> bool:
    return steps[k].configuration["gripper"] <= command + HELD_MARGIN_PCT


def _at_the_place(session, steps, index: int, command: float):
    """The plan's holding waypoints from here to where it opens the jaws, or None."""
    opening = next((k for k in range(index, len(steps)) if not _closes(steps, k, command)), None)
    if opening is None or opening == 0:
        return None
    pose = session.command
    lower = [dict(steps[k].configuration, gripper=command) for k in range(index, opening)]
    release = lower[-1] if lower else dict(pose)
    opened = dict(release, gripper=steps[opening].configuration["gripper"])
    grasp = next((k for k in range(min(index, len(steps) - 1), 0, -1)
                  if _closes(steps, k, command) and not _closes(steps, k - 1, command)), None)
    came_down_from = opening - 2  # the waypoint the plan lowered the cube from
    above = steps[came_down_from].configuration if grasp is not None and \
        came_down_from > grasp else pose
    return lower, opened, dict(above, gripper=opened["gripper"]), \
        f"at the plan's place ('{steps[opening].name}')"


def _straight_down(session, command: float):
    """The grasp's pose turned to the present pan and roll: the cube back on the table.

    The grasp is the last move that closed the jaws (from open to at most ``command`` + the
    margin): its goal is where the cube stood on the table; it opened from its start's gripper.
    """
    def closed(value: float) -> bool:
        return value <= command + HELD_MARGIN_PCT

    grasp = next((s for s in reversed(session.segments) if s.kind == "move"
                  and closed(s.goal["gripper"]) and not closed(s.start["gripper"])), None)
    if grasp is None:
        return None
    pose = session.command
    release = dict(grasp.goal, shoulder_pan=pose["shoulder_pan"], wrist_roll=pose["wrist_roll"],
                   gripper=command)
    opened = dict(release, gripper=grasp.start["gripper"])
    return [release], opened, dict(pose, gripper=opened["gripper"]), "straight down where it is"
