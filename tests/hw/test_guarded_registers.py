"""Every register a student writes is guarded, and the last line is read back (issue 33).

The issue's unsafe rows, each as a course-style script runs them against the virtual SO-101
through lerobot's bus: ``setup_motors``, ``move_to_pose(bus, all-zero, 2.0)`` (the arm
stretched out), then one write. A write that can drop, spin or weaken the arm is the
guarded release (``Torque_Enable`` 0) or refused in one line naming ``bus.raw``
(``hw/guarded.py``); what an earlier program left is put back by ``setup_motors``
(``hw/servo_settings.py``); and when the raw bus was used anyway, the last line says which
servo cannot hold, read back from the servos.

The course's values asserted here are lerobot 0.4.4's (``robots/so_follower/so_follower.py``
``configure``: Operating_Mode 0, P 16, I 0, D 32; ``motors/feetech/feetech.py``
``configure_motors``: Acceleration 254) and the STS memory table's (Torque_Limit loaded from
Max_Torque_Limit, 1000 from the factory; Goal_Velocity 0 the fastest).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from so101_kinematics.constants import HOME_POSE
from so101_kinematics.frames import ARM_JOINTS, JOINTS
from so101_kinematics.gravity import feedforward
from so101_kinematics.hw.course_calibration import ScriptEnded
from so101_kinematics.hw.servo_settings import unable_to_hold
from so101_kinematics.servo import LEROBOT

CALIBRATION_PATH = Path(__file__).resolve().parents[2] / "calibration" / "virtual_so101.json"
ZERO = dict.fromkeys(JOINTS, 0.0)  # the all-zero pose: the arm stretched out
# The goal that holds the arm at its start (the virtual arm powers up at HOME): HOME plus the
# gravity feed-forward at lerobot's P = 16 on the virtual arm's 5 V (as test_so101_utils.py).
HOME_GOAL = {j: HOME_POSE[j] + v for j, v in feedforward(HOME_POSE, LEROBOT, 5.0).items()}
DONE = "Done: back at the starting pose, torque off."


def stretched_out(arm):
    """The course-style script up to its one write: setup_motors, move_to_pose(all-zero, 2.0)."""
    from so101_utils import load_calibration, move_to_pose, setup_motors

    bus = setup_motors(load_calibration(str(CALIBRATION_PATH)), arm.port)
    move_to_pose(bus, ZERO, 2.0)
    return bus


def last_line(text: str) -> str:
    return text.strip().splitlines()[-1]


def near(actual, expected, tol):
    return {j: round(actual[j] - expected[j], 1) for j in ARM_JOINTS
            if abs(actual[j] - expected[j]) > tol}


# --- the unsafe rows -----------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_torque_enable_0_is_the_guarded_release_not_a_drop(course_arm, capsys, caplog):
    bus = stretched_out(course_arm)
    bus.sync_write("Torque_Enable", 0)
    # released only back at the start: the last goal before the release is the start's
    assert not any(course_arm.torque_enabled().values())
    assert near(course_arm.commanded_positions(), HOME_GOAL, 2.0) == {}
    assert "released as bus.disable_torque() releases the arm" in caplog.text
    assert last_line(capsys.readouterr().out) == DONE


@pytest.mark.hw
@pytest.mark.parametrize("write, register, joint, kept", [
    (("sync_write", "Torque_Limit", 0), "Torque_Limit", "shoulder_lift", 1000),
    (("sync_write", "P_Coefficient", 1), "P_Coefficient", "shoulder_lift", 16),
    (("write", "Operating_Mode", "wrist_roll", 1), "Operating_Mode", "wrist_roll", 0),
    (("write", "Goal_Velocity", "wrist_roll", 500), "Goal_Velocity", "wrist_roll", 0),
])
@pytest.mark.slow
@pytest.mark.newest_lerobot
def test_a_write_that_weakens_or_spins_the_arm_is_refused_naming_bus_raw(
        course_arm, capsys, write, register, joint, kept):
    bus = stretched_out(course_arm)
    held = course_arm.joint_positions()
    method, *args = write
    with pytest.raises(ScriptEnded) as ended:
        getattr(bus, method)(*args)
    err = capsys.readouterr()
    line = ended.value.line
    assert ended.value.code == 2 and line.startswith("Refused: ") and "\n" not in line
    assert f"bus.raw.{method}(" in line and "Fix: " in line and line in err.err
    assert course_arm.registers(joint)[register] == kept  # nothing written
    # the arm did not drop at the write: where it held, then back at the start, released
    assert near(held, ZERO, 5.0) == {}
    assert not any(course_arm.torque_enabled().values())
    assert near(course_arm.commanded_positions(), HOME_GOAL, 2.0) == {}
    assert last_line(err.out) == DONE


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_the_courses_own_values_pass_and_lerobots_torque_disabled_is_refused(course_arm,
                                                                            capsys):
    bus = stretched_out(course_arm)
    bus.sync_write("P_Coefficient", 16)  # what lerobot's configuration writes: harmless
    bus.write("Acceleration", "elbow_flex", 254)
    bus.sync_write("Torque_Enable", 1)
    assert all(course_arm.torque_enabled().values())
    with pytest.raises(ScriptEnded) as ended:
        with bus.torque_disabled():
            pass
    assert "bus.raw.torque_disabled(" in ended.value.line
    assert last_line(capsys.readouterr().out) == DONE


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_setup_motors_puts_back_what_an_earlier_program_left_and_says_so(course_arm, caplog):
    """The issue's poor row: a Goal_Velocity (or Torque_Limit, P, ...) left behind made the
    next move abort blaming "something blocks the arm"."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw.bus import connect, disconnect
    from so101_utils import move_to_pose

    other = connect(course_arm.port, load_calibration(CALIBRATION_PATH))  # an earlier program
    try:
        other.write("Goal_Velocity", "shoulder_lift", 100)
        other.write("Torque_Limit", "elbow_flex", 150)
        other.write("P_Coefficient", "wrist_flex", 3)
        other.write("Acceleration", "shoulder_pan", 5)
        other.write("Operating_Mode", "wrist_roll", 1)
    finally:
        disconnect(other)
    bus = stretched_out(course_arm)  # the move must not abort
    expected = {"Goal_Velocity": 0, "Torque_Limit": 1000, "P_Coefficient": 16,
                "Acceleration": 254, "Operating_Mode": 0, "I_Coefficient": 0,
                "D_Coefficient": 32}
    for joint in ARM_JOINTS:
        registers = course_arm.registers(joint)
        assert {k: registers[k] for k in expected} == expected, joint
    assert near(course_arm.joint_positions(), ZERO, 3.0) == {}
    for register, joint in [("Goal_Velocity", "shoulder_lift"), ("Torque_Limit", "elbow_flex"),
                            ("P_Coefficient", "wrist_flex"), ("Acceleration", "shoulder_pan"),
                            ("Operating_Mode", "wrist_roll")]:
        said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"
                and r.getMessage().startswith(f"setup_motors: {register} was ")]
        assert len(said) == 1 and joint in said[0] and "earlier program" in said[0], register
    move_to_pose(bus, HOME_POSE, 2.0)
    bus.disable_torque()


