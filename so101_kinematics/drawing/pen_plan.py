"""Drawing at a constant pen speed: the tip's path in time, the joint path, the servo's lead.

The strokes (page millimetres, ``strokes.prepare``) become one sample per control period
``dt``: for each stroke the pen goes down at its start (``LOWER_S``, cubic), waits
``DWELL_S`` for the servos to settle, draws at ``speed`` [mm/s] with the contact height
held (the tip ``pen.PEN_PRESS_M`` below the paper: the holder's spring keeps it on the
page), lifts ``LIFT_M`` at the stroke's end, and travels pen-up to the next stroke at
``TRAVEL_SPEED_MM_S``. Along a stroke the speed is constant between corners; at a corner
sharper than ``CORNER_DEG`` the pen slows to a stop and goes on (a trapezoid of
ramps of ``SPEED_RAMP_S``): a lagging servo cuts a corner it passes at speed. The ramps take the
same time at any speed, so the pen reaches the asked speed on every run longer than
``speed x SPEED_RAMP_S``.

The servo's lag: a position servo trails a goal moving at ``v`` by ``tau v``
(``servo.lag``: 0.10 s at lerobot's P = 16 on 5 V, less on 12 V). Each command is the
planned configuration plus ``tau`` times its planned velocity (``hw/lead.py``'s velocity
lead, here on the whole path), so the faithful servo is where the plan is; the lead
vanishes where the pen stops. :func:`check_joint_speeds` refuses a pen speed that asks a
joint for more than ``SPEED_SHARE`` of the servo's no-load speed at its supply.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from so101_kinematics import gravity, servo
from so101_kinematics.drawing.page import PAGE_THICKNESS, Page, page_to_base
from so101_kinematics.drawing.pen import (
    GRAVITY,
    HOLDER_MASS,
    PEN_MASS,
    PEN_PRESS_M,
    PenPose,
    pen_configuration,
    pressing_force,
)
from so101_kinematics.errors import PlanError, UnreachableError
from so101_kinematics.frames import ARM_JOINTS

__all__ = [
    "CORNER_DEG", "SPEED_RAMP_S", "DEFAULT_SPEED_MM_S", "DWELL_S", "LIFT_M", "LOWER_S",
    "PenPath", "SPEED_SHARE", "TRAVEL_SPEED_MM_S", "check_joint_speeds", "corner_runs",
    "lag_seconds", "lead_commands", "plan_drawing", "points_along", "trapezoid", "with_pen_load",
]

DEFAULT_SPEED_MM_S = 15.0
"""The pen's speed on the paper by default [mm/s] (a public SO-101 drawing project: 10)."""
TRAVEL_SPEED_MM_S = 40.0  # [mm/s] pen up, between strokes
SPEED_RAMP_S = 0.1  # [s]: the pen's speed-up and slow-down at stroke ends and corners
CORNER_DEG = 25.0  # [deg]: a turn sharper than this is drawn with a stop
LIFT_M = 0.008  # [m]: the pen's lift between strokes (above the paper)
LOWER_S = 0.4  # [s]: the pen's way down or up (cubic)
DWELL_S = 0.25  # [s]: the pen waits on the paper before it draws and after it stops
CORNER_DWELL_S = 0.08  # [s]: the wait at a corner (the servos catch up their lag)
SPEED_SHARE = 0.5
"""The largest share of a servo's no-load speed a drawing may ask of a joint: the rest is
the margin the servo's position loop needs to follow (and the load's)."""


@dataclass
class PenPath:
    """A drawing in time: the tip's planned path and the joints'.

    Attributes:
        dt: the control period [s] (one sample each).
        tips: (n, 3) planned tip positions [m], base frame.
        down: (n,) True where the pen is planned on the paper (drawing or resting on it).
        stroke: (n,) the stroke's index being drawn, -1 elsewhere.
        plan: the planned configurations [deg], one per sample.
        commands: the configurations sent (the plan with the servo's lead) [deg].
    """

    dt: float
    tips: np.ndarray
    down: np.ndarray
    stroke: np.ndarray
    plan: list[dict] = field(default_factory=list)
    commands: list[dict] = field(default_factory=list)

    @property
    def duration(self) -> float:
        """The drawing's length in time [s]."""
        return len(self.tips) * self.dt


