"""Where Feetech's sources disagree: the virtual STS3215's pick, and the other one as a switch.

``VirtualSO101(rules={...})`` takes any of these keys; the default is the first value of each
(``docs/virtual_arm_protocol.md``, "Where the sources disagree", has the sources):

- ``goal_time``: ``"ignored"`` (STS: Goal_Time, address 44, is the PWM mode's duty and does
  not time a position move) or ``"move_time"`` (SCS series: a goal moves in Goal_Time ms,
  its speed the distance over that time).
- ``limp_goal``: ``"follows"`` (with torque off Goal_Position follows Present_Position, so
  torque on holds where the joint is) or ``"kept"`` (a goal written with torque off is
  kept, and the joint moves there when torque comes on).
- ``locked_eeprom``: ``"acts"`` (with Lock = 1 an EEPROM write acts until the next power
  cycle, then reverts) or ``"refused"`` (with Lock = 1 EEPROM writes are ignored).
- ``restart_reply``: ``"none"`` (RESTART, 0x08, is never answered) or ``"status"`` (answered
  with a status packet, built before the servo restarts).

Example::

    >>> check_rules({"goal_time": "move_time"})["limp_goal"]
    'follows'
"""

from __future__ import annotations

from collections.abc import Mapping

from so101_kinematics.errors import InputError

__all__ = ["check_rules"]

RULES = {
    "goal_time": ("ignored", "move_time"),
    "limp_goal": ("follows", "kept"),
    "locked_eeprom": ("acts", "refused"),
    "restart_reply": ("none", "status"),
}
"""Rule -> its choices, the default first."""


def check_rules(rules: Mapping[str, str] | None) -> dict[str, str]:
    """Every rule's choice: the defaults, with ``rules`` on top.

    Raises:
        InputError: naming the rule, the value and the choices.
    """
    chosen = {name: choices[0] for name, choices in RULES.items()}
    for name, value in (rules or {}).items():
        if name not in RULES:
            raise InputError(f"Virtual arm rule '{name}': unknown; use one of {sorted(RULES)}.")
        if value not in RULES[name]:
            raise InputError(f"Virtual arm rule {name} = {value!r}: use one of "
                             f"{list(RULES[name])}.")
        chosen[name] = value
    return chosen
