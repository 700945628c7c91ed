"""The STS3215 servo as measured: its numbers, its registers' meaning and its static law.

Every backend needs these facts: the simulator and the virtual arm step the
servo's dynamics on them (``sim/sts3215.py``), the real-arm path offsets its
goals by the sag they predict (``gravity.py``). No MuJoCo, no lerobot here.

Sources, with their numbers (the one list this repository cites for the servo):

- [BAM] Rhoban's identified STS3215 model (repository Rhoban/bam,
  ``bam/feetech/actuator.py``, ``bam/params/feetech_sts3215_7_4V/m1.json``):
  duty = clip(0.166 P e, +-0.97) with e in [rad]; kt = 1.2116 N m/A,
  R = 2.676 ohm; Coulomb friction 0.0524 N m, viscous 0.0591 N m s/rad,
  reflected rotor inertia 0.0284 kg m^2; the target rate-limited to 3400 counts/s.
- [TEL] roboninecom, Measuring-Backlash-in-Popular-UART-Servos (telemetry logs and
  paper): at rest, Present_Load [0.1 % duty] = Minimum_Startup_Force +
  (P / 4) (|e| - dead zone) with e in counts (P / 4 per count is 0.163 P per rad:
  BAM's 0.166 within 2 %); the triangular motion profile; Present_Velocity in
  steps of 50 counts/s; backlash 0.62 deg unloaded through the servo's encoder.
- [MEM] Feetech's STS memory table (and lerobot's ``motors/feetech/tables.py``):
  register addresses and units.
- [LR] lerobot (``motors/feetech/feetech.py``, ``robots/so_follower``): what it
  writes: P = 16, D = 32, I = 0, Acceleration = 254, gripper Max_Torque_Limit 500.
- [DS] Feetech's datasheets: C001 (7.4 V) stall 1.91 N m, 52 rpm; C018 (12 V)
  stall 2.94 N m, 45 rpm, stall current 2.7 A.

The firmware's loop works in encoder counts; this module does too, and
converts at its edge with :data:`COUNTS_PER_RAD`.

Example (the shoulder's stiffness at lerobot's P = 16)::

    >>> round(stiffness(LEROBOT, 7.4), 2)  # [N m/rad] at 7.4 V
    8.74
    >>> round(stiffness(LEROBOT, 5.0), 2)  # the kit's 5 V supply
    5.9
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

__all__ = [
    "ACCELERATION_UNIT", "BACKLASH_DEG", "COUNTS_PER_RAD", "COUNTS_PER_TURN", "CURRENT_UNIT_A",
    "DEFAULT_SUPPLY_V", "DEFAULT_VARIANT", "DUTY_MAX", "D_SCALE_S", "FACTORY", "I_RATE",
    "KIT_SUPPLY_V", "LEROBOT", "LEROBOT_GRIPPER", "LOOP_PERIOD_S", "MIN_VOLTS", "Settings",
    "TARGET_RATE_MAX", "VARIANTS", "VELOCITY_STEP", "default_variant", "duty", "holding_error",
    "lag", "stiffness", "supply_problem",
]

COUNTS_PER_TURN = 4096
"""The encoder's positions in one turn [MEM] (lerobot's ``max_res`` 4095 is this less one):
the one home of the STS3215's resolution."""

COUNTS_PER_RAD = COUNTS_PER_TURN / (2 * math.pi)
"""Encoder counts per radian [MEM]."""

DUTY_MAX = 970
"""Largest duty the firmware applies [0.1 %]: BAM's 0.97, measured with an oscilloscope."""

TARGET_RATE_MAX = 3400.0
"""Fastest the firmware moves its internal target [counts/s] [BAM]; Goal_Velocity 0 means this."""

ACCELERATION_UNIT = 100.0
"""One unit of the Acceleration register [counts/s^2] [MEM, TEL]; 0 means no ramp."""

VELOCITY_STEP = 50
"""Present_Velocity comes in multiples of this [counts/s] [TEL]."""