def trapezoid(length: float, speed: float, accel: float, dt: float) -> np.ndarray:
    """Distances [same unit as ``length``] along a line at each ``dt``: rest to rest.

    Constant acceleration to ``speed``, constant speed, constant deceleration (a triangle
    when the line is too short to reach ``speed``); the last sample is ``length``.

    Example:
        >>> trapezoid(10.0, 10.0, 100.0, 0.05).round(3).tolist()[:4]  # 0.1 s to 10 /s
        [0.125, 0.5, 1.0, 1.5]
    """
    if length <= 0.0:
        return np.zeros(1)
    ramp = speed / accel
    if speed * ramp >= length:  # a triangle: never reaches speed
        ramp = math.sqrt(length / accel)
        speed = accel * ramp
    total = 2.0 * ramp + (length - speed * ramp) / speed
    t = np.arange(1, max(1, math.ceil(total / dt - 1e-9)) + 1) * dt
    t = np.minimum(t, total)
    s = np.where(t < ramp, 0.5 * accel * t**2,
                 np.where(t <= total - ramp, 0.5 * speed * ramp + speed * (t - ramp),
                          length - 0.5 * accel * (total - t) ** 2))
    s[-1] = length
    return s


def points_along(points: np.ndarray, distances: np.ndarray) -> np.ndarray:
    """Points at ``distances`` along the polyline ``points``."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(steps)])
    return np.column_stack([np.interp(distances, cumulative, points[:, k])
                            for k in range(points.shape[1])])


def corner_runs(stroke: np.ndarray) -> list[np.ndarray]:
    """A stroke cut at its corners sharper than ``CORNER_DEG`` (each run drawn rest to rest)."""
    d = np.diff(stroke, axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    turn = np.abs((np.diff(heading) + math.pi) % (2 * math.pi) - math.pi)
    corners = [i + 1 for i in np.flatnonzero(turn > math.radians(CORNER_DEG))]
    cuts = [0, *corners, len(stroke) - 1]
    return [stroke[a:b + 1] for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def _vertical(a: np.ndarray, b: np.ndarray, dt: float) -> np.ndarray:
    n = max(1, round(LOWER_S / dt))
    s = np.arange(1, n + 1) / n
    f = s * s * (3.0 - 2.0 * s)
    return a + f[:, None] * (b - a)


def _hold(p: np.ndarray, seconds: float, dt: float) -> np.ndarray:
    return np.repeat(p[None], max(1, round(seconds / dt)), axis=0)


def _tip_samples(page: Page, strokes: Sequence[np.ndarray], speed: float, dt: float,
                 z_down: float, z_up: float):
    """The tip's samples [m] with their pen-down flags and stroke indices."""
    parts: list[tuple[np.ndarray, bool, int]] = []
    here, travel = None, TRAVEL_SPEED_MM_S
    for index, stroke in enumerate(strokes):
        start_up = page_to_base(page, stroke[:1], z_up)[0]
        if here is not None:
            way = float(np.linalg.norm(start_up - here)) * 1000.0
            if way > 0.0:
                line = np.vstack([here, start_up])
                distances = trapezoid(way, travel, travel / SPEED_RAMP_S, dt) / 1000.0
                parts.append((points_along(line, distances), False, -1))
        else:
            parts.append((_hold(start_up, DWELL_S, dt), False, -1))
        start_down = page_to_base(page, stroke[:1], z_down)[0]
        parts.append((_vertical(start_up, start_down, dt), False, -1))
        parts.append((_hold(start_down, DWELL_S, dt), True, index))
        for run in corner_runs(stroke):
            tips = page_to_base(page, run, z_down)
            length = float(np.linalg.norm(np.diff(run, axis=0), axis=1).sum())
            distances = trapezoid(length, speed, speed / SPEED_RAMP_S, dt) / 1000.0
            parts.append((points_along(tips, distances), True, index))
            parts.append((_hold(tips[-1], CORNER_DWELL_S, dt), True, index))
        end_down = page_to_base(page, stroke[-1:], z_down)[0]
        parts.append((_hold(end_down, DWELL_S - CORNER_DWELL_S, dt), True, index))
        here = page_to_base(page, stroke[-1:], z_up)[0]
        parts.append((_vertical(end_down, here, dt), False, -1))
    parts.append((_hold(here, DWELL_S, dt), False, -1))  # at rest, pen up: the servos settle
    tips = np.vstack([p for p, _, _ in parts])
    down = np.concatenate([np.full(len(p), flag) for p, flag, _ in parts])
    stroke = np.concatenate([np.full(len(p), i) for p, _, i in parts])
    return tips, down, stroke


