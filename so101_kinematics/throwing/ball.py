"""The thrown ball and its flight: release point and velocity -> landing point, with air drag.

The forward model of a throw. A ball of mass ``m`` and diameter ``D`` flies under gravity
and quadratic air drag (no lift, no spin: the ball leaves the jaws without a spin worth
modelling, and the Magnus force of a slow spin is a few % of the drag)::

    dv/dt = g - k |v| v,   k = rho Cd A / (2 m),   A = pi D^2 / 4

integrated by the classical Runge-Kutta method at ``FLIGHT_STEP_S``. The simulator applies
the same drag force to its free ball at every physics step (``throw_scene``), so the
simulated landing and this model differ only by the integrators and the release state.

Sources of the numbers:

- ITTF Technical Leaflet T3 (the ball): a ping-pong ball is 40 mm, 2.7 g.
- Cd 0.47: a smooth sphere at Reynolds numbers 1e3-2e5 (Hoerner, *Fluid-Dynamic Drag*,
  1965, ch. 3); a ping-pong ball at 2-3 m/s has Re = v D / nu = 5000-8000 (nu = 1.5e-5 m^2/s).
- Air at 20 C and 101.325 kPa: rho = 1.204 kg/m^3 (ISO 2533's standard atmosphere, scaled).

Example (a ping-pong ball's drag at 2.5 m/s, as a fraction of its weight)::

    >>> round(BALLS["pingpong"].drag_per_speed_squared * 2.5 ** 2 / 9.81, 3)
    0.084
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = [
    "AIR_DENSITY", "BALLS", "Ball", "FALL_ACCELERATION", "FLIGHT_STEP_S", "MAX_FLIGHT_S", "flight",
    "landing_point",
]

AIR_DENSITY = 1.204
"""Air's density [kg/m^3] at 20 C and sea-level pressure (ISO 2533)."""

FALL_ACCELERATION = -float(mujoco.MjOption().gravity[2])
"""Gravity's acceleration [m/s^2]: MuJoCo's default ``opt.gravity`` (9.81), the simulator's."""

FLIGHT_STEP_S = 0.001
"""The forward model's integration step [s] (RK4: its own error is far below a millimetre)."""

MAX_FLIGHT_S = 2.0
"""The longest flight the model integrates [s] (a throw across the table lasts under 1 s)."""


@dataclass(frozen=True)
class Ball:
    """A thrown ball: a sphere of ``diameter`` [m] and ``mass`` [kg] with drag coefficient ``cd``.

    Attributes:
        name: its name (``--ball``).
        diameter: [m]. mass: [kg]. cd: the drag coefficient [-].
        source: where the numbers come from.
    """

    name: str
    diameter: float
    mass: float
    cd: float
    source: str

    def report(self) -> dict:
        """The ball as a JSON report gives it: name, diameter [m], mass [kg], drag, source."""
        return {"name": self.name, "diameter_m": self.diameter, "mass_kg": self.mass,
                "cd": self.cd, "source": self.source}

    @property
    def radius(self) -> float:
        """The ball's radius [m]."""
        return self.diameter / 2.0

    @property
    def drag_per_speed_squared(self) -> float:
        """``k`` [1/m]: the drag's deceleration is ``k v^2``."""
        area = math.pi * self.diameter ** 2 / 4.0
        return AIR_DENSITY * self.cd * area / (2.0 * self.mass)

    def drag_force(self, velocity) -> np.ndarray:
        """The air's force [N] on the ball moving at ``velocity`` [m/s] (world frame)."""
        v = np.asarray(velocity, dtype=float)
        return -self.mass * self.drag_per_speed_squared * np.linalg.norm(v) * v


BALLS = {
    "pingpong": Ball("pingpong", 0.040, 0.0027, 0.47,
                     "ITTF T3: 40 mm, 2.7 g; Cd 0.47 of a smooth sphere (Hoerner 1965)"),
    "beanbag": Ball("beanbag", 0.030, 0.015, 0.47,
                    "a small beanbag as a 30 mm, 15 g sphere (a bag is not a sphere: its drag, "
                    "0.3 % of its weight at 2.5 m/s, barely matters); Cd 0.47 as a sphere's"),
}
"""The balls ``throw.py --ball`` offers, by name."""


def _acceleration(v: np.ndarray, k: float) -> np.ndarray:
    """Gravity and drag on (n, 3) velocities [m/s]: (n, 3) accelerations [m/s^2]."""
    speed = np.linalg.norm(v, axis=1, keepdims=True)
    a = -k * speed * v
    a[:, 2] -= FALL_ACCELERATION
    return a


def flight(position, velocity, ball: Ball, floor: float, step: float = FLIGHT_STEP_S,
           drag: bool = True) -> np.ndarray:
    """Where the ball's centre crosses the height ``floor`` [m] on its way down, for each start.

    Args:
        position: (3,) or (n, 3) release points [m] (world frame, z up).
        velocity: (3,) or (n, 3) release velocities [m/s].
        ball: the ball (its drag).
        floor: the height [m] of the ball's centre where the flight ends.
        step: the integration step [s].
        drag: False: a vacuum (to show what the drag is worth).

    Returns:
        (n, 4) rows (x, y, z, t): the crossing point [m] (z is ``floor``) and the flight time
        [s], interpolated within the last step; NaN for a ball that never comes down to
        ``floor`` within ``MAX_FLIGHT_S`` (or starts below it).

    Example (no drag: from 0.3 m up, 2 m/s level: x = 2 sqrt(2 0.3 / 9.81) = 0.4946 m)::

        >>> round(float(flight([0, 0, 0.3], [2, 0, 0], BALLS["pingpong"], 0.0,
        ...                    drag=False)[0, 0]), 4)
        0.4946
    """
    p = np.atleast_2d(np.asarray(position, dtype=float)).copy()
    v = np.atleast_2d(np.asarray(velocity, dtype=float)).copy()
    k = ball.drag_per_speed_squared if drag else 0.0
    result = np.full((len(p), 4), np.nan)
    live = p[:, 2] >= floor
    for i in range(int(MAX_FLIGHT_S / step)):
        if not live.any():
            break
        k1v = _acceleration(v, k)
        k2v = _acceleration(v + 0.5 * step * k1v, k)
        k3v = _acceleration(v + 0.5 * step * k2v, k)
        k4v = _acceleration(v + step * k3v, k)
        p_next = p + step / 6.0 * (v + 2.0 * (v + 0.5 * step * k1v)
                                   + 2.0 * (v + 0.5 * step * k2v) + (v + step * k3v))
        v_next = v + step / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        crossed = live & (p_next[:, 2] < floor)
        if crossed.any():
            share = ((p[crossed, 2] - floor) / (p[crossed, 2] - p_next[crossed, 2]))[:, None]
            result[crossed, :3] = p[crossed] + share * (p_next[crossed] - p[crossed])
            result[crossed, 3] = (i + share[:, 0]) * step
            live &= ~crossed
        p, v = p_next, v_next
    return result


def landing_point(position, velocity, ball: Ball, floor: float) -> np.ndarray:
    """(x, y) [m] where one ball's centre comes down to ``floor`` [m] (NaN if it never does)."""
    return flight(position, velocity, ball, floor)[0, :2]
