"""A board registered to each arm's base from touched points: one home for both games.

The bases truly stand where a hand set them down: the nominal ones (``two_arm_scene.arm_bases``)
moved by a small error (:func:`displaced_bases`, :data:`BASE_ERROR` by default). With
``register="touch"`` each arm in turn registers the board to its base, as a student would by
hand: the arm's object frame (the grasp point between the jaw tips) is put on each of its marks
from where the mark truly is (standing in for the hand), the joint angles are read back, the
forward kinematics gives the touched points in the arm's base frame, and the 2-D rigid fit
(``frames.rigid_fit_2d``, the page registration's) gives the board's pose in that frame: the
arm's base as the planner knows it, with the residual (RMS and worst). ``register="nominal"``
plans with the nominal bases. Chess (``chess_game.py``) and tic-tac-toe (``two_arm_game.py``)
both call :func:`register_arms`; each game names its own marks.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import PlanError, UnreachableError
from so101_kinematics.fast_fk import forward_kinematics
from so101_kinematics.frames import rigid_fit_2d
from so101_kinematics.ik.call_shapes import get_inverse_kinematics
from so101_kinematics.two_arms.scene_arm import SceneArm
from so101_kinematics.two_arms.two_arm_scene import ArmBase, base_from_world, world_from_base

__all__ = [
    "BASE_ERROR", "MAX_REGISTRATION_RMS_MM", "REGISTRATIONS", "Registration",
    "check_register_option", "check_registration", "check_touch_reach", "describe_registration",
    "displaced_bases", "register_arms", "register_by_touch", "registered_base",
    "registration_options",
]

BASE_ERROR = (3.0, 1.0)
"""(mm, deg) How far each true base stands from its nominal pose by default: moved 3 mm
towards its own side (its frame's +y) and turned 1 deg. Not a measurement: the size of a
base set down by hand against a line on the table (issue 38's touched-point registration
is there to take it out). Unregistered, the 1 deg alone moves a square 0.26 m away 4.5 mm."""
REGISTRATIONS = ("touch", "nominal")
TOUCH_HEIGHT = CUBE_HALF_SIZE
"""[m] The object frame's height at a touch: the grasp point of a piece on the table (the
jaw tips just above the board)."""
TOUCH_DURATION = 1.5
"""[s] The move onto each mark."""
TOUCH_SETTLE = 0.5
"""[s] Held on the mark before the angles are read (the servos settle)."""
MAX_REGISTRATION_RMS_MM = 1.5
"""[mm] The largest RMS residual of a registration used: a third of the 5 mm the pieces
must land within (a fit that bad would eat the tolerance)."""


@dataclass(frozen=True)
class Registration:
    """The board's pose fitted in one arm's base frame.

    Attributes:
        arm: "left" or "right".
        base: the arm's base as the fit puts it in the world (the board's frame).
        residuals_mm: each touched point's distance from its mark after the fit [mm].
        rms_mm: their root mean square [mm].
    """

    arm: str
    base: ArmBase
    residuals_mm: tuple[float, ...]
    rms_mm: float

    def as_json(self) -> dict:
        """The report's entry for this registration."""
        return {"arm": self.arm, "base": asdict(self.base),
                "residuals_mm": [round(r, 3) for r in self.residuals_mm],
                "rms_mm": round(self.rms_mm, 3), "worst_mm": round(max(self.residuals_mm), 3)}


def describe_registration(entry: dict) -> str:
    """One line from a report's registration entry: the arm, the points, the residual.

    Example:
        >>> describe_registration({"arm": "left", "residuals_mm": [0.1, 0.3], "rms_mm": 0.224,
        ...                        "worst_mm": 0.3})
        'left arm: board registered from 2 touched points, residual 0.22 mm RMS, 0.30 mm worst'
    """
    return (f"{entry['arm']} arm: board registered from {len(entry['residuals_mm'])} touched "
            f"points, residual {entry['rms_mm']:.2f} mm RMS, {entry['worst_mm']:.2f} mm worst")


