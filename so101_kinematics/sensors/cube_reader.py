"""The virtual lab's cube sensor as a ``Sensor``: a cube's reading, read through any bus.

The sensor is a device on the arm's bus (``cube_wire.py``); how a block of bytes
is read from the bus is the backend's business, so :class:`CubeSensor` takes
that one operation, ``read_block(device_id, address, size) -> bytes | None``
(``hw.bus.read_block`` bound to a lerobot bus, or ``BusArm.read_block``). It
never keeps a reading: each :meth:`CubeSensor.read` asks the bus again (a
stale cube position would send the gripper where the cube was).

Example (a fake bus that answers with cube 0 at (0.2, 0.1, 0.013) m):
    >>> from so101_kinematics.sensors.cube_wire import encode
    >>> bus = lambda device, address, size: encode((0.2, 0.1, 0.013), 0.0, False)
    >>> CubeSensor(bus).read().position_m
    (0.2, 0.1, 0.013)
"""

from __future__ import annotations

from collections.abc import Callable

from so101_kinematics.errors import InputError
from so101_kinematics.sensors.cube_wire import (
    MAX_CUBES,
    SENSOR_ID,
    SIZE,
    CubeReading,
    address,
    decode,
)

__all__ = ["BlockReader", "CubeSensor", "read_cubes"]

BlockReader = Callable[[int, int, int], "bytes | None"]
"""``read_block(device_id, address, size)``: the bytes a device on the bus answered, or None."""


class CubeSensor:
    """Cube ``index`` (0: the first) as the virtual lab's sensor reports it (``interfaces.Sensor``).

    Args:
        read_block: the bus's block read (:data:`BlockReader`).
        index: which cube.
        name: the sensor's name (default ``"cube"``, ``"cube_2"``, ... as the scene's bodies).
    """

    def __init__(self, read_block: BlockReader, index: int = 0, name: str | None = None):
        if not 0 <= index < MAX_CUBES:
            raise InputError(f"cube index {index} is outside 0..{MAX_CUBES - 1} (the sensor "
                             f"reports at most {MAX_CUBES} cubes). Fix: pass 0 for the first.")
        self._read_block = read_block
        self.index = index
        self.name = name or ("cube" if index == 0 else f"cube_{index + 1}")

    def read(self) -> CubeReading | None:
        """The cube now (centre [m], tilt [deg], held); None: no cube, or no sensor (a real arm)."""
        data = self._read_block(SENSOR_ID, address(self.index), SIZE)
        return None if data is None or len(data) != SIZE else decode(data)

    def close(self) -> None:
        """Nothing to let go: the bus belongs to the arm."""

    def __repr__(self) -> str:
        return f"CubeSensor({self.name!r}, index={self.index})"


def read_cubes(read_block: BlockReader) -> list[CubeReading]:
    """Every cube the sensor reports, in order; empty on a real arm (one read that times out)."""
    cubes: list[CubeReading] = []
    while len(cubes) < MAX_CUBES:
        reading = CubeSensor(read_block, len(cubes)).read()
        if reading is None:
            break
        cubes.append(reading)
    return cubes
