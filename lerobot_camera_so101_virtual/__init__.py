"""lerobot's camera type ``so101_virtual``: a camera of ``virtual_so101.py --camera NAME``.

lerobot's own ``OpenCVCamera`` cannot open the virtual arm's stream as given on the command
line: its ``index_or_path`` is typed ``int | Path``, and ``Path("http://127.0.0.1:PORT/x")``
turns the ``//`` into ``/``; given in Python it opens, but only without ``width``,
``height`` and ``fps`` (which a robot's recording needs): it sets them on the capture, which a
network stream refuses ("failed to set capture_width=640 (actual_width=640)"). This type
takes the address as a string and checks the stream's size instead of setting it::

    lerobot-record --robot.type=so101_follower --robot.port=/dev/pts/3 ...
        --robot.discover_packages_path=lerobot_camera_so101_virtual
        --robot.cameras="{front: {type: so101_virtual, width: 640, height: 480, fps: 30,
                                  address: 'http://127.0.0.1:PORT/overhead.mjpg'}}"

lerobot imports third-party packages whose *distribution* name starts with
``lerobot_camera_``; this one ships inside ``so101-kinematics``, so a lerobot command is told
to import it (``--robot.discover_packages_path=lerobot_camera_so101_virtual``) and Python code
imports it before building the cameras.
"""

from lerobot_camera_so101_virtual.camera_so101_virtual import SO101VirtualCamera
from lerobot_camera_so101_virtual.configuration_so101_virtual import SO101VirtualCameraConfig

__all__ = ["SO101VirtualCamera", "SO101VirtualCameraConfig"]