def lag_seconds(volts: float = servo.DEFAULT_SUPPLY_V, variant: str | None = None,
                p: int | None = None) -> float:
    """The servo's lag per unit of speed [s] at lerobot's registers, P changed (``servo.lag``).

    Example:
        >>> round(lag_seconds(5.0, "C001"), 3)  # the kit's servo on 5 V (hw/lead.py's 0.103 s)
        0.103
    """
    settings = servo.LEROBOT if p is None else servo.LEROBOT.with_(p=int(p))
    return servo.lag(1.0, settings, volts, variant or servo.default_variant(volts))


def lead_commands(plan: list[dict], dt: float, tau: float) -> list[dict]:
    """Each configuration plus ``tau`` times the plan's velocity (central differences)."""
    q = np.array([[c[j] for j in ARM_JOINTS] for c in plan])
    rate = np.gradient(q, dt, axis=0) if len(q) > 1 else np.zeros_like(q)
    led = q + tau * rate
    return [dict(zip(ARM_JOINTS, row.tolist(), strict=True)) for row in led]


def with_pen_load(commands: list[dict], down: np.ndarray, volts: float, variant: str | None,
               p: int | None) -> list[dict]:
    """Each command plus the sag the pen's load at the object frame adds (``gravity``).

    The servos' own feed-forward (the simulator's, the arm's ``--gravity-ff``) knows the arm,
    not the pen: in the air the pen and its holder hang on it; on the paper the pen pushes
    its holder up with its force (``pen.pressing_force``), less the holder's weight. Each
    is a mass at the object frame (negative: a push up) for ``gravity.feedforward``.
    """
    settings = servo.LEROBOT if p is None else servo.LEROBOT.with_(p=int(p))
    in_air = PEN_MASS + HOLDER_MASS
    on_paper = HOLDER_MASS - pressing_force() / GRAVITY
    out = []
    for cfg, pressed in zip(commands, down, strict=True):
        full = {**cfg, "gripper": 50.0}
        loaded = gravity.feedforward(full, settings, volts, variant,
                                     on_paper if pressed else in_air)
        bare = gravity.feedforward(full, settings, volts, variant)
        out.append({j: cfg[j] + loaded[j] - bare[j] for j in ARM_JOINTS})
    return out


