"""The virtual STS3215's electrical and thermal model: Present_Current, _Temperature, _Voltage.

A simple model, documented so that a student can predict what the registers show:

- **Current** follows the actuator's effort: ``I = STALL_CURRENT_MA * |load| / 1000``,
  ``load`` being Present_Load (0.1 % of the stall torque, what the simulated
  actuator pushes). Present_Current counts ``CURRENT_UNIT_MA`` (6.5 mA) a unit,
  as on the STS3215. A limp servo draws nothing: its driver is off, so a joint
  moved by gravity or a hand back-drives the motor into an open circuit; only an
  EMF above the supply plus the driver's two body diodes would push current back
  (:func:`limp_current`). By hand, the fastest fall: the shoulder's 0.86 N m of
  gravity against 0.61 N m s/rad of damping (BAM) falls at 1.4 rad/s, an EMF of
  1.2116 N m/A x 1.4 rad/s = 1.7 V, well below a 5 V supply plus 1.4 V.
- **Reading noise** (seeded): while the driver drives, Present_Current reads
  its mean plus up to ``CURRENT_FLICKER`` unit either way (roboninecom's
  telemetry, STS3215 at rest holding a few % of duty, 10 Hz reads: 0, 1, 2, 1, 0
  units at a steady 4 % duty; 2, 2, 3, 2 at 6.4 %; a constant 0 with the duty 0);
  Present_Voltage flickers by a unit (0.1 V) on about one reading in three
  (``VOLTAGE_FLICKER``: a choice, no public log of it at rest; the same servo's
  temperature register flickers by one unit, 35/36 degC, in that telemetry).
- **Temperature** is a first-order thermal body: its resting value is the
  ambient temperature plus a rise proportional to the copper losses,
  ``AMBIENT_C + STALL_RISE_C * (I / I_stall) ** 2``, reached with the time
  constant ``thermal_time_s`` (default ``THERMAL_TIME_S``). A servo pushing at
  stall torque heats towards 25 + 80 = 105 degC (crossing the 70 degC limit
  after 0.83 time constants, 99 s by default); at rest it cools back to
  the ambient temperature. Present_Temperature is in degC.
- **Voltage** is the supply's minus the drop of the whole bus's current over
  the supply's internal resistance: ``V = supply - SUPPLY_RESISTANCE_OHM * sum(I)``;
  Present_Voltage counts 0.1 V.
- **Error bits** (status byte and Status register, as the STS3215 sets them):
  overheat (0x04) while Present_Temperature > Max_Temperature_Limit;
  voltage (0x01) while Present_Voltage is outside [Min_Voltage_Limit,
  Max_Voltage_Limit]; overload (0x20) once |Present_Load| has stayed at or above
  Overload_Torque (percent) for Protection_Time (10 ms a unit). With the overload
  protection on (Unloading_Condition bit 5, the factory value) the servo then drives at
  most Protective_Torque, and the bit stays, until a new goal or a Torque_Enable write
  (``registers.ServoRegisters.protect``); with it off the bit clears when the load drops.
  Injected faults (``arm.parse_faults``) add their bits on top.

Example::

    >>> current_units(1000)  # stall: 2.7 A
    415
    >>> round(next_temperature(25.0, 1000, dt=120.0, time_constant=120.0), 1)  # one tau
    75.6
    >>> voltage_units(12.0, [0.0] * 6)
    120
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from so101_kinematics.servo import DEFAULT_SUPPLY_V
from so101_kinematics.virtual.protocol import ERR_OVERHEAT, ERR_OVERLOAD, ERR_VOLTAGE

__all__ = [
    "AMBIENT_C", "CURRENT_FLICKER", "SUPPLY_RESISTANCE_OHM", "SUPPLY_V", "THERMAL_TIME_S",
    "VOLTAGE_FLICKER", "current_units", "limp_current", "next_temperature", "noisy_reading",
    "status_bits", "voltage_units",
]

CURRENT_UNIT_MA = 6.5  # [mA] one unit of Present_Current (STS3215)
STALL_CURRENT_MA = 2700.0  # [mA] current at stall torque (12 V STS3215)
AMBIENT_C = 25.0  # [degC]
STALL_RISE_C = 80.0  # [K] steady-state rise above ambient at stall torque
THERMAL_TIME_S = 120.0  # [s] thermal time constant of a servo
SUPPLY_V = DEFAULT_SUPPLY_V
"""[V] The virtual arm's supply by default: the course's follower's, 12 V (its servos then
default to the 12 V C018; ``servo.DEFAULT_SUPPLY_V``, docs/servo_model.md says why). The kit's
5 V C001 arm is ``supply=servo.KIT_SUPPLY_V`` (``virtual_so101.py --supply 5``)."""
SUPPLY_RESISTANCE_OHM = 0.1  # [ohm] supply + cable internal resistance
DIODE_DROP_V = 0.7  # [V] one MOSFET body diode of the H-bridge, conducting
CURRENT_FLICKER = 1.0
"""Present_Current's noise: a reading is the mean plus a uniform value in +-1 unit, rounded
(roboninecom/Measuring-Backlash-in-Popular-UART-Servos, logs/motor_telemetry_single.csv: a servo
holding at a steady 4 % duty reads 0-2 units, at 6.4 % 2-3)."""
VOLTAGE_FLICKER = 0.75
"""Present_Voltage's noise [0.1 V]: the mean plus a uniform value in +-0.75, rounded: one
reading in three a unit off (a choice; see the module docstring)."""


def current_ma(load: float) -> float:
    """Current [mA] drawn for an effort of ``load`` (Present_Load units, 0.1 % of stall)."""
    return STALL_CURRENT_MA * min(1000.0, abs(load)) / 1000.0


def current_units(load: float) -> int:
    """Present_Current (6.5 mA units) for an effort of ``load`` (0.1 % of stall)."""
    return round(current_ma(load) / CURRENT_UNIT_MA)


def limp_current(emf: float, supply: float, resistance: float) -> float:
    """A limp (driver off) motor's current [A], back-driven at an EMF of ``emf`` [V].

    The bridge is open: current flows back through two body diodes into the supply only
    when the EMF exceeds the supply plus their drops.

    >>> limp_current(1.5, 5.0, 2.676)
    0.0
    >>> round(limp_current(7.4, 5.0, 2.676), 3)
    0.374
    """
    return max(0.0, abs(emf) - supply - 2 * DIODE_DROP_V) / resistance


def noisy_reading(value: float, rng, flicker: float) -> int:
    """A register reading of ``value`` [units] with a uniform noise of +-``flicker`` units."""
    return max(0, round(value + rng.uniform(-flicker, flicker)))


def next_temperature(temperature: float, load: float, dt: float,
                     time_constant: float = THERMAL_TIME_S) -> float:
    """Temperature [degC] after ``dt`` [s] at an effort of ``load`` (exact first-order step)."""
    fraction = min(1000.0, abs(load)) / 1000.0
    target = AMBIENT_C + STALL_RISE_C * fraction * fraction
    return target + (temperature - target) * math.exp(-dt / time_constant)


def voltage_units(supply: float, loads: Iterable[float]) -> int:
    """Present_Voltage (0.1 V units) with the bus's servos at efforts ``loads``."""
    total_a = sum(current_ma(load) for load in loads) / 1000.0
    return max(0, min(255, round(10.0 * (supply - SUPPLY_RESISTANCE_OHM * total_a))))


def status_bits(temperature: float, voltage: int, overloaded: bool, max_temperature: int,
                voltage_range: tuple[int, int]) -> int:
    """The model's status error bits (overheat, voltage, overload) from the servo's state."""
    bits = 0
    if temperature > max_temperature:
        bits |= ERR_OVERHEAT
    if not voltage_range[0] <= voltage <= voltage_range[1]:
        bits |= ERR_VOLTAGE
    if overloaded:
        bits |= ERR_OVERLOAD
    return bits
