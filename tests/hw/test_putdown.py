"""hw/putdown.py's judgement, without an arm: what counts as a cube in the jaws, and the return
that cannot put it down keeps the jaws open around it (the end-to-end runs against the
virtual arm and its cube are tests/hw/test_stop_with_cube.py)."""

from __future__ import annotations

from so101_kinematics.constants import HOME_POSE
from so101_kinematics.hw.grip import held_grip
from so101_kinematics.hw.putdown import put_down
from so101_kinematics.hw.timing import Cycle

GRASP = dict(HOME_POSE, shoulder_lift=-60.0, elbow_flex=60.0)


class Session:
    """What put_down and held_grip read of an ArmSession: its cycles, segments and command."""

    def __init__(self, grippers, commands):
        self.cycles = [Cycle(0.01 * k, 0.01 * k, "lift", dict(GRASP, gripper=c),
                             dict(GRASP, gripper=g)) for k, (g, c) in
                       enumerate(zip(grippers, commands, strict=True))]
        self.segments = []  # no move closed the jaws: nothing tells where the table is
        self.command = dict(GRASP, gripper=grippers[-1])
        self.step = "lift"


def test_jaws_standing_wider_than_their_command_hold_something():
    # the virtual arm on the course's cube: stopped at 23.3 % against a command of 5 %
    assert held_grip(Session([23.3] * 20, [5.0] * 20)) == (5.0, 23.3)


def test_jaws_closed_on_nothing_or_still_closing_hold_nothing():
    assert held_grip(Session([5.4] * 20, [5.0] * 20)) is None  # at their command: empty
    closing = [50.0 - 2.0 * k for k in range(20)]  # 100 %/s in free air, trailing by 8 %
    assert held_grip(Session(closing, [c - 8.0 for c in closing])) is None
    opening = [10.0 + 2.0 * k for k in range(20)]
    assert held_grip(Session(opening, [c + 8.0 for c in opening])) is None


def test_a_cube_that_cannot_be_put_down_is_not_squeezed_by_the_return():
    """No grasp move to lower to: the return keeps the jaws as wide as the cube (23 %), never
    the start's 9 %; with nothing held it goes to the start as it is."""
    start = dict(HOME_POSE)
    session = Session([23.3] * 20, [5.0] * 20)
    target = put_down(session, None, held_grip(session), None, start)
    assert target == dict(start, gripper=23.3)
    empty = Session([5.4] * 20, [5.0] * 20)
    assert put_down(empty, None, held_grip(empty), None, start) == start