def check_joint_speeds(plan: list[dict], dt: float, speed: float,
                       volts: float = servo.DEFAULT_SUPPLY_V, variant: str | None = None,
                       tips: np.ndarray | None = None, down: np.ndarray | None = None) -> None:
    """Refuse a plan that asks a joint for more than ``SPEED_SHARE`` of its no-load speed.

    The speed that fits: each pen-down sample's fastest joint per unit of the tip's speed
    there is the Jacobian's, the same at any pen speed, so the pen's speed times the largest
    such ratio bounds every joint's speed.

    Args:
        plan: the configurations [deg], one per ``dt``.
        dt: the control period [s].
        speed: the pen's asked speed [mm/s] (for the message).
        volts: the supply [V].
        variant: the STS3215 variant (default: the supply's).
        tips: the tip's planned positions [m] (n, 3), for the speed that fits.
        down: the samples with the pen on the paper (n,).

    Raises:
        PlanError: naming the joint, its speed, the servo's, and the pen speed that fits.
    """
    q = np.array([[c[j] for j in ARM_JOINTS] for c in plan])
    if len(q) < 2:
        return
    joint_rates = np.abs(np.diff(q, axis=0)) / dt  # [deg/s] per sample and joint
    rates = joint_rates.max(axis=0)
    chosen = servo.VARIANTS[variant or servo.default_variant(volts)]
    limit = SPEED_SHARE * math.degrees(chosen.no_load_speed(volts))
    worst = int(np.argmax(rates))
    if rates[worst] <= limit:
        return
    fits = speed * limit / rates[worst]
    if tips is not None and down is not None:
        tip_speed = np.linalg.norm(np.diff(tips, axis=0), axis=1) * 1000.0 / dt  # [mm/s]
        drawing = down[1:] & down[:-1] & (tip_speed > 1e-3 * speed)
        if drawing.any():
            fits = limit / float((joint_rates.max(axis=1)[drawing] / tip_speed[drawing]).max())
    raise PlanError(
        f"--speed-mm-s {speed:g}: the drawing turns {ARM_JOINTS[worst]} at up to "
        f"{rates[worst]:.0f} deg/s, more than the {SPEED_SHARE:.0%} of the STS3215 "
        f"{chosen.name}'s no-load speed at {volts:g} V ({limit:.0f} deg/s) a servo can "
        f"hold on a path. Fix: --speed-mm-s {math.floor(fits):g} or less.")


def plan_drawing(page: Page, strokes: Sequence[np.ndarray], pose: PenPose,
                 speed: float = DEFAULT_SPEED_MM_S, dt: float = 0.01,
                 volts: float = servo.DEFAULT_SUPPLY_V, variant: str | None = None,
                 lag: float = 0.0, load: bool = False, p: int | None = None) -> PenPath:
    """The drawing's samples in time and the joint path that draws them.

    Args:
        page: where the page lies.
        strokes: the prepared strokes [mm] on the page (``strokes.prepare``).
        pose: the pen's tilt and roll.
        speed: the pen's speed on the paper [mm/s].
        dt: the control period [s].
        volts: the servos' supply [V] (their speed).
        variant: the STS3215 variant (default: the supply's).
        lag: the servo's lag [s] (:func:`lag_seconds`): each command leads the plan by it
            times the plan's velocity; 0: the plan as it is.
        load: offset each command by the sag the pen's load adds (:func:`with_pen_load`).
        p: the servos' P_Coefficient (default lerobot's), for that sag.

    Raises:
        PlanError: a speed the servos cannot hold; UnreachableError: a point out of reach
            (``page.check_reach`` says which stroke first).
    """
    if not speed > 0.0:
        raise PlanError(f"--speed-mm-s {speed:g} is not positive. Fix: e.g. --speed-mm-s 15.")
    z_down = PAGE_THICKNESS - PEN_PRESS_M
    tips, down, stroke = _tip_samples(page, strokes, speed, dt, z_down, PAGE_THICKNESS + LIFT_M)
    plan, cfg = [], None
    for tip in tips:
        try:
            cfg = pen_configuration(tip, pose, cfg)
        except UnreachableError as error:
            raise UnreachableError(f"{error} (check the page's reach first: "
                                   "page.check_reach)", error.reason, error.distance) from None
        plan.append(cfg)
    check_joint_speeds(plan, dt, speed, volts, variant, tips, down)
    commands = lead_commands(plan, dt, lag) if lag else [dict(c) for c in plan]
    if load:
        commands = with_pen_load(commands, down, volts, variant, p)
    return PenPath(dt, tips, down, stroke, plan, commands)
