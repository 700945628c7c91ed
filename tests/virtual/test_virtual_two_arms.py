"""The tic-tac-toe game's plan on two virtual arms through lerobot's bus (issue 38).

``two_arms.py --ports A B`` (``lab/two_arms_arm.py``): two ``VirtualSO101``, each its own
process and one-arm world holding its own pieces (the cubes at the simulator's supply
positions, in its base frame), powered up at its park pose as ``two_arms.py
--print-virtual-arms`` starts them; one program drives both through the course helpers, on
the arms' simulated clocks (``virtual/sim_clock.py``), so the run does not depend on the
machine's speed. The expected end is the issue's acceptance: a whole game, every piece within
5 mm of its square, no collision between the arms, both arms back at their starting pose and
released, said by the last line from both arms' servos.
"""

from __future__ import annotations

import functools
import json
import math

import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

import two_arms  # noqa: E402
from so101_kinematics.lab import two_arms_arm  # noqa: E402
from so101_kinematics.two_arms.game_board import LAYOUT_BOARDS  # noqa: E402
from so101_kinematics.two_arms.tictactoe import full_game  # noqa: E402
from so101_kinematics.two_arms.two_arm_game import park_pose  # noqa: E402
from so101_kinematics.two_arms.two_arm_scene import arm_bases, base_from_world  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402

PLACE_TOLERANCE_MM = 5.0  # the acceptance: every piece within 5 mm of its square
BASES = arm_bases("facing")
BOARD = LAYOUT_BOARDS["facing"]
DONE = "Done: back at the starting pose, torque off."


def two_virtual_arms():
    """The two virtual arms as ``two_arms.py --print-virtual-arms`` starts them (sim clocks)."""
    cubes = two_arms_arm.virtual_arm_cubes(BASES)
    return (VirtualSO101(cube=cubes[k], initial=park_pose(BASES[k]), sim_clock=True)
            for k in (0, 1))


def on_sim_clocks(monkeypatch, left, right) -> None:
    """``two_arms.py`` runs the arms on their simulated clocks (the command line: the wall's)."""
    monkeypatch.setattr(two_arms_arm, "play_on_arms", functools.partial(
        two_arms_arm.play_on_arms, time_sources=(left.clock, right.clock)))


def expected_board() -> str:
    """The board after the game, from the game's own moves (``tictactoe.full_game``)."""
    board = ["."] * 9
    for mark, square in full_game(4):
        board[square] = mark
    return "".join(board)


@pytest.mark.slow
def test_the_whole_game_on_two_virtual_arms_through_lerobots_bus(tmp_path, monkeypatch, capsys):
    report_path = tmp_path / "two_arms.json"
    left, right = two_virtual_arms()
    with left, right:
        on_sim_clocks(monkeypatch, left, right)
        code = two_arms.main(["--game", "tictactoe", "--headless", "--ports", left.port,
                              right.port, "--json", str(report_path)])
        torque = left.torque_enabled() | {f"right {j}": on for j, on in
                                          right.torque_enabled().items()}
        truth = {"x": [left.cube(k) for k in range(5)], "o": [right.cube(k) for k in range(4)]}
    out, err = capsys.readouterr()
    assert code == 0, err
    # the last line is both arms', from their servos: each back where it started, released
    assert out.strip().splitlines()[-1] == (f"Left arm ({left.port}): {DONE} "
                                            f"Right arm ({right.port}): {DONE}")
    assert not any(torque.values()), torque
    report = json.loads(report_path.read_text())
    assert report["completed"] is True and report["collisions"] == 0 and report["read_back"]
    assert report["winner"] == "draw" and report["aborted"] is None
    moves = report["moves"]
    assert [(mv["mark"], mv["square"]) for mv in moves] == list(full_game(4))
    errors = [mv["piece_error_mm"] for mv in moves]
    print(f"pieces {sum(errors) / len(errors):.2f} mm mean, {max(errors):.2f} mm worst; least "
          f"distance {report['least_arm_distance_run_mm']} mm")
    assert all(isinstance(e, float) and e <= PLACE_TOLERANCE_MM for e in errors), errors
    assert moves[-1]["board_read"] == expected_board()
    # the arms' own worlds say so too (the emulators' truth, not the bus's reading): each
    # piece within 5 mm of its square, in the arm's base frame
    for mark, square in full_game(4):
        k = "XO".index(mark)
        cube = truth[mark.lower()].pop(0)
        target = base_from_world(BASES[k], BOARD.square(square))
        assert math.dist(cube.position_m[:2], target[:2]) <= PLACE_TOLERANCE_MM / 1e3, (
            mark, square, cube)
        assert cube.tilt_deg <= 5.0 and not cube.held