CURRENT_UNIT_A = 0.0065
"""One unit of Present_Current [A] [MEM]."""

LOOP_PERIOD_S = 0.001
"""The firmware's loop period [s]. An ASSUMPTION (undocumented); it no longer sets the D
term's scale (``D_SCALE_S`` does, fitted)."""

D_SCALE_S = 0.03
"""The D term's scale [s]: D acts as P does (D / 4 of duty per count) on the error's rate
[counts/s] times this. FITTED to two real SO-101 recordings (``docs/servo_model.md``,
``so101_kinematics/lab/replay.py``): the firmware's scale is undocumented, and the first
guess (one 1 ms loop period) left the loop underdamped: steps from rest overshot 0.4-2.5 deg
where the recorded arms overshoot 0.00-0.07 deg. At P 16 / D 32 on 12 V this adds about
0.46 N m s/rad of damping while the servo is torqued (the motor's own back-EMF: 0.49)."""

I_RATE = 10.0
"""The I term's scale: I acts as P does on the error integrated over 1 / I_RATE s. An
ASSUMPTION: with it, lerobot PR #4310's residual at P = 48 (1.45 deg) goes at I = 4 within
seconds, as measured; the firmware's own scale is undocumented."""

BACKLASH_DEG = 0.62
"""Gear play [deg] measured through the servo's own encoder, unloaded [TEL] (1.30 loaded).
Modelled as play the motor's push crosses before it reaches the joint: the push is computed
on the error less half the play (``sim/sts3215.py``); Present_Load is the firmware's duty."""


VARIANTS_DIR = Path(__file__).resolve().parent / "servo_variants"
"""The variants' data files, one JSON per variant, each naming its sources: a motor
identified (``motor``: kt, R) or a datasheet's stall torque, no-load speed and stall current
(``datasheet``); the gearbox's friction and inertia (``gearbox``, or ``gearbox_from`` another
variant). :data:`VARIANTS` is read from them, and the command line's ``--variant`` choices."""


def _read_variant_files() -> dict[str, dict]:
    """Each variant file's contents by its ``name``, in name order."""
    found = {}
    for path in sorted(VARIANTS_DIR.glob("*.json")):
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("name") != path.stem or not data.get("source"):
            raise ValueError(f"{path}: a variant file names itself (name {path.stem!r}) and "
                             "its source. Fix: add the missing name or source.")
        found[data["name"]] = data
    return dict(sorted(found.items()))


_VARIANT_FILES = _read_variant_files()
_GEARBOX = _VARIANT_FILES["C001"]["gearbox"]  # BAM's, identified (C001.json)


@dataclass(frozen=True)
class Variant:
    """An STS3215 variant's motor, reflected to the output shaft.

    Attributes:
        name: the variant's name.
        nominal_volts: its rated supply [V].
        torque_per_volt: torque per volt of motor voltage at stall, kt / R [N m/V].
        emf_damping: the back-EMF's damping kt^2 / R [N m s/rad].
        kt: torque constant [N m/A] (Present_Current).
        coulomb: Coulomb friction [N m]; viscous: viscous friction [N m s/rad];
            armature: reflected rotor inertia [kg m^2] (by default BAM's, the same 1/345
            gearbox: ``servo_variants/C001.json``).
        source: where the numbers come from.
        max_volts: the highest supply it takes [V]: its Max_Voltage_Limit as shipped [MEM].
    """

    name: str
    nominal_volts: float
    torque_per_volt: float
    emf_damping: float
    kt: float
    coulomb: float = _GEARBOX["coulomb_nm"]
    viscous: float = _GEARBOX["viscous_nm_s_per_rad"]
    armature: float = _GEARBOX["armature_kg_m2"]
    source: str = ""
    max_volts: float = 14.0

    def no_load_speed(self, volts: float) -> float:
        """Speed [rad/s] at full duty with no load: the motor's torque spent on friction."""
        drive = self.torque_per_volt * volts * DUTY_MAX / 1000.0 - self.coulomb
        return max(0.0, drive) / (self.emf_damping + self.viscous)

    def stall_torque(self, volts: float) -> float:
        """Torque [N m] at the firmware's full duty (0.97), at rest."""
        return self.torque_per_volt * volts * DUTY_MAX / 1000.0