@pytest.mark.hw
def test_the_hardware_script_puts_back_what_an_earlier_program_left_too(course_arm, caplog):
    """pick_place_hw.py's run arms the servos through the same path as setup_motors: a
    Torque_Limit and a Goal_Velocity left behind are put back (and named) before torque."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw import run as hw
    from so101_kinematics.hw.bus import connect, disconnect
    from so101_kinematics.planning.motion import Plan, Step

    other = connect(course_arm.port, load_calibration(CALIBRATION_PATH))  # an earlier program
    try:
        other.write("Goal_Velocity", "shoulder_lift", 100)
        other.write("Torque_Limit", "elbow_flex", 150)
    finally:
        disconnect(other)
    start = course_arm.joint_positions()
    plan = Plan([Step("stay", {j: start[j] for j in JOINTS}, 0.5, 0.2)], return_duration=0.5)
    hw.run_on_arm(course_arm.port, load_calibration(CALIBRATION_PATH), plan)
    assert course_arm.registers("shoulder_lift")["Goal_Velocity"] == 0
    assert course_arm.registers("elbow_flex")["Torque_Limit"] == 1000
    for register, joint in [("Goal_Velocity", "shoulder_lift"), ("Torque_Limit", "elbow_flex")]:
        said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"
                and r.getMessage().startswith(f"pick_place_hw: {register} was ")]
        assert len(said) == 1 and joint in said[0] and "earlier program" in said[0], register


# --- the last line, read back ------------------------------------------------------------
@pytest.mark.hw
@pytest.mark.parametrize("writes, joint, reason", [
    ([("sync_write", "Torque_Limit", 0)], "shoulder_lift", "Torque_Limit 0"),
    ([("sync_write", "P_Coefficient", 1)], "shoulder_lift", "P_Coefficient 1"),
    ([("write", "Operating_Mode", "wrist_roll", 1), ("write", "Goal_Velocity", "wrist_roll", 500)],
     "wrist_roll", "Operating_Mode 1"),
])
def test_the_last_line_says_which_servo_cannot_hold_read_back(course_arm, capsys, writes,
                                                              joint, reason):
    """The same writes on bus.raw (the escape hatch): the arm drops or spins, the ending
    cannot bring it back, and the last line names the servo that cannot hold."""
    import time

    bus = stretched_out(course_arm)
    for method, *args in writes:
        getattr(bus.raw, method)(*args)
    time.sleep(0.5)
    bus.disable_torque()
    last = last_line(capsys.readouterr().err)
    assert "is holding where it stopped" not in last and "is NOT holding" in last, last
    assert "UNABLE TO HOLD (read back)" in last and reason in last, last
    cannot = last.split("UNABLE TO HOLD (read back):")[1]
    assert joint in cannot.split(f"({reason}")[0]
    assert "--release" in last


@pytest.mark.slow
@pytest.mark.newest_lerobot
@pytest.mark.hw
def test_the_hardware_scripts_ending_reads_back_too(course_arm):
    """pick_place_hw.py's run: a servo weakened on the bus mid-run (another program) is named."""
    from so101_kinematics.calibration import load_calibration
    from so101_kinematics.hw import run as hw
    from so101_kinematics.planning.motion import Plan, Step

    def weaken(session, cycle):  # once stretched out: it falls, and cannot lift itself back
        if cycle.measured and abs(cycle.measured["shoulder_lift"]) < 3.0 and not weaken.done:
            weaken.done = True
            session.bus.write("Torque_Limit", "shoulder_lift", 0)

    weaken.done = False
    plan = Plan([Step("out", dict(ZERO), 2.0, 1.0)], return_duration=1.5)
    with pytest.raises(hw.MotionAborted) as info:
        hw.run_on_arm(course_arm.port, load_calibration(CALIBRATION_PATH), plan, on_cycle=weaken)
    result = info.value.result
    assert weaken.done and not result.torque_released
    line = hw.ending(result, "RELEASE")
    assert result.unable.get("shoulder_lift") == "Torque_Limit 0"
    assert "UNABLE TO HOLD (read back): shoulder_lift" in line and "is holding where" not in line


