"""The virtual lab's cube sensor on the wire: a read-only device only the virtual arm has.

A real SO-101 cannot tell where the cube is; the virtual arm can. It answers a
protocol-0 READ addressed to :data:`SENSOR_ID` (never a PING, so lerobot's
scans and motor checks do not see it) with :data:`SIZE` bytes: the cube's
centre in the base frame [0.1 mm] as three signed 16-bit values, its tilt from
upright [0.1 deg], and flags (bit 0: there is a cube, bit 1: it is in the
jaws). A virtual arm with several cubes answers for its cube ``k`` (0, 1, ...,
in the order they were given) at address :func:`address` ``(k)`` = ``k * SIZE``,
and with "no cube" past the last one. On a real arm nothing answers, and the
hardware script says nothing about the cube. The layout lives here, in
``sensors/`` (which every backend may import), because both backends speak it;
the sensor a program reads is ``sensors/cube_reader.py``.

Example:
    >>> decode(encode((0.2291, -0.1912, 0.013), 1.5, held=False))
    CubeReading(position_m=(0.2291, -0.1912, 0.013), tilt_deg=1.5, held=False)
"""

from __future__ import annotations

import struct
from typing import NamedTuple

__all__ = [
    "CubeReading", "MAX_CUBES", "SENSOR_ID", "SIZE", "address", "decode", "encode",
    "encode_absent", "index_of",
]

SENSOR_ID = 100
"""Bus ID of the cube sensor (no SO-101 servo uses it)."""
ADDRESS = 0
SIZE = 9
MAX_CUBES = 8
"""The most cubes the sensor reports (addresses 0 to ``(MAX_CUBES - 1) * SIZE``)."""
_FORMAT = "<hhhHB"
_PRESENT, _HELD = 0x01, 0x02


class CubeReading(NamedTuple):
    """The cube as the sensor saw it."""

    position_m: tuple[float, float, float]  # centre in the base frame [m]
    tilt_deg: float  # its up axis from the vertical [deg]
    held: bool  # between the jaws


def encode(position_m, tilt_deg: float, held: bool) -> bytes:
    """The sensor's reply data for a cube at ``position_m`` [m] (clamped to +-3.2 m)."""
    ticks = [max(-32767, min(32767, round(v * 1e4))) for v in position_m]
    tilt = max(0, min(65535, round(tilt_deg * 10)))
    return struct.pack(_FORMAT, *ticks, tilt, _PRESENT | (_HELD if held else 0))


def encode_absent() -> bytes:
    """The reply data when the virtual arm has no cube."""
    return struct.pack(_FORMAT, 0, 0, 0, 0, 0)


def decode(data: bytes) -> CubeReading | None:
    """The reading in ``data`` (``SIZE`` bytes), or None when there is no cube."""
    x, y, z, tilt, flags = struct.unpack(_FORMAT, bytes(data))
    if not flags & _PRESENT:
        return None
    return CubeReading((x / 1e4, y / 1e4, z / 1e4), tilt / 10, bool(flags & _HELD))


def address(index: int) -> int:
    """The sensor address of cube ``index`` (0 = the first cube)."""
    return ADDRESS + index * SIZE


def index_of(address_: int, size: int) -> int | None:
    """Which cube a READ of ``size`` bytes at ``address_`` asks for, or None (not a cube read)."""
    index, rest = divmod(address_ - ADDRESS, SIZE)
    return index if size == SIZE and rest == 0 and 0 <= index < MAX_CUBES else None
