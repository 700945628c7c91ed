"""lerobot's camera type ``so101_virtual``: a virtual SO-101's camera (``virtual_so101.py --camera``).

lerobot's own ``OpenCVCamera`` cannot open the virtual arm's stream as given on the command
line: its ``index_or_path`` is typed ``int | Path``, and ``Path("http://127.0.0.1:PORT/x")``
turns the ``//`` into ``/``; given in Python it opens, but a configured ``fps`` (which
``lerobot-record`` needs) is refused because a network stream cannot be set to a rate. This
type takes the address as a string and checks the stream's size instead of setting it::

    lerobot-record --robot.type=so101_follower --robot.port=/dev/pts/3 \\
        --robot.discover_packages_path=lerobot_camera_so101_virtual \\
        --robot.cameras="{front: {type: so101_virtual, address: 'http://127.0.0.1:PORT/overhead.mjpg', width: 640, height: 480, fps: 30}}" ...

lerobot imports third-party packages whose *distribution* name starts with
``lerobot_camera_``; this one ships inside ``so101-kinematics``, so a lerobot command is told
to import it (``--robot.discover_packages_path=lerobot_camera_so101_virtual``) and Python code
imports it before building the cameras.
"""

from lerobot_camera_so101_virtual.camera_so101_virtual import SO101VirtualCamera
from lerobot_camera_so101_virtual.configuration_so101_virtual import SO101VirtualCameraConfig

__all__ = ["SO101VirtualCamera", "SO101VirtualCameraConfig"]
