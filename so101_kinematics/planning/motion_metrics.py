"""How well a joint trajectory followed its commands, and how smoothly it moved.

One implementation of the write-up's figures (assignment 9: "tracking performance,
smoothness of motion") for every source of a trajectory: the simulator's physics
steps (``sim/tracking.py``), a hardware run's log and the simulator's replay of it
(``lab/profile_compare.py``). :func:`metrics` returns :data:`METRIC_KEYS`:

- ``tracking_rms_deg``, ``tracking_max_deg``: measured minus commanded [deg], the RMS
  over every sample and joint together, and the largest magnitude;
- ``peak_velocity_deg_s``, ``peak_acceleration_deg_s2``, ``peak_jerk_deg_s3``: the
  largest magnitude of the measured motion's derivatives, any joint, any sample.

Where the derivatives come from: the simulator knows its joints' velocity and
acceleration exactly at each physics step (:func:`step_derivatives`); a log holds only
positions, and the arm's are whole encoder counts (1 count = 360/4096 deg = 0.088 deg,
``so101_kinematics/servo.py``'s sources). Differencing them sample by sample turns one count
into 8.8 deg/s, 880 deg/s^2 and 88 000 deg/s^3 at the arm's 100 Hz loop, far above a
2 s move's own figures (tens of deg/s^3). :func:`fitted_derivatives` therefore fits a
cubic in time to the samples of a :data:`DERIVATIVE_WINDOW_S` window around each
sample (least squares; a Savitzky-Golay filter on the samples' own times, so a gap
left by a failed read is no error) and takes its derivatives there: exact for any
cubic, so a cubic move's figures come out as its formulas (6 (qf - q0) / T^2, 12 (qf -
q0) / T^3), and the window averages the counts' steps. Its width is a trade-off,
derived here from steady ramps of 1 to 60 deg/s sampled at 100 Hz and rounded to counts
(true acceleration and jerk 0; the worst speed and phase): the counts alone read as up
to 38 deg/s^2 and 250 deg/s^3 with a 0.3 s window, 14 and 110 with 0.4 s, 14 and 55
with 0.5 s (velocity within 2.3, 1.4, 1.3 deg/s). A wider window also spreads a step
of acceleration (a cubic's start) or of velocity (linear's) over its width, so a
profile's peaks are read at the window's resolution: 0.4 s, a fifth of the course's
2 s moves. On the virtual arm at 0.3 s the
arm's peak jerk of a minimum-jerk run came out twice the simulator's (the counts); at
0.4 s they agree within 10 % (docs/trajectories.md). Only figures taken with the same
window compare.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from so101_kinematics.servo import COUNTS_PER_TURN

__all__ = [
    "DERIVATIVE_WINDOW_S", "ENCODER_COUNT_DEG", "METRIC_KEYS", "fitted_derivatives", "metrics",
    "step_derivatives", "to_encoder_counts",
]

METRIC_KEYS = ("tracking_rms_deg", "tracking_max_deg", "peak_velocity_deg_s",
               "peak_acceleration_deg_s2", "peak_jerk_deg_s3")
"""The figures of :func:`metrics`, in their units."""
DERIVATIVE_WINDOW_S = 0.4  # [s] the fit's window for positions-only data (see the module)
MIN_WINDOW_SAMPLES = 5  # a cubic (4 coefficients) fitted to at least one sample more
ENCODER_COUNT_DEG = 360.0 / COUNTS_PER_TURN  # [deg] one STS3215 count ([MEM], servo.py)


def fitted_derivatives(time: Sequence[float], positions,
                       window_s: float = DERIVATIVE_WINDOW_S) -> tuple[np.ndarray, ...]:
    """Velocity, acceleration and jerk of sampled positions, from a local cubic fit.

    Each sample's window holds the samples nearest it by index (as many as
    ``window_s`` spans at the median sample spacing, at least ``MIN_WINDOW_SAMPLES``),
    centred, or shifted inward at the ends of the data.

    Args:
        time: [s] of each sample, increasing (n,).
        positions: [deg] (n,) or (n, joints).
        window_s: [s] the window's width.

    Returns:
        velocity [deg/s], acceleration [deg/s^2], jerk [deg/s^3], each shaped as ``positions``.

    Example:
        >>> t = np.linspace(0.0, 2.0, 201)  # [s], 100 Hz
        >>> v, a, j = fitted_derivatives(t, 10.0 * t**3)  # [deg]
        >>> round(float(v[-1]), 6), round(float(a[-1]), 6), round(float(j[0]), 6)
        (120.0, 120.0, 60.0)
    """
    t = np.asarray(time, dtype=float)
    q = np.asarray(positions, dtype=float)
    flat = q.ndim == 1
    q = q.reshape(len(t), -1)
    if len(t) < MIN_WINDOW_SAMPLES:
        zeros = np.zeros_like(q)
        return tuple(z[:, 0] if flat else z for z in (zeros, zeros.copy(), zeros.copy()))
    spacing = float(np.median(np.diff(t)))
    size = min(len(t), max(MIN_WINDOW_SAMPLES, int(round(window_s / spacing)) + 1))
    first = np.clip(np.arange(len(t)) - size // 2, 0, len(t) - size)
    index = first[:, None] + np.arange(size)[None, :]  # (n, size): each sample's window
    scale = max(window_s, spacing) / 2.0  # [s] times scaled to about [-1, 1]: well conditioned
    u = (t[index] - t[:, None]) / scale
    basis = u[:, :, None] ** np.arange(4)[None, None, :]  # (n, size, 4)
    normal = np.einsum("nsi,nsj->nij", basis, basis)
    rhs = np.einsum("nsi,nsk->nik", basis, q[index])
    c = np.linalg.solve(normal, rhs)  # (n, 4, joints): q ~ c0 + c1 u + c2 u^2 + c3 u^3
    out = (c[:, 1] / scale, 2.0 * c[:, 2] / scale**2, 6.0 * c[:, 3] / scale**3)
    return tuple(x[:, 0] if flat else x for x in out)


def step_derivatives(time: Sequence[float], velocity, acceleration) -> tuple[np.ndarray, ...]:
    """A simulator's exact velocity and acceleration, and the jerk: their change per step.

    Args:
        time: [s] of each physics step (n,).
        velocity: [deg/s] (n, joints).
        acceleration: [deg/s^2] (n, joints).
    """
    acceleration = np.asarray(acceleration, dtype=float)
    jerk = np.diff(acceleration, axis=0) / np.diff(np.asarray(time, dtype=float))[:, None]
    return np.asarray(velocity, dtype=float), acceleration, jerk


def metrics(time: Sequence[float], commanded, measured, derivatives=None,
            window_s: float = DERIVATIVE_WINDOW_S) -> dict[str, float]:
    """Tracking error and smoothness (:data:`METRIC_KEYS`) of a trajectory.

    Args:
        time: [s] of each sample (n,).
        commanded: [deg] (n, joints): what the joints were told.
        measured: [deg] (n, joints): where they were.
        derivatives: (velocity, acceleration, jerk) of ``measured`` when known (a
            simulator's: :func:`step_derivatives`); None: :func:`fitted_derivatives`, its
            peaks over the samples at least half a window from either end (there the fit
            is one-sided and reads a move starting with the log higher than the same move
            later: 2x for linear's first move on the virtual arm).
        window_s: [s] the fit's window (without ``derivatives``).

    Example: a joint told to step by 2 deg that follows one sample (10 ms) late.

        >>> t = np.arange(5) * 0.01  # [s]
        >>> cmd = np.array([[0.0], [2.0], [2.0], [2.0], [2.0]])  # [deg]
        >>> meas = np.array([[0.0], [0.0], [2.0], [2.0], [2.0]])
        >>> figures = metrics(t, cmd, meas)
        >>> figures["tracking_max_deg"], round(figures["tracking_rms_deg"], 4)  # 2 sqrt(1/5)
        (2.0, 0.8944)
    """
    t = np.asarray(time, dtype=float)
    if len(t) < 2:
        return dict.fromkeys(METRIC_KEYS, 0.0)
    commanded, measured = np.asarray(commanded, dtype=float), np.asarray(measured, dtype=float)
    error = measured - commanded
    if derivatives is not None:
        velocity, acceleration, jerk = derivatives
    else:  # the peaks where the window is centred: at the data's ends the fit extrapolates
        velocity, acceleration, jerk = fitted_derivatives(t, measured, window_s)
        inner = (t >= t[0] + window_s / 2 - 1e-9) & (t <= t[-1] - window_s / 2 + 1e-9)
        if inner.any():
            velocity, acceleration, jerk = velocity[inner], acceleration[inner], jerk[inner]
    return {"tracking_rms_deg": float(np.sqrt(np.mean(error**2))),
            "tracking_max_deg": float(np.abs(error).max()),
            "peak_velocity_deg_s": float(np.abs(velocity).max()),
            "peak_acceleration_deg_s2": float(np.abs(acceleration).max()),
            "peak_jerk_deg_s3": float(np.abs(jerk).max()) if np.size(jerk) else 0.0}


def to_encoder_counts(angles) -> np.ndarray:
    """``angles`` [deg] rounded to whole encoder counts, as the arm reads them."""
    return np.round(np.asarray(angles, dtype=float) / ENCODER_COUNT_DEG) * ENCODER_COUNT_DEG