def _variant(data: dict) -> Variant:
    """A :class:`Variant` from its file's ``data``.

    Identified (``motor``): kt / R and kt^2 / R. From a datasheet: kt / R = stall / volts;
    the damping is what leaves the no-load speed at the datasheet's rpm with the gearbox's
    friction; kt = stall / stall current (or ``kt_from`` another variant's motor).
    """
    gearbox = _VARIANT_FILES[data.get("gearbox_from", data["name"])]["gearbox"]
    friction = {"coulomb": gearbox["coulomb_nm"], "viscous": gearbox["viscous_nm_s_per_rad"],
                "armature": gearbox["armature_kg_m2"]}
    volts, about = data["nominal_volts"], {"source": data["source"],
                                           "max_volts": data["max_volts"]}
    if "motor" in data:
        kt, resistance = data["motor"]["kt_nm_per_a"], data["motor"]["resistance_ohm"]
        return Variant(data["name"], volts, kt / resistance, kt ** 2 / resistance, kt,
                       **friction, **about)
    sheet = data["datasheet"]
    stall = sheet["stall_torque_nm"]
    kt = (stall / sheet["stall_current_a"] if "stall_current_a" in sheet
          else _VARIANT_FILES[data["kt_from"]]["motor"]["kt_nm_per_a"])
    per_volt = stall / volts
    drive = per_volt * volts * DUTY_MAX / 1000.0 - friction["coulomb"]
    damping = drive / (sheet["no_load_rpm"] * 2 * math.pi / 60) - friction["viscous"]
    return Variant(data["name"], volts, per_volt, damping, kt, **friction, **about)


VARIANTS = {name: _variant(data) for name, data in _VARIANT_FILES.items()}
"""The variants, by name (the registry: ``servo_variants/*.json``): the kit's C001 (BAM's
numbers, or its datasheet's, 1.75x weaker; tested both ways) and the 12 V C018, the
project's default."""

MIN_VOLTS = 4.0
"""The lowest supply an STS3215 runs on [V]: its Min_Voltage_Limit as shipped, 40 [MEM]
(below it the servo sets the voltage bit); the highest is each variant's ``max_volts``."""

KIT_SUPPLY_V = 5.0
"""The standard SO-101 kit's supply [V] for its C001 servos (SO-ARM100 README, issue #36)."""

DEFAULT_SUPPLY_V = 12.0
"""The follower's supply by default [V]: the course's (ECE4560 assignment 3: "You will need to
use the 12V power supply with the follower arm"); its servos are 12 V C018s. The two real
arms' recordings are reproduced best by this servo (docs/servo_model.md)."""

SIMULATED_SERVOS = ("sts3215", "ideal")
"""The servos the simulator offers (``--servo``): this module's measured STS3215, or the
upstream model's stiff ideal position servo (``sim/actuation.py``)."""

DEFAULT_VARIANT = "C018"
"""The variant by default: the 12 V SO-101 follower's (docs/servo_model.md)."""


def supply_problem(variant: str, volts: float) -> str | None:
    """Why ``volts`` [V] does not suit ``variant`` (one line with the fix), or None if it does."""
    chosen = VARIANTS[variant]
    if volts <= chosen.max_volts:
        return None
    return (f"supply {volts:g} V is above the {variant}'s Max_Voltage_Limit "
            f"{chosen.max_volts:g} V (it would cut its torque). Fix: give --variant C018 for "
            f"a 12 V supply, or --supply 5 or 7.4 for a {variant}.")


def default_variant(volts: float) -> str:
    """The variant a supply voltage implies: above 9 V only the 12 V C018 survives."""
    return "C018" if volts > 9.0 else "C001"


