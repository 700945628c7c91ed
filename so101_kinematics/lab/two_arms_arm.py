"""The tic-tac-toe game's plan on two arms through lerobot's bus: ``two_arms.py --ports A B``.

One program drives both arms, each through its own course helpers (``so101_utils``'s
``setup_motors``, ``move_to_pose``, ``hold_position``: ``hw/course_helpers.py``) on its own
port: the left arm (A) plays X, the right (B) O. Every move is planned exactly as the
simulator's game (``two_arms/two_arm_game.py``): the same ``move_steps`` in the moving arm's base
frame, the same release opening, the same park pose, and every planned path passes the same
shared-workspace rule (``shared_workspace.check_shared_path``) before it runs, against the
OTHER arm's joints as its servos read back. Then the moving arm runs it while the other
holds its last goal (a position-controlled servo holds by itself).

Read back as far as the arms can:

- the collisions: each control cycle's read-back joints of the moving arm (every 20 ms,
  as the simulator's watch) and the other arm's read-back, put into the two-arm model
  kinematically (``mj_kinematics``), the arms' distance measured and a touch counted by
  the simulator's own watch (``shared_workspace.ArmDistanceWatch``);
- the board: on virtual arms each arm's cube sensor (``sensors/``) reads its own pieces in
  its base frame; turned into the world and merged, they judge each move as the simulation
  does (``game_board.judge_move``, ``board_of``). A real arm has no cube sensor: the report
  says the board was not read back (``None``), never a figure it did not measure.

Each virtual arm is its own one-arm world holding only its own pieces (the cubes at the
supply positions of ``game_board.game_pieces``, in its base frame: :func:`virtual_arm_cubes`,
:func:`virtual_arm_commands`): the other arm's pieces on the board are not in it, so a
piece cannot be pushed by the other arm's pieces there (docs/final_project_two_arms.md).

Every ending is the project's one ending, for both arms: each arm back to its starting pose
(the pose it stood in at ``setup_motors``) and released there, or holding where it stopped,
each arm's line from its servos' read-back (``hw/run.ending``), and the last line both. A
fault on one arm (its ending runs in the course helpers) ends the other too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import mujoco

from so101_kinematics.constants import CUBE_HALF_SIZE
from so101_kinematics.errors import ClearanceError, ConnectionFailed, PlanError
from so101_kinematics.frames import JOINT_LIMITS, JOINTS
from so101_kinematics.hw.bus import clamp_to_limits, connect, disconnect, read_block, read_pose
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.hw.course_helpers import (
    course_hold_position,
    course_logged_move,
    end_arm,
    setup_motors,
)
from so101_kinematics.hw.timing import TimeSource
from so101_kinematics.sensors.cube_reader import read_cubes
from so101_kinematics.two_arms.game_board import GameBoard, board_of, game_pieces, judge_move
from so101_kinematics.two_arms.scene_arm import SceneArm
from so101_kinematics.two_arms.shared_workspace import ArmDistanceWatch, check_shared_path
from so101_kinematics.two_arms.tictactoe import EMPTY, full_game, winner
from so101_kinematics.two_arms.two_arm_game import (
    board_zone,
    check_board_reach,
    move_steps,
    park_pose,
)
from so101_kinematics.two_arms.two_arm_scene import (
    ArmBase,
    base_from_world,
    build_two_arm_model,
    check_bases,
    world_from_base,
)

__all__ = ["MARKS", "WATCH_PERIOD_S", "TwoArmRun", "check_ports", "play_on_arms",
           "virtual_arm_commands", "virtual_arm_cubes"]

MARKS = ("X", "O")
"""What each arm plays: the left (the first port) X, the right O (as the simulator's game)."""
WATCH_PERIOD_S = 0.02
"""[s] Between two measurements of the arms' distance along a move: the simulator's watch
(``shared_workspace.WATCH_EVERY`` physics steps of 4 ms)."""
PARK_FIRST_S = 3.0
"""[s] Each arm's move from where it stands to its park pose before the game, and back at
the end (the speed cap stretches a longer one: ``hw/timing.capped_duration``)."""


def _base_yaw(base: ArmBase) -> float:
    """[deg] A piece square to the world (as the game's are) in ``base``'s frame.

    Folded into [-45, 45) as ``two_arm_game.piece_yaw`` folds it (a cube every 90 deg).
    """
    return (-base.yaw + 45.0) % 90.0 - 45.0


def virtual_arm_cubes(bases: tuple[ArmBase, ArmBase]) -> list[list[tuple[float, float, float]]]:
    """Each arm's own pieces as its virtual arm's cubes: (x [m], y [m], yaw [deg]), its base frame.

    The supply positions of ``game_board.game_pieces`` (the simulator's game), in the order
    played: the cube sensor's index k is the arm's piece k + 1.
    """
    pieces = game_pieces(bases)
    cubes = []
    for base, mark in zip(bases, MARKS, strict=True):
        own = [p for p in pieces if p.name[0] == mark.lower()]
        cubes.append([(*(round(float(v), 4) for v in base_from_world(base, (p.x, p.y, 0.0))[:2]),
                       _base_yaw(base)) for p in own])
    return cubes


def virtual_arm_commands(bases: tuple[ArmBase, ArmBase]) -> list[str]:
    """The two commands that start the two virtual arms (left, then right).

    Each with its own pieces, powered up at its park pose (``--initial``): the virtual arm's
    default, the model's ``home``, reaches 0.24 m ahead, and two facing arms 0.46 m apart
    there overlap by 9 mm.
    """
    return ["python virtual_so101.py --initial "
            + " ".join(f"{park_pose(base)[j]:g}" for j in JOINTS) + " "
            + " ".join(f"--cube {x:g} {y:g} {yaw:g}" for x, y, yaw in own)
            for base, own in zip(bases, virtual_arm_cubes(bases), strict=True)]


@dataclass
class TwoArmRun:
    """How the game on the arms went: the report, each arm's last line, the last line, the code."""

    report: dict[str, Any]
    endings: dict[str, str]
    last_line: str
    code: int  # 0 played (completed or not), 1 a fault's or an error's ending, 130 interrupted

    @property
    def released(self) -> bool:
        """Both arms back at their starting pose, torque off (read back)."""
        return all(line.endswith("torque off.") for line in self.endings.values())


def check_ports(ports: Sequence[str]) -> None:
    """Refuse one port given for both arms, in one line (lerobot itself does not)."""
    if ports[0] == ports[1]:
        raise PlanError(f"--ports {ports[0]} {ports[1]}: one port for both arms (each arm needs "
                        "its own bus). Fix: give each arm its own port (virtual_so101.py prints "
                        "each virtual arm's).")


def _preflight(ports: Sequence[str], calibrations: Sequence[Mapping]) -> None:
    """Both ports answer with their arm and its calibration, before either is torqued.

    Raises:
        PlanError: one line naming the port (nothing moved).
    """
    for name, port, calibration in zip(("left", "right"), ports, calibrations, strict=True):
        try:
            disconnect(connect(port, calibration))
        except ConnectionFailed as error:  # a calibration mismatch is refused as it comes
            reason = " ".join(str(error).split())
            fix = "" if "Fix:" in reason else (" Fix: give each arm its own port "
                                               "(virtual_so101.py prints a virtual arm's).")
            raise PlanError(f"--ports {' '.join(ports)}: the {name} arm's port {port}: "
                            f"{reason}{fix}") from None


class _Arms:
    """The two arms on their buses, their model for the checks, and how far apart they came."""

    def __init__(self, bases, buses, starts):
        self.buses, self.starts, self.moving = buses, starts, 0
        self.m = build_two_arm_model(bases)
        self.plan_d, self.scratch, self.live = (mujoco.MjData(self.m) for _ in range(3))
        self.arms = tuple(SceneArm(self.m, base) for base in bases)
        self.watch = ArmDistanceWatch(self.m, self.live, self.arms)
        self.least_planned = math.inf
        self.measured = 0  # the arms' distances measured along the moves

    def read(self, k: int) -> dict[str, float]:
        """Arm ``k``'s joints as its servos read back, within the model's range."""
        return clamp_to_limits(read_pose(self.buses[k].raw, 2), JOINT_LIMITS)

    def _pose(self, d: mujoco.MjData, k: int, cfg: Mapping[str, float]) -> None:
        arm = self.arms[k]
        arm.send_position_command(d, cfg)
        d.qpos[arm.qpos_addresses] = d.ctrl[arm.actuators]

    def start(self, k: int) -> None:
        """A move of arm ``k`` starts from where it stands (as ``guarded.resync`` does)."""
        self._pose(self.plan_d, k, self.read(k))

    def move(self, k: int, cfg: Mapping[str, float], duration: float, hold: float,
             zone, what: str) -> None:
        """Check the path against the other arm's read-back, run it, watch the arms' distance."""
        arm, other = self.arms[k], self.arms[1 - k]
        self.moving = k
        held = self.read(1 - k)
        self._pose(self.plan_d, 1 - k, held)
        rows = arm.path(self.m, self.plan_d, cfg, duration)
        self.least_planned = min(self.least_planned, check_shared_path(
            self.m, self.scratch, arm, other, rows, self.plan_d.ctrl[other.actuators], zone, what))
        cycles = course_logged_move(self.buses[k], cfg, duration)
        arm.send_position_command(self.plan_d, cfg)
        self._pose(self.live, 1 - k, held)
        due = -math.inf
        for cycle in cycles:
            if cycle.measured is not None and cycle.t_s >= due:
                due = cycle.t_s + WATCH_PERIOD_S
                self._pose(self.live, k, clamp_to_limits(cycle.measured, JOINT_LIMITS))
                mujoco.mj_kinematics(self.m, self.live)
                self.watch.sync()
                self.measured += 1
        if hold:
            course_hold_position(self.buses[k], hold)


def _pieces_seen(buses, bases) -> dict[str, tuple]:
    """Each arm's pieces as its cube sensor reads them: name -> (centre in the world [m], tilt)."""
    seen = {}
    for bus, base, mark in zip(buses, bases, MARKS, strict=True):
        for k, cube in enumerate(read_cubes(lambda *block, b=bus: read_block(b.raw, *block))):
            seen[f"{mark.lower()}_{k + 1}"] = (world_from_base(base, cube.position_m),
                                               cube.tilt_deg)
    return seen


def _play(arms: _Arms, bases, board: GameBoard, pieces, opening: int, read_back: bool,
          moves: list) -> str:
    """Park both arms, then the game's moves, each planned, checked, run and read back."""
    zone, expected = board_zone(board), EMPTY
    try:
        for k in (0, 1):  # each to its park pose, one at a time, checked as every move
            arms.start(k)
            arms.move(k, park_pose(bases[k]), PARK_FIRST_S, 0.3, zone,
                      f"{bases[k].name} arm: from its starting pose to its park pose")
    except ClearanceError as error:  # where the arms stood: the fix is where they start
        raise ClearanceError(str(error).split(" Fix:")[0].rstrip(".") + ". Fix: start each arm "
                             "at its park pose (the virtual arms: the commands two_arms.py "
                             "--print-virtual-arms prints).") from None
    unused = {mark: [p for p in pieces if p.name[0] == mark.lower()] for mark in MARKS}
    seen = _pieces_seen(arms.buses, bases) if read_back else {}
    for mark, square in full_game(opening):
        k = MARKS.index(mark)
        base, piece = bases[k], unused[mark].pop(0)
        pick = seen[piece.name][0] if piece.name in seen else (piece.x, piece.y, CUBE_HALF_SIZE)
        steps = move_steps(base, pick, board.square(square), _base_yaw(base))
        arms.start(k)
        for name, cfg, duration, hold in steps:
            arms.move(k, cfg, duration, hold, zone,
                      f"{base.name} arm: {piece.name} to square {square} ({name})")
        expected = expected[:square] + (mark,) + expected[square + 1:]
        move = {"mark": mark, "square": square, "piece": piece.name, "arm": base.name}
        after = _pieces_seen(arms.buses, bases) if read_back else {}
        if piece.name in after and piece.name in seen:
            verdict = judge_move(board, piece.name, square,
                                 {n: c for n, (c, _) in seen.items()},
                                 {n: c for n, (c, _) in after.items()}, after[piece.name][1])
            read = board_of(board, {n: c for n, (c, _) in after.items()})
            move |= asdict(verdict) | {"board_read": "".join(c or "." for c in read),
                                       "board_as_read_matches": read == expected,
                                       "reason": verdict.reason()}
        else:  # no cube sensor (a real arm): not read back, never invented
            move |= {"piece_error_mm": None, "tilt_deg": None, "others_moved_mm": None,
                     "ok": None, "board_read": None, "board_as_read_matches": None,
                     "reason": "not read back (no cube sensor on the bus)"}
        seen = after
        moves.append(move)
    for k in (1, 0):  # back to the starting pose, checked, before the release there
        arms.move(k, arms.starts[k], PARK_FIRST_S, 0.0, zone,
                  f"{bases[k].name} arm: back to its starting pose")
    return winner(expected) or "draw"


def play_on_arms(ports: Sequence[str], calibrations: Sequence[Mapping], bases, board: GameBoard,
                 opening: int = 4, *, gravity_ff: bool = True,
                 time_sources: Sequence[TimeSource | None] = (None, None)) -> TwoArmRun:
    """The whole tic-tac-toe game on the arms at ``ports`` (left X, right O); both ended.

    Args:
        ports: the left and the right arm's serial ports.
        calibrations: their lerobot calibrations (``calibration.load_calibration``).
        bases: the bases as the simulator places them (``two_arm_scene.arm_bases``): the
            arms must stand so on the table.
        board: the board, in the same world.
        opening: X's first square (0-8).
        gravity_ff: the course helpers' gravity feed-forward.
        time_sources: each arm's time (None: the wall clock; the virtual arm's ``clock``).

    Returns:
        The run: the report (``completed``, ``collisions``, ``moves``, each with
        ``piece_error_mm`` (None when not read back), ``read_back``, ``aborted``, ...), each
        arm's last line, the last line (both), the exit code.

    Raises:
        PlanError: refused before anything moved (one line): the bases, the board, the
            reach, a port without its arm.
        CalibrationError: an arm holds another calibration (one line, nothing moved).
        ScriptEnded: an arm refused by ``setup_motors`` (its line printed; nothing moved).
    """
    check_ports(ports)
    check_bases(bases)
    board.check()
    pieces = game_pieces(bases)
    check_board_reach(bases, board, pieces)
    _preflight(ports, calibrations)
    names = [base.name for base in bases]
    buses, starts, moves, endings = [], [], [], {}
    arms, winner_is, refused, aborted, code, sensed = None, None, None, None, 0, False
    try:
        for port, calibration, clock in zip(ports, calibrations, time_sources, strict=True):
            buses.append(setup_motors(calibration, port, gravity_ff=gravity_ff,
                                      time_source=clock))
            starts.append(read_pose(buses[-1].raw, 2))
        arms = _Arms(bases, buses, starts)
        sensed = {f"{mark.lower()}_1" for mark in MARKS} <= set(_pieces_seen(buses, bases))
        winner_is = _play(arms, bases, board, pieces, opening, sensed, moves)
    except ScriptEnded as ended:  # one arm's fault: its ending ran; the other's below
        if arms is None:  # refused while setting up: nothing moved
            refused = ended
        else:
            endings[names[arms.moving]] = ended.line
            why = ended.line if ended.result is None else ended.result.aborted
            aborted, code = f"the {names[arms.moving]} arm: {why}", ended.code
    except KeyboardInterrupt:
        aborted, code = "stopped by Ctrl-C or a stop signal", 130
    except Exception as error:  # noqa: BLE001 - a path refused mid-game: end both arms
        aborted, code = " ".join(str(error).split()), 1
    finally:
        for name, bus in zip(names, buses, strict=False):
            line = end_arm(bus, f"The game's end ({name} arm):")
            if line is not None:
                endings[name] = line
    if refused is not None:
        raise refused
    last = " ".join(f"{name.capitalize()} arm ({port}): {endings[name]}"
                    for name, port in zip(names, ports, strict=True) if name in endings)
    completed = (aborted is None and winner_is is not None and (not sensed or all(
        mv["ok"] and mv["board_as_read_matches"] for mv in moves)))
    watched = arms is not None and arms.measured > 0
    report = {"completed": completed, "collisions": arms.watch.collisions if watched else 0,
              "moves": moves, "winner": winner_is, "aborted": aborted, "read_back": sensed,
              "least_arm_distance_planned_mm": _mm(arms.least_planned) if watched else None,
              "least_arm_distance_run_mm": _mm(arms.watch.least_distance) if watched else None,
              "ports": list(ports), "bases": [asdict(b) for b in bases],
              "board": asdict(board), "endings": endings}
    return TwoArmRun(report, endings, last, code)


def _mm(metres: float) -> float | None:
    return None if math.isinf(metres) else round(1e3 * metres, 1)
