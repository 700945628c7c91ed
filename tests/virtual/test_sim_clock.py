"""The simulated clock: the virtual arm and the control loop on one time that passes when the
program sleeps (so101_kinematics/virtual/sim_clock.py).

The clock alone against a stand-in emulator; the virtual arm's physics on it (never slipping,
standing still while the program does); a move and a fault drill through lerobot's bus on it,
the same whether the program stalls or not.
"""

from __future__ import annotations

import os
import select
import signal
import socket
import struct
import termios
import threading
import time
import tty

import pytest

import so101_kinematics.virtual.protocol as fp
from so101_kinematics.hw.timing import RateLoop
from so101_kinematics.virtual.arm import VirtualSO101
from so101_kinematics.virtual.sim_clock import ClockFollower, SimClock

STEP_NS = 4_000_000  # the model's physics step, 4 ms (model/so101.xml) [ns]
STEP_S = STEP_NS / 1e9
STALL_S = 0.3  # [s] of wall time a stalled program or emulator loses


@pytest.fixture
def stand_in():
    """A SimClock whose emulator is a thread stepping whole 4 ms steps, as the real one does."""
    ours, theirs = socket.socketpair()
    follower = ClockFollower(theirs.detach())

    def emulator():
        while follower.receive():
            follower.acknowledge(follower.target_ns // STEP_NS * STEP_NS)

    thread = threading.Thread(target=emulator, daemon=True)
    thread.start()
    clock = SimClock(ours)
    yield clock
    clock.close()
    thread.join(5)
    follower.close()


# --- the clock alone -----------------------------------------------------------------------------
def test_a_sleep_returns_with_the_arm_at_the_new_time(stand_in):
    assert stand_in.clock() == 0.0
    stand_in.sleep(0.25)
    assert stand_in.clock() == pytest.approx(0.25, abs=2e-9)  # rounded up, never short of it
    assert stand_in.clock() >= 0.25
    assert stand_in.reached == 0.248  # 62.5 steps of 4 ms: the physics stands at 62 whole ones
    stand_in.sleep(0.003)
    assert stand_in.reached == 0.252  # 63 steps: 0.253 s is within the 64th
    stand_in.sleep(0.0)
    stand_in.sleep(-1.0)
    assert stand_in.clock() == pytest.approx(0.253, abs=3e-9)  # nothing passes


def test_the_control_loop_lands_on_its_deadlines_without_spinning_forever(stand_in):
    loop = RateLoop(100.0, stand_in.clock, stand_in.sleep, stand_in.spin)
    start = loop.start()
    deadlines = [loop.wait() for _ in range(50)]
    assert deadlines == pytest.approx([start + 0.01 * k for k in range(1, 51)], abs=1e-12)
    assert loop.overruns == loop.skipped == 0
    assert 0.0 <= stand_in.clock() - deadlines[-1] < 1e-8
    assert stand_in.reached == pytest.approx(0.5)  # 125 steps


def test_an_answer_to_an_earlier_sleep_is_skipped():
    ours, theirs = socket.socketpair()
    clock = SimClock(ours)

    def emulator():  # answers an old time first (left unread by an interrupted sleep)
        (target,) = struct.unpack("<q", theirs.recv(8))
        theirs.sendall(struct.pack("<qqq", target - 1000, 0, target - 1000)
                       + struct.pack("<qqq", target, STEP_NS, target))

    thread = threading.Thread(target=emulator)
    thread.start()
    clock.sleep(0.005)
    thread.join()
    assert clock.reached_ns == STEP_NS  # the answer to this sleep, not the stale one
    clock.close()
    theirs.close()


def test_without_the_emulator_the_time_goes_on_in_the_program_alone():
    ours, theirs = socket.socketpair()
    theirs.close()
    clock = SimClock(ours)
    clock.sleep(1.5)
    clock.sleep(0.5)
    assert clock.clock() == pytest.approx(2.0, abs=1e-8)


# --- the virtual arm's physics on it -------------------------------------------------------------
def physics_time(arm) -> float:
    """[s] the arm's physics has simulated (MuJoCo's d.time)."""
    return arm.reply_stats()["sim_time_s"]


def stopped(pid: int, seconds: float) -> None:
    """Stop the process for ``seconds`` of wall time (a machine too busy to run it)."""
    os.kill(pid, signal.SIGSTOP)
    threading.Timer(seconds, os.kill, (pid, signal.SIGCONT)).start()


def test_the_arm_stands_still_while_the_program_does_and_moves_on_when_it_sleeps():
    with VirtualSO101(sim_clock=True) as arm:
        time.sleep(STALL_S)  # the program stalls: the arm's time does not pass
        assert physics_time(arm) == 0.0
        arm.clock.sleep(0.2)
        assert physics_time(arm) == pytest.approx(0.2, abs=STEP_S)
        assert physics_time(arm) == pytest.approx(arm.clock.reached)


def test_the_physics_never_slips_on_the_simulated_clock_but_does_on_the_wall_clock():
    with VirtualSO101(sim_clock=True) as arm:
        stopped(arm.pid, STALL_S)  # the emulator cannot run: the sleep waits for it
        arm.clock.sleep(0.5)
        assert physics_time(arm) == pytest.approx(0.5, abs=STEP_S)  # every step taken
    with VirtualSO101() as arm:
        before = arm.reply_stats()
        stopped(arm.pid, STALL_S)
        time.sleep(STALL_S + 0.1)
        after = arm.reply_stats()
        slipped = (after["wall_time_s"] - after["sim_time_s"]) \
            - (before["wall_time_s"] - before["sim_time_s"])
        assert slipped >= STALL_S - 25 * STEP_S - 0.05  # all but 25 steps of the stop lost


def test_an_unanswered_request_costs_the_program_lerobots_timeout():
    with VirtualSO101(sim_clock=True) as arm:
        fd = os.open(arm.port, os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            attrs = termios.tcgetattr(fd)
            attrs[4] = attrs[5] = termios.B1000000  # the bus's 1 Mbit/s
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
            os.write(fd, fp.instruction_packet(1, fp.INST_PING))  # shoulder_pan answers
            assert select.select([fd], [], [], 5.0)[0] and os.read(fd, 64)
            time.sleep(0.1)
            assert arm.clock.clock() == 0.0  # an answered request costs no simulated time
            os.write(fd, fp.instruction_packet(42, fp.INST_PING))  # nobody has ID 42
            time.sleep(0.1)
            assert arm.clock.clock() == pytest.approx(0.050)  # lerobot waited its 50 ms
        finally:
            os.close(fd)


# --- the control loop through lerobot's bus on it ------------------------------------------------
MOVE_S, RATE_HZ = 0.6, 50.0  # a move of 0.6 s at 50 Hz: 30 cycles
STALL_EVERY = 3  # the stalling program loses STALL_S of wall time every third cycle


def move_on_the_simulated_clock(stall: bool) -> tuple[dict[str, float], int]:
    """Move elbow_flex 20 deg in MOVE_S of simulated time; (MuJoCo's final pose, cycles)."""
    pytest.importorskip("lerobot")
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.bus import connect, disconnect
    from so101_kinematics.hw.control import ArmSession
    from so101_kinematics.virtual.shipped_calibration import DEFAULT_CALIBRATION_PATH

    def on_cycle(session, cycle):
        if stall and len(session.cycles) % STALL_EVERY == 0:
            time.sleep(STALL_S)

    with VirtualSO101(sim_clock=True) as arm:
        bus = connect(arm.port, load_calibration(DEFAULT_CALIBRATION_PATH))
        try:
            clock = arm.clock
            session = ArmSession(bus, rate_hz=RATE_HZ, on_cycle=on_cycle, clock=clock.clock,
                                 sleep=clock.sleep, spin=clock.spin)
            start = session.read_pose()
            session.move(dict(start, elbow_flex=start["elbow_flex"] - 20.0), MOVE_S)
            return arm.joint_positions(), len(session.cycles)
        finally:
            disconnect(bus)


@pytest.mark.hw
def test_a_move_ends_the_same_whether_the_program_stalls_or_not():
    steady_pose, steady_cycles = move_on_the_simulated_clock(stall=False)
    stalled_pose, stalled_cycles = move_on_the_simulated_clock(stall=True)
    assert steady_cycles == stalled_cycles == round(MOVE_S * RATE_HZ)
    assert stalled_pose == pytest.approx(steady_pose, abs=0.1)  # [deg]


@pytest.mark.hw
def test_a_drill_of_the_fault_matrix_ends_as_the_policy_says_on_the_simulated_clock(tmp_path):
    pytest.importorskip("lerobot")
    from so101_kinematics.frames import JOINTS
    from so101_kinematics.lab.fault_drill import run_drill

    drill = run_drill("elbow_flex overheats", "carry (cube lifted)", tmp_path, sim_clock=True)
    assert drill.goals_outside == 0
    assert drill.log_rows == drill.cycles > 0
    assert not drill.completed and "overheated" in drill.aborted
    assert drill.at_start and len(drill.torque_off) == len(JOINTS), drill
    assert drill.last_line.endswith("at the starting pose, torque off."), drill.last_line