def registration_options(register: str | None, base_error, not_here: str | None = None) -> dict:
    """The games' ``register`` and ``base_error`` from the command line's (None: not given).

    Args:
        register: ``--register`` (default: :data:`REGISTRATIONS`' first, touch).
        base_error: ``--base-error`` (mm, deg) (default :data:`BASE_ERROR`).
        not_here: None where they apply; else why they do not, with the fix: either given is
            refused in one line, and the bases are the nominal ones.

    Raises:
        PlanError: ``--register`` or ``--base-error`` given where they do not apply.
    """
    if not_here is None:
        return {"register": register or REGISTRATIONS[0],
                "base_error": tuple(BASE_ERROR if base_error is None else base_error)}
    for option, value in (("--register", register), ("--base-error", base_error)):
        if value is not None:
            shown = value if isinstance(value, str) else " ".join(f"{v:g}" for v in value)
            raise PlanError(f"{option} {shown}: {not_here}")
    return {"register": "nominal", "base_error": (0.0, 0.0)}


def check_register_option(register: str) -> None:
    """Refuse, in one line, a ``register`` that is not one of :data:`REGISTRATIONS`."""
    if register not in REGISTRATIONS:
        raise PlanError(f"--register {register!r} is not one of {', '.join(REGISTRATIONS)}. "
                        "Fix: --register touch.")


def displaced_bases(bases: tuple[ArmBase, ArmBase], error_mm: float, error_deg: float
                    ) -> tuple[ArmBase, ArmBase]:
    """The bases moved ``error_mm`` towards their own side and turned ``error_deg``.

    Example:
        >>> from so101_kinematics.two_arms.two_arm_scene import arm_bases
        >>> left = displaced_bases(arm_bases("facing", 0.6), 3.0, 1.0)[0]
        >>> round(left.x, 4), round(left.y, 4), left.yaw
        (-0.3, 0.003, 1.0)
    """
    moved = []
    for base in bases:
        x, y, _ = world_from_base(base, (0.0, base.side * error_mm / 1e3, 0.0))
        moved.append(ArmBase(base.name, float(x), float(y), base.yaw + error_deg, base.side))
    return moved[0], moved[1]


def registered_base(name: str, side: float, board_points, touched) -> tuple[ArmBase, np.ndarray]:
    """The arm's base in the board's frame from touched points, and each point's residual [m].

    Args:
        name: the arm's name.
        side: its ``ArmBase.side``.
        board_points: (n, 2) the marks (x, y) [m] in the board's frame (the world).
        touched: (n, 2) where the object frame touched each, (x, y) [m] in the base frame.
    """
    marks = np.asarray(board_points, dtype=float)[:, :2]
    touched = np.asarray(touched, dtype=float)[:, :2]
    # base point = R(angle) board point + shift
    angle, shift, residuals = rigid_fit_2d(marks, touched)
    c, s = math.cos(angle), math.sin(angle)
    origin = -np.array([[c, s], [-s, c]]) @ shift  # R^T: the base's origin in the board's frame
    return (ArmBase(name, float(origin[0]), float(origin[1]), -math.degrees(angle), side),
            residuals)


def _tool_in_base(arm: SceneArm, m, d) -> np.ndarray:
    """The object frame (x, y, z) [m] in the arm's base frame, by FK of the angles read back."""
    return forward_kinematics(arm.get_configuration(m, d))[0]


