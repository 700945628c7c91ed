"""The torch's switch on an arm with no output: the gripper presses its button, led in time.

The SO-101 has no output of its own to switch a light. A torch with a momentary push button
is tied to the gripper's fixed jaw, its button facing the moving jaw: closing the gripper
past the button's click lights it, opening lets it go (``docs/final_project_drawing.md`` has
the mount). The jaw reaches the click some time after its goal starts to move (the goal's
ramp at the gripper's speed cap, then the servo's lag), so each press and each release
starts that lag (``lead_on_s``, ``lead_off_s``) before the plan wants the light on or off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from so101_kinematics.errors import PlanError

__all__ = ["SWITCH_LEAD_S", "TorchSwitch", "gripper_goals", "switch_times"]

SWITCH_LEAD_S = (0.14, 0.11)
"""The time [s] from the gripper's goal starting to move to its jaw at the click, to press and
to release, measured on the virtual arm (the STS3215 C018 on 12 V, lerobot's P = 16, the
default button): the JSON's ``light.switch`` of a run with ``--switch-lead-s 0 0``. A press
moves the jaw 6 % to the click, a release 4 %: each a ramp at the gripper's speed cap
(100 %/s), then the servo's lag. A real arm's own is measured the same way."""


@dataclass(frozen=True)
class TorchSwitch:
    """The torch's button under the moving jaw, in the gripper's units [%] (0 closed).

    Attributes:
        released: the jaw clear of the button (the light off).
        click: where the button switches (read by hand with ``read_position.py``).
        pressed: the button held down (the jaw past the click, the button's travel left).
        lead_on_s: how long before the light is wanted on the jaw starts to press [s].
        lead_off_s: how long before it is wanted off the jaw starts to release [s].
    """

    released: float = 30.0
    click: float = 24.0
    pressed: float = 20.0
    lead_on_s: float = SWITCH_LEAD_S[0]
    lead_off_s: float = SWITCH_LEAD_S[1]

    def check(self) -> None:
        """Refuse, in one line, positions not in the order released > click > pressed."""
        if not self.released > self.click > self.pressed >= 0.0:
            raise PlanError(
                f"--switch-gripper {self.released:g} {self.click:g} {self.pressed:g}: the jaw "
                "closes to press, so released > click > pressed >= 0 [%]. Fix: read the "
                "gripper at the click with read_position.py, give e.g. click + 6, click, "
                "click - 4.")


def switch_times(lit: np.ndarray, dt: float) -> list[tuple[float, float]]:
    """Each lit stretch's (on, off) times [s] from the first sample (``lit``: one per ``dt``).

    Example:
        >>> switch_times(np.array([0, 1, 1, 0, 0, 1, 1, 1], bool), 0.5)
        [(0.5, 1.5), (2.5, 4.0)]
    """
    lit = np.asarray(lit, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[False], lit, [False]]).astype(int)))
    return [(float(a * dt), float(b * dt)) for a, b in zip(edges[::2], edges[1::2],
                                                            strict=True)]


def gripper_goals(lit: np.ndarray, dt: float, switch: TorchSwitch,
                  max_speed: float) -> np.ndarray:
    """The gripper's goal [%] at each sample: the capped ramp to press, or to release.

    Each press starts ``switch.lead_on_s`` before its light goes on and each release
    ``switch.lead_off_s`` before it goes off; between, the goal moves at ``max_speed``
    [%/s] (the hardware path's speed cap of the gripper: so it does not stretch the steps).
    """
    n = len(lit)
    target = np.full(n, switch.released)
    press, release = round(switch.lead_on_s / dt), round(switch.lead_off_s / dt)
    for on, off in switch_times(lit, dt):
        start, stop = max(0, round(on / dt) - press), max(0, round(off / dt) - release)
        target[start:stop] = switch.pressed
    goals = np.empty(n)
    step = max_speed * dt * (1.0 - 1e-9)  # a hair under the cap
    here = switch.released
    for k in range(n):
        here += float(np.clip(target[k] - here, -step, step))
        goals[k] = here
    return goals
