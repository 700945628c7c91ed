"""Vision: the cameras, the ArUco tags and the one path from an image to a pose in the base frame.

A layer above ``sim/`` and the core (docs/architecture.md): ``camera_model`` (intrinsics and
the one OpenCV <-> MuJoCo camera-frame flip), ``sim_camera`` (the simulator's cameras as
``interfaces.Camera``), ``tags`` (the tags' facts, textures and printable images),
``tagged_scene`` (the course's scene with them), ``detect`` (detection and pose for any
image). OpenCV is imported only inside the functions that need it (``opencv_import``), so
every module imports without it.
"""

__all__: list[str] = []
