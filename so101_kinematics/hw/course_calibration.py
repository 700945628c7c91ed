"""The course's ``load_calibration`` on the arm, and how the course's helpers refuse.

A robot id (where lerobot keeps its calibration) or a calibration JSON file; a
refusal before anything moved is one line and exit status 2 (:class:`ScriptEnded`).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from so101_kinematics.calibration import find_calibration, load_calibration
from so101_kinematics.errors import CalibrationError, SO101Error

if TYPE_CHECKING:
    from so101_kinematics.hw.run import RunResult

__all__ = ["ScriptEnded", "course_load_calibration", "refuse"]


class ScriptEnded(SystemExit):
    """The helpers ended the script; ``line`` (printed to stderr) says why and how the arm is left.

    A ``SystemExit``: the script stops there without a traceback, with exit
    status ``code`` (2: refused, nothing moved; 1: a fault's ending ran).
    ``result`` is the run's ``hw/run.py`` ``RunResult`` after a fault (else None).
    """

    def __init__(self, code: int, line: str, result: RunResult | None = None):
        super().__init__(code)
        self.line = line
        self.result = result


class CourseCalibration(dict):
    """A loaded calibration (joint -> ServoCalibration) that remembers where it came from."""

    source: Path | None = None
    robot_id: str | None = None


def refuse(error: BaseException, prefix: str = "Refused, nothing moved") -> ScriptEnded:
    """The one-line refusal of ``error``, printed; raise what it returns.

    ``prefix`` says what did not happen: "nothing moved" is true only before the first move
    (a write refused later says that write moved nothing; the run's ending follows).
    """
    line = f"{prefix}: " + " ".join(str(error).split())
    print(line, file=sys.stderr, flush=True)
    return ScriptEnded(2, line)


def course_load_calibration(robot_name_or_path: str | os.PathLike) -> CourseCalibration:
    """The calibration of a robot id (where lerobot keeps it) or of a calibration JSON file.

    Raises:
        ScriptEnded: no such robot id or file, or a malformed calibration (one line, exit 2).
    """
    try:
        if not isinstance(robot_name_or_path, (str, os.PathLike)) or not str(robot_name_or_path):
            raise CalibrationError(
                f"load_calibration needs a robot id (the --robot.id given to lerobot-calibrate) "
                f"or a calibration JSON path, got {robot_name_or_path!r}. Fix: e.g. "
                "load_calibration(\"follower-1\").")
        text = os.fspath(robot_name_or_path)
        is_path = text.endswith(".json") or os.sep in text or Path(text).is_file()
        robot_id = None if is_path else text
        path = Path(text) if is_path else find_calibration(text)
        calibration = CourseCalibration(load_calibration(path, robot_id))
    except SO101Error as error:
        raise refuse(error) from None
    calibration.source, calibration.robot_id = path, robot_id
    return calibration
