"""Every error of the project, in one family.

``SO101Error`` is the base. Bad input (an argument, a plan, an option, a
file) is an :class:`InputError`, which is also a ``ValueError`` (and a
``TypeError`` where the type is wrong), so a scripting user can catch what
Python would raise; the command-line scripts turn it into one line and exit 2.
What goes wrong with the arm is a :class:`HardwareError` (a ``RuntimeError``).
Messages name the parameter or joint, the value, the allowed range and end
with "Fix: ...".
"""

from __future__ import annotations

__all__ = [
    "ARM_NOT_STARTED", "BusError", "CalibrationError", "CallShapeError", "ClearanceError",
    "ConnectionFailed",
    "CubePositionError", "FaultSpecError", "FreezeRequested", "HardwareError", "InputError",
    "JointLimitError", "KinematicsInputError", "KinematicsTypeError", "LerobotMissing",
    "MeshError", "NotConfirmed", "OpenCVMissing", "OutputPathError", "PlanError", "PortInUse",
    "PortLost",
    "RenderError", "RenderSettingError", "SO101Error", "ServoFault", "StalePoseError",
    "StopRequested", "TagNotInView", "TorqueLost", "TrackingError", "TrimError",
    "UnreachableError", "ViewerClosed", "VirtualSO101Error", "VisionError",
]


class SO101Error(Exception):
    """Base of every error raised by this project."""


class InputError(SO101Error, ValueError):
    """An input (argument, option, plan file, setting) is missing, malformed or out of range."""


# --- kinematics and plans ------------------------------------------------------------------
class KinematicsInputError(InputError):
    """An argument of a kinematics function is missing, not a number, or out of its range."""


class KinematicsTypeError(KinematicsInputError, TypeError):
    """An argument of a kinematics function has the wrong type (text, None, a boolean)."""


class PlanError(InputError):
    """A plan (waypoints, durations, options) is malformed or cannot be run."""


class CallShapeError(PlanError, TypeError):
    """A course function was called with its arguments in a shape it does not accept.

    The message names the shapes it does accept (e.g. ``hold_position(m, d, viewer,
    duration)`` or ``hold_position(m, d, viewer, cfg, duration)``). Also a ``TypeError``,
    what Python raises for a call with the wrong arguments.
    """


class JointLimitError(PlanError):
    """A configuration is outside the joint limits (the model's or the arm's calibration)."""


class ClearanceError(PlanError):
    """A configuration or a path would bring the arm into the table (``clearance.py``)."""


class UnreachableError(PlanError):
    """No configuration within the joint limits puts the object frame at the target.

    Attributes:
        reason: "below_table", "too_far", "too_close", "joint_limit",
            "no_convergence" or "orientation".
        distance: how far off the target is: [m] for the reach reasons, [deg]
            beyond the limit for "joint_limit", [deg] from the asked
            orientation for "orientation".
        joint: the joint at its limit for "joint_limit", else None.
    """

    def __init__(self, message: str, reason: str, distance: float, joint: str | None = None):
        super().__init__(message)
        self.reason = reason
        self.distance = distance
        self.joint = joint


class TrimError(InputError):
    """A trim (the course's "offset_config") names an unknown joint, is not a number or too big."""


class OutputPathError(InputError):
    """An output path cannot be written (a folder, not writable, or one of the inputs)."""


# --- simulation ---------------------------------------------------------------------------
class ViewerClosed(SO101Error):
    """The MuJoCo viewer window was closed by the user."""


class RenderError(SO101Error, RuntimeError):
    """Offscreen rendering or video writing failed."""


class RenderSettingError(RenderError, ValueError):
    """A rendering setting (size, fps, camera) is out of its range."""


class MeshError(SO101Error, RuntimeError):
    """The SO-101 meshes are missing or do not match their pinned hashes."""


# --- vision (issue 36) -------------------------------------------------------------------
class VisionError(SO101Error, RuntimeError):
    """A camera, a tag or an image cannot be used (``so101_kinematics/vision/``)."""


class OpenCVMissing(VisionError):
    """OpenCV (``cv2``, with its ``aruco`` module) is not installed: the hw extra brings it."""


class TagNotInView(VisionError):
    """A tag the program needs is not (wholly) in the camera's image: nothing moves."""


class StalePoseError(VisionError):
    """A seen pose is older than the age the arm may move on: look again before moving."""


# --- the real arm -------------------------------------------------------------------------
class HardwareError(SO101Error, RuntimeError):
    """Something about the real (or virtual) arm prevents the run."""


class CalibrationError(HardwareError, ValueError):
    """A lerobot calibration is missing, malformed or does not fit the arm.

    Both a :class:`HardwareError` (what the real arm's callers catch) and a
    ``ValueError`` (what the virtual arm's callers catch).
    """


class LerobotMissing(HardwareError):
    """lerobot (the ``hw`` extra) is not installed."""


class ConnectionFailed(HardwareError):
    """The port cannot be opened or a servo does not answer."""


ARM_NOT_STARTED = (CalibrationError, ConnectionFailed, LerobotMissing)
"""What refuses a run on an arm before anything moves: every arm script's bad input (one
line, exit 2) beside its own (``cli.run_script``'s ``refused``)."""


class PortInUse(ConnectionFailed):
    """Another program has the arm's port open."""


class PortLost(HardwareError):
    """The arm's USB connection was lost mid-run (the port vanished)."""

    @classmethod
    def during(cls, what: str) -> PortLost:
        """The error for a port that vanished during ``what``."""
        return cls(f"the arm's USB connection was lost during {what} (the port vanished). The "
                   "servos keep holding their last goal with torque on")


class TrackingError(HardwareError):
    """A joint stayed too far from its command for too long: a stall or a collision."""


class BusError(HardwareError):
    """The arm went unobserved for longer than the outage tolerance during motion."""


class ServoFault(HardwareError):
    """A servo reported an error bit (overload, overheating, voltage) during motion."""


class TorqueLost(ServoFault):
    """A servo's Torque_Enable read back 0 while the loop commanded it: its joint is limp.

    A brown-out of the servo power, or another program that released it.
    """


class StopRequested(HardwareError):
    """A stop was requested (Ctrl-C, SIGTERM, SIGHUP) and honoured at the next control cycle."""


class FreezeRequested(KeyboardInterrupt):
    """A second stop signal: freeze at once where the arm is, torque on (no return)."""


class NotConfirmed(HardwareError):
    """The user did not confirm (or could not be asked)."""


# --- the virtual arm ----------------------------------------------------------------------
class VirtualSO101Error(SO101Error, RuntimeError):
    """The virtual arm could not start or answer."""


class FaultSpecError(InputError):
    """A fault specification does not follow the grammar."""


class CubePositionError(InputError):
    """A cube position for the virtual arm is malformed or off the table."""
