"""Time scalings of a joint-space move: where, how fast and how hard it goes.

A move from ``q0`` to ``qf`` in ``T`` [s] is ``q(t) = q0 + f(s) (qf - q0)`` with
``s = t / T`` clipped to [0, 1] (the course's "time clipped to [0, duration]"), so
``dq/dt = f'(s) (qf - q0) / T`` and ``d2q/dt2 = f''(s) (qf - q0) / T^2``. One
:class:`Profile` per scaling, with ``f``, ``f'`` and ``f''`` and the peak of ``f'``
(the speed cap's factor: a move's peak speed over its mean speed):

==============  ==========================  =============  ===========================
name            f(s)                        peak of f'     ends
==============  ==========================  =============  ===========================
direct          1 (the goal at once)        infinite       a step: the servo's own move
linear          s                           1              velocity jumps at both ends
cubic           3 s^2 - 2 s^3               3/2            zero velocity
quintic         10 s^3 - 15 s^4 + 6 s^5     15/8           zero velocity, acceleration
minimum_jerk    (the same polynomial)       15/8           (its name in the literature)
==============  ==========================  =============  ===========================

The course writes the cubic per joint as ``a0 + a1 t + a2 t^2 + a3 t^3``
(:func:`cubic_coefficients`); with zero end velocities that is the table's row
times ``qf - q0``. The rest-to-rest quintic with zero end accelerations is the
minimum-jerk polynomial (Flash and Hogan 1985): both names are kept, one function.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["PROFILES", "SPEED_CAPPED_PROFILES", "cubic_coefficients", "quintic_coefficients"]


def _ones(s):
    return np.ones_like(s, dtype=float) if isinstance(s, np.ndarray) else 1.0


def _zeros(s):
    return np.zeros_like(s, dtype=float) if isinstance(s, np.ndarray) else 0.0


def minimum_jerk(s):
    """Minimum-jerk time scaling: 0 -> 0, 1 -> 1, zero velocity and acceleration at both ends."""
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def linear(s):
    """Linear time scaling (the course's interpolation)."""
    return s


def cubic(s):
    """Cubic time scaling with zero end velocities: 3 s^2 - 2 s^3."""
    return s * s * (3.0 - 2.0 * s)


@dataclass(frozen=True)
class Profile:
    """A time scaling ``f(s)`` on [0, 1] with its derivatives (works on floats and arrays).

    Calling a profile is ``position``: ``PROFILES["cubic"](0.5) == 0.5``.
    """

    name: str
    position: Callable  # f(s)
    velocity: Callable  # f'(s), per unit of s
    acceleration: Callable  # f''(s), per unit of s^2
    peak_speed: float  # max of f' on [0, 1]: the speed cap's factor

    def __call__(self, s):
        """``f(s)``: the fraction of the way at ``s`` (time over duration)."""
        return self.position(s)


PROFILES: dict[str, Profile] = {
    "direct": Profile("direct", _ones, _zeros, _zeros, math.inf),
    "linear": Profile("linear", linear, _ones, _zeros, 1.0),
    "cubic": Profile("cubic", cubic, lambda s: 6.0 * s * (1.0 - s), lambda s: 6.0 - 12.0 * s,
                     1.5),
    "quintic": Profile("quintic", minimum_jerk, lambda s: 30.0 * s * s * (1.0 - s) ** 2,
                       lambda s: 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s), 1.875),
    "minimum_jerk": Profile("minimum_jerk", minimum_jerk,
                            lambda s: 30.0 * s * s * (1.0 - s) ** 2,
                            lambda s: 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s), 1.875),
}
"""Every profile by name. ``direct`` is a step (the course's "direct position commands")."""

SPEED_CAPPED_PROFILES = tuple(name for name, p in PROFILES.items() if math.isfinite(p.peak_speed))
"""The profiles a speed cap can stretch (all but ``direct``): the real arm's choices."""


def cubic_coefficients(q0: float, qf: float, duration: float) -> tuple[float, float, float, float]:
    """The course's ``a0, a1, a2, a3`` of one joint: from ``q0`` to ``qf`` in ``duration`` [s].

    Zero velocity at both ends: ``a1 = 0``, ``a2 = 3 (qf - q0) / T^2``, ``a3 = -2 (qf - q0) / T^3``.

    Example:
        >>> cubic_coefficients(10.0, 50.0, 2.0)  # [deg], [deg/s], [deg/s^2], [deg/s^3]
        (10.0, 0.0, 30.0, -10.0)
    """
    delta = qf - q0
    return q0, 0.0, 3.0 * delta / duration**2, -2.0 * delta / duration**3


def quintic_coefficients(q0: float, qf: float, duration: float) -> tuple[float, ...]:
    """``a0 .. a5`` of one joint, zero velocity and acceleration at both ends.

    Example:
        >>> quintic_coefficients(0.0, 10.0, 1.0)
        (0.0, 0.0, 0.0, 100.0, -150.0, 60.0)
    """
    delta = qf - q0
    return (q0, 0.0, 0.0, 10.0 * delta / duration**3, -15.0 * delta / duration**4,
            6.0 * delta / duration**5)