def register_by_touch(m, d, watch, arm: SceneArm, points, park: tuple[dict, float]
                      ) -> Registration:
    """Touch ``points`` with ``arm``'s object frame and fit the board's pose (the module's doc).

    The arm is driven to each mark as it truly lies in its (true) base frame, a student's hand
    on the mark; only the angles read back enter the fit. Then it goes to ``park``
    (configuration [deg], duration [s]).

    Args:
        m: the model.
        d: its data.
        watch: the arms' ``ArmDistanceWatch`` (the moves are watched and filmed).
        arm: the ``SceneArm`` that touches (on its true base).
        points: the marks, each (x, y, ...) [m] in the world (the board's frame).
        park: where the arm waits after, and how long the move there takes.
    """
    marks, touched = [], []
    for point in points:
        target = base_from_world(arm.base, (point[0], point[1], TOUCH_HEIGHT))
        try:
            cfg = get_inverse_kinematics(target, approach="down", yaw_deg=0.0,
                                         initial=arm.get_command(m, d), gripper=0.0)
        except UnreachableError:
            raise PlanError(f"the {arm.name} arm, as its base truly stands, cannot touch the "
                            f"registration mark at ({point[0]:.3f}, {point[1]:.3f}) m. Fix: set "
                            "the base down nearer its nominal pose (a smaller --base-error), or "
                            "--register nominal.") from None
        arm.move_to_pose(m, d, watch, cfg, TOUCH_DURATION)
        arm.hold_position(m, d, watch, TOUCH_SETTLE)
        marks.append((float(point[0]), float(point[1])))
        touched.append(_tool_in_base(arm, m, d)[:2])
    arm.move_to_pose(m, d, watch, *park)
    base, residuals = registered_base(arm.name, arm.base.side, marks, touched)
    residuals_mm = tuple(float(r) * 1e3 for r in residuals)
    rms = math.sqrt(sum(r * r for r in residuals_mm) / len(residuals_mm))
    registration = Registration(arm.name, base, residuals_mm, rms)
    check_registration(registration)
    return registration


def register_arms(m, d, watch, arms, bases, marks, parks, register: str
                  ) -> tuple[tuple[ArmBase, ArmBase], list[Registration]]:
    """The bases to plan with and the registrations: each arm touches its marks in turn.

    Args:
        m: the model.
        d: its data.
        watch: the arms' ``ArmDistanceWatch``.
        arms: the two ``SceneArm`` (on the true bases).
        bases: the nominal bases (planned with when ``register="nominal"``).
        marks: per arm, its marks in the world (:func:`register_by_touch`'s ``points``).
        parks: per arm, (configuration, duration) of its park pose.
        register: one of :data:`REGISTRATIONS`.
    """
    check_register_option(register)
    if register == "nominal":
        return tuple(bases), []
    registrations = [register_by_touch(m, d, watch, arm, points, park)
                     for arm, points, park in zip(arms, marks, parks, strict=True)]
    return (registrations[0].base, registrations[1].base), registrations


def check_registration(registration: Registration,
                       bound_mm: float = MAX_REGISTRATION_RMS_MM) -> None:
    """Refuse, in one line, a registration whose RMS residual is above ``bound_mm``.

    Raises:
        PlanError: the arm, the RMS, the worst point, the bound and the fix.
    """
    if registration.rms_mm <= bound_mm:
        return
    worst = max(registration.residuals_mm)
    raise PlanError(f"the {registration.arm} arm's registration residual is "
                    f"{registration.rms_mm:.2f} mm RMS (worst {worst:.2f} mm), above "
                    f"{bound_mm:g} mm: a touch missed its mark or the board moved. Fix: "
                    "tape the board down and touch the marks again (or --register nominal).")


def check_touch_reach(bases, marks, names, fix: str) -> None:
    """Refuse, before anything moves, a registration mark out of its arm's reach.

    Args:
        bases: the two (nominal) bases.
        marks: per arm, its marks in the world.
        names: per arm, the marks' names for the message (e.g. "b3", "square 0").
        fix: the message's fix ("Fix: ...").

    Raises:
        PlanError: one line: the arm, the mark, the fix.
    """
    for base, points, labels in zip(bases, marks, names, strict=True):
        for point, label in zip(points, labels, strict=True):
            try:
                get_inverse_kinematics(base_from_world(base, (point[0], point[1], TOUCH_HEIGHT)),
                                       approach="down", yaw_deg=0.0)
            except UnreachableError:
                raise PlanError(f"the {base.name} arm cannot touch its registration mark "
                                f"{label}. {fix}") from None