# --- the verdict itself (no arm) ----------------------------------------------------------
def state(**changes):
    """Registers as the course leaves them (lerobot's values, 5 V), with ``changes``."""
    base = {"Torque_Enable": 1, "Operating_Mode": 0, "Torque_Limit": 1000,
            "Max_Torque_Limit": 1000, "P_Coefficient": 16, "Status": 0, "Present_Voltage": 50}
    out = {register: dict.fromkeys(JOINTS, value) for register, value in base.items()}
    for key, value in changes.items():
        register, joint = key.rsplit("__", 1)
        out[register][joint] = value
    return out


def test_lerobots_settings_hold_the_stretched_arm_and_each_weakening_is_named():
    assert unable_to_hold(state(), ZERO) == {}
    assert unable_to_hold(state(Torque_Limit__elbow_flex=0), ZERO) == {
        "elbow_flex": "Torque_Limit 0"}
    assert unable_to_hold(state(Max_Torque_Limit__wrist_roll=0), ZERO) == {
        "wrist_roll": "Torque_Limit 0"}
    assert unable_to_hold(state(Operating_Mode__wrist_roll=1), ZERO) == {
        "wrist_roll": "Operating_Mode 1: wheel mode"}
    # P 1: stretched out the shoulder holds 0.54 N m (the model's masses), 24 % of the 5 V
    # stall torque (0.453 N m/V x 5 V): 238 duty, 1 + (238 - 16) x 4 / 1 counts plus half the
    # backlash: about 78 deg of sag, far past the 15 deg the stall check allows
    weak = unable_to_hold(state(P_Coefficient__shoulder_lift=1), ZERO)
    assert list(weak) == ["shoulder_lift"] and weak["shoulder_lift"].startswith("P_Coefficient 1")
    # the wrist's roll carries no gravity load: P 1 still holds it in still air
    assert unable_to_hold(state(P_Coefficient__wrist_roll=1), ZERO) == {}
    # Torque_Limit 30: 3 % of the 5 V stall torque, less than the 24 % the shoulder needs there
    assert "shoulder_lift" in unable_to_hold(state(Torque_Limit__shoulder_lift=30), ZERO)
    # torque off is the torque's own words (limp), the gripper's overload its job (squeezing)
    assert unable_to_hold(state(Torque_Enable__elbow_flex=0, Torque_Limit__elbow_flex=0,
                                Status__gripper=0x20), ZERO) == {}
    assert unable_to_hold(state(Status__elbow_flex=0x20), ZERO) == {
        "elbow_flex": "status: overloaded"}
    # a register not read decides nothing
    assert unable_to_hold({}, ZERO) == {}


