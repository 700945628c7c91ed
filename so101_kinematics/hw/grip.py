"""Whether the jaws hold something, read from the servos: one rule for the stop and the put-down.

A gripper that stands still more than :data:`HELD_MARGIN_PCT` wider than its command is
pressing on something between its jaws. A gripper still closing in free air is moving, and
one closed on nothing stands at its command. The controlled stop (``hw/control.py``) keeps
such a gripper's command, so the squeeze goes on while the arm stops; the put-down
(``hw/putdown.py``) lays the held cube on the table before the return.
"""

from __future__ import annotations

__all__ = ["HELD_MARGIN_PCT", "held_grip"]

HELD_MARGIN_PCT = 3.0  # the jaws stopped this much wider than commanded hold something [%]
"""Also ``hw/teach.py``'s test of a grasp that closed on nothing; on the course's 26 mm cube
the virtual arm's gripper stops at 23.3 % against a command of 5 %."""
SETTLED_WINDOW_S = 0.1  # the jaws must have stood still this long ... [s]
SETTLED_PCT = 1.0  # ... within this much [%] (closing in free air they move 100 %/s)


def held_grip(session) -> tuple[float, float] | None:
    """(gripper command, gripper width) [%] if the jaws hold something, else None.

    Read from the session's last measured cycles (a controlled stop's own records are left
    out: they are not the run's cycles).
    """
    cycles = [c for c in session.cycles if c.measured is not None and c.step != "stop"]
    if not cycles:
        return None
    last = cycles[-1]
    command, width = last.command["gripper"], last.measured["gripper"]
    if width - command <= HELD_MARGIN_PCT:
        return None
    recent = [c.measured["gripper"] for c in cycles if c.t_s >= last.t_s - SETTLED_WINDOW_S]
    if max(recent) - min(recent) > SETTLED_PCT:
        return None  # still moving: closing in free air, or opening
    return command, width
