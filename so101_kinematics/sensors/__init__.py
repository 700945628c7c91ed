"""Sensors beside the arm, behind ``interfaces.Sensor``: the cube sensor now, cameras next.

Every backend may import this folder (it imports only the core): the cube sensor's
layout on the wire (``cube_wire.py``), which the virtual arm answers and the hardware
path reads, and the sensor a program reads (``cube_reader.py``).
"""

__all__: list[str] = []