class LateReplies:
    """Stands for lerobot's bus on a loaded host: each register's first read is answered by
    the reply to the read before it (late, past the settling: the SDK matches replies by id
    only); the registers in ``silent`` never answer."""

    def __init__(self, registers, silent=()):
        self.registers, self.silent, self.last = registers, silent, None
        self.port_handler = type("Port", (), {"is_using": False})()

    def sync_read(self, register, normalize=True, num_retry=0):
        if register in self.silent:
            raise ConnectionError(f"no status packet for {register}")
        answer, self.last = self.last or self.registers[register], self.registers[register]
        return dict(answer)


def test_the_ending_believes_a_setting_only_when_two_reads_agree_and_says_what_it_could_not_read(
        monkeypatch):
    from so101_kinematics.hw import bus as hw_bus
    from so101_kinematics.hw.run import RunResult, ending
    from so101_kinematics.hw.servo_settings import HOLD_REGISTERS, read_back

    monkeypatch.setattr(hw_bus, "PORT_SETTLE_S", 0.0)
    weak = state(P_Coefficient__shoulder_lift=1)
    # in the order the ending reads, each register's first reply is the one before's: believed
    # once, P_Coefficient would read 1000 (a stiff servo), Status 16, the supply 0 V
    late = LateReplies({r: weak[r] for r in HOLD_REGISTERS})
    torque, unable, unread = read_back(late, ZERO, None)
    assert torque == dict.fromkeys(JOINTS, True) and unread == []
    assert list(unable) == ["shoulder_lift"] and unable["shoulder_lift"].startswith(
        "P_Coefficient 1:")
    # P_Coefficient never answers: nothing is claimed for it, and the last line says so
    torque, unable, unread = read_back(LateReplies(weak, silent=("P_Coefficient",)), ZERO, None)
    assert unable == {} and unread == ["P_Coefficient"]
    last = ending(RunResult(ZERO, aborted="stopped", final_pose=ZERO, torque=torque, unread=unread),
                  "python pick_place_hw.py --release")
    assert "torque ON, but P_Coefficient not read back" in last and "unknown" in last


# --- the guard's table itself (no arm: a bus that records) --------------------------------
class Recorder:
    """Stands for lerobot's bus: records what reaches it."""

    motors = dict.fromkeys(JOINTS)

    def __init__(self):
        self.written = []

    def sync_write(self, name, values, normalize=True, num_retry=0):
        self.written.append((name, values))

    def write(self, name, motor, value, normalize=True, num_retry=0):
        self.written.append((name, {motor: value}))


class Refused(Exception):
    pass


def guarded():
    from so101_kinematics.hw.guarded import GuardedBus

    raw, released = Recorder(), []

    def refuse(line):
        raise Refused(line)

    bus = GuardedBus(raw, lambda *a: None, lambda *a: released.append(a), refuse)
    return bus, raw, released


@pytest.mark.parametrize("register, value", [
    ("ID", 7), ("Baud_Rate", 1), ("Lock", 0), ("Homing_Offset", 100),
    ("Min_Position_Limit", 0), ("Max_Position_Limit", 4095), ("Return_Delay_Time", 250),
    ("Torque_Enable", 128), ("Max_Torque_Limit", 0), ("I_Coefficient", 5),
    ("D_Coefficient", 0), ("Acceleration", 0)])
def test_every_other_register_write_is_refused_in_one_line_with_the_fix_and_bus_raw(register,
                                                                                     value):
    bus, raw, released = guarded()
    for call in (lambda: bus.write(register, "elbow_flex", value),
                 lambda: bus.sync_write(register, value)):
        with pytest.raises(Refused) as refused:
            call()
        line = str(refused.value)
        assert line.startswith("Refused: bus.") and register in line and "\n" not in line
        assert "Fix: " in line and "bus.raw." in line
    assert raw.written == [] and released == []


def test_torque_enable_0_on_one_motor_is_the_whole_arms_guarded_release():
    bus, raw, released = guarded()
    bus.write("Torque_Enable", "gripper", 0)
    bus.sync_write("Torque_Enable", {"elbow_flex": 1, "wrist_flex": 0})
    assert raw.written == [] and len(released) == 2
    bus.sync_write("Torque_Enable", 1)  # on: holds the goal register, the helpers' last goal
    assert raw.written == [("Torque_Enable", 1)]


@pytest.mark.parametrize("call", ["torque_disabled", "write_calibration", "reset_calibration",
                                  "set_half_turn_homings", "setup_motor", "set_baudrate"])
def test_lerobots_own_calls_that_write_those_registers_are_refused(call):
    bus, raw, _ = guarded()
    with pytest.raises(Refused, match=f"bus.raw.{call}"):
        getattr(bus, call)()