def play_with_a_fault_in_the_first_pick(monkeypatch, fault):
    """Tic-tac-toe on two virtual arms, ``fault(left)`` called as the left arm's first pick
    starts (the fifth course move: park, park, then that pick).

    Returns:
        (exit code, both arms' Torque_Enable and pose at the end, the two arms).
    """
    from so101_kinematics.hw.course_helpers import course_logged_move as logged

    calls = []
    left, right = two_virtual_arms()

    def move(bus, *args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            fault(left)
        return logged(bus, *args, **kwargs)

    with left, right:
        on_sim_clocks(monkeypatch, left, right)
        monkeypatch.setattr(two_arms_arm, "course_logged_move", move)
        code = two_arms.main(["--ports", left.port, right.port])
        torque = [left.torque_enabled(), right.torque_enabled()]
        poses = [left.joint_positions(), right.joint_positions()]
    return code, torque, poses, left, right


@pytest.mark.slow
def test_a_fault_on_one_arm_ends_both_back_at_their_start(monkeypatch, capsys):
    # the left arm's elbow overheats in its first move (the fault policy: a controlled stop,
    # back to its start, released); the right arm, holding at its park pose, ends as well
    code, torque, _, left, right = play_with_a_fault_in_the_first_pick(
        monkeypatch, lambda arm: arm.inject("overheat:elbow_flex"))
    out, err = capsys.readouterr()
    assert code == 1 and "nexpected" not in err, err
    last = err.strip().splitlines()[-1]
    assert last == (f"Left arm ({left.port}): Back at the starting pose, torque off. "
                    f"Right arm ({right.port}): {DONE}"), err
    assert "aborted: the left arm: The elbow_flex servo reports: overheated" in out, out
    assert not any(torque[0].values()) and not any(torque[1].values()), torque


@pytest.mark.slow
def test_arms_started_at_home_are_refused_before_they_move_and_released(monkeypatch, capsys):
    # at the model's home two facing arms 0.46 m apart overlap (their boxes 9 mm into each
    # other): the first move's check refuses it, nothing moves, both end released
    cubes = two_arms_arm.virtual_arm_cubes(BASES)
    with VirtualSO101(cube=cubes[0], sim_clock=True) as left, \
            VirtualSO101(cube=cubes[1], sim_clock=True) as right:
        before = [left.joint_positions(), right.joint_positions()]
        on_sim_clocks(monkeypatch, left, right)
        code = two_arms.main(["--ports", left.port, right.port])
        after = [left.joint_positions(), right.joint_positions()]
        torque = [left.torque_enabled(), right.torque_enabled()]
    out, err = capsys.readouterr()
    assert code == 1 and "nexpected" not in err, err
    assert err.strip().splitlines()[-1] == (f"Left arm ({left.port}): {DONE} "
                                            f"Right arm ({right.port}): {DONE}"), err
    assert "0 moves" in out and "start each arm at its park pose" in out, out
    assert not any(torque[0].values()) and not any(torque[1].values()), torque
    for was, now in zip(before, after, strict=True):  # nothing moved (gravity aside, limp)
        assert abs(now["shoulder_pan"] - was["shoulder_pan"]) <= 0.5, (was, now)


@pytest.mark.parametrize(("ports", "says"), [
    (("ARM", "ARM"), "--ports ARM ARM: one port for both arms"),
    (("MISSING", "ARM"), "the left arm's port MISSING: Port 'MISSING' does not exist"),
])
def test_a_port_refused_in_one_line_moves_nothing(ports, says, tmp_path, capsys):
    missing = str(tmp_path / "no_such_port")
    with VirtualSO101(initial=park_pose(BASES[0])) as arm:
        before, torque = arm.joint_positions(), arm.torque_enabled()
        named = {"ARM": arm.port, "MISSING": missing}
        code = two_arms.main(["--ports", *(named[p] for p in ports)])
        after = arm.joint_positions()
        assert arm.torque_enabled() == torque  # as it powered up: torqued, nothing written
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    for name, value in named.items():
        says = says.replace(name, value)
    assert says in err and "Fix:" in err, err
    assert all(abs(after[j] - before[j]) <= 0.5 for j in before), (before, after)


def test_a_missing_port_is_refused_in_one_line(capsys):
    assert two_arms.main(["--ports", "/dev/pts/7"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error: argument --ports: expected 2 arguments" in err, err


def test_the_virtual_arms_are_printed_with_their_pieces_and_park_pose(capsys):
    assert two_arms.main(["--print-virtual-arms"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2
    # X's five pieces beside the left arm, O's four beside the right; facing across the board
    # each arm's pieces lie on its own left, the same in its own frame: the first at 0.19 m
    # from the pan axis at 42 deg (game_board.SUPPLY_RADIUS, SUPPLY_BEARINGS)
    assert [line.count("--cube ") for line in lines] == [5, 4]
    first = [float(v) for v in lines[0].split("--cube ")[1].split()[:3]]
    # the pan axis is 38.8 mm ahead of the base frame's origin (the model: ik/geometry.py)
    assert math.hypot(first[0] - 0.0388, first[1]) == pytest.approx(0.19, abs=2e-4)
    assert math.degrees(math.atan2(first[1], first[0] - 0.0388)) == pytest.approx(42.0, abs=0.1)
    assert lines[0].startswith("python virtual_so101.py --initial -90 -90 90 -90 0 0 ")


@pytest.mark.slow
@pytest.mark.parametrize(("signum", "said"), [("SIGINT", "stopped by Ctrl-C"),
                                              ("SIGTERM", "stopped by SIGTERM")])
def test_a_stop_signal_during_a_move_ends_both_arms_back_at_their_start(monkeypatch, capsys,
                                                                        signum, said):
    # a real signal while the left arm's first pick is under way: the moving arm stops as the
    # course helpers stop it (the cube in its jaws put down, back to its start, released),
    # then the other arm; exit 1 as every aborted run on an arm (pick_place_hw's too)
    import os
    import signal
    import threading

    def send(_arm):
        threading.Timer(0.2, os.kill, (os.getpid(), getattr(signal, signum))).start()

    code, torque, poses, left, right = play_with_a_fault_in_the_first_pick(monkeypatch, send)
    out, err = capsys.readouterr()
    assert code == 1 and "nexpected" not in err and "Traceback" not in err, err
    assert said in err and "aborted: the left arm" in out, (out, err)
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"Left arm ({left.port}): ") and "torque off" in last, err
    assert last.endswith(f"Right arm ({right.port}): {DONE}"), err
    assert not any(torque[0].values()) and not any(torque[1].values()), torque
    for k, pose in enumerate(poses):  # each released at its start: its park pose
        start = park_pose(BASES[k])
        assert all(abs(pose[j] - start[j]) < 5.0 for j in ("shoulder_pan", "shoulder_lift",
                                                           "elbow_flex")), (k, pose)