@dataclass(frozen=True)
class Settings:
    """The registers that shape one servo's loop [MEM] (names as lerobot's table).

    Attributes:
        p, d, i: P/D/I_Coefficient. min_startup: Minimum_Startup_Force [0.1 %].
        dead_zone: CW/CCW_Dead_Zone [counts]. acceleration: Acceleration [100 counts/s^2].
        goal_velocity: Goal_Velocity [counts/s] (0: the fastest). torque_limit:
        Torque_Limit [0.1 % duty].
    """

    p: int = 16
    d: int = 32
    i: int = 0
    min_startup: int = 16
    dead_zone: int = 1
    acceleration: int = 254
    goal_velocity: int = 0
    torque_limit: int = 1000

    def with_(self, **changes) -> Settings:
        """A copy with ``changes``."""
        return replace(self, **changes)


LEROBOT = Settings()
"""What lerobot writes to a follower arm's servos [LR] (Goal_Velocity never written)."""

LEROBOT_GRIPPER = Settings(torque_limit=500)
"""lerobot's gripper: Max_Torque_Limit 500 (so Torque_Limit 500 from power-up) [LR]."""

FACTORY = Settings(p=32, d=32, i=0, acceleration=0)
"""A servo as shipped [MEM]: P 32, D 32, I 0, no acceleration ramp."""


def duty(error_counts: float, settings: Settings) -> float:
    """The firmware's static duty [0.1 %] at a position error [counts] (the [TEL] law).

    Zero inside the dead zone; outside it Minimum_Startup_Force plus P / 4 per count
    beyond the dead zone, capped by Torque_Limit and the firmware's 97 %.

    >>> duty(50, LEROBOT)  # 16 + 4 * 49
    212.0
    """
    size = abs(error_counts)
    if size <= settings.dead_zone:
        return 0.0
    value = settings.min_startup + settings.p / 4.0 * (size - settings.dead_zone)
    return math.copysign(min(value, settings.torque_limit, DUTY_MAX), error_counts)


def stiffness(settings: Settings, volts: float, variant: str = "C001") -> float:
    """The loop's linearised stiffness [N m/rad]: torque per radian of error, unsaturated."""
    return VARIANTS[variant].torque_per_volt * volts * settings.p / 4000.0 * COUNTS_PER_RAD


def holding_error(torque: float, settings: Settings, volts: float, variant: str = "C001",
                  backlash_deg: float = BACKLASH_DEG) -> float | None:
    """The error [rad] at which the servo holds ``torque`` [N m] at rest (the law inverted).

    The push needs ``|torque| / (kt/R V)`` of duty: the dead zone, then the startup
    force, then P / 4 per count; half the backlash comes on top (the motor crosses the
    play first). The sign is the torque's (the joint sits on the load's side of the goal
    when ``torque`` is what gravity asks of the servo). Friction is left out: it widens
    the rest band by ``coulomb / stiffness`` either way.

    Returns:
        The error [rad], or ``None`` when the torque is beyond what the duty cap gives.
    """
    if torque == 0.0:
        return 0.0
    needed = abs(torque) / (VARIANTS[variant].torque_per_volt * volts) * 1000.0  # [0.1 %]
    if needed > min(settings.torque_limit, DUTY_MAX):
        return None
    counts = settings.dead_zone + max(0.0, needed - settings.min_startup) * 4.0 / settings.p
    counts += math.radians(backlash_deg) / 2 * COUNTS_PER_RAD
    return math.copysign(counts / COUNTS_PER_RAD, torque)


def lag(speed: float, settings: Settings, volts: float, variant: str = "C001") -> float:
    """How far [rad] the joint trails a goal moving at ``speed`` [rad/s], steady, unloaded.

    The push that balances the back-EMF and viscous damping at that speed, over the
    loop's stiffness (``stiffness``): 0.10 s of motion at P = 16 on 5 V.
    """
    chosen = VARIANTS[variant]
    return (chosen.emf_damping + chosen.viscous) * abs(speed) / stiffness(settings, volts, variant)
