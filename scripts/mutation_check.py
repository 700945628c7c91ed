"""Plant realistic bugs one at a time and check that the tests meant to catch each one fail.

Each planted bug (a *mutant*) names a file, the function it lives in (or ``None``
for a module-level setting) and an exact piece of code in it, with its
replacement: located by function and text, not by line, so the list survives
refactors. A mutant whose code is no longer found is reported ``stale`` (update
the list). The repository is copied to a temporary folder once; each mutant is
applied to the copy, its tests run with a timeout, and the copy restored. Your
worktree is never modified.

Not part of CI (every mutant in ``MUTANTS`` below, a baseline run first; ``--list``
counts them). Run it after changing tests or the code they guard (docs/development.md, "The
mutation check")::

    python scripts/mutation_check.py                 # every mutant
    python scripts/mutation_check.py -k return_speed # mutants whose name contains it
    python scripts/mutation_check.py --json out/mutation.json --list

Exit status 0 when every mutant is caught and the unmutated tests pass.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TIMEOUT_S = 600.0  # per mutant [s]; a mutant that hangs the tests counts as caught (timeout)
IGNORE = shutil.ignore_patterns(".git", "__pycache__", "*.pyc", ".pytest_cache", ".ruff_cache",
                                "out", "*.egg-info", ".venv", ".notes")


@dataclass(frozen=True)
class Edit:
    """Replace ``old`` (exact text, found exactly once in ``function``) by ``new`` in ``path``."""

    path: str
    function: str | None  # "Class.method", "function", or None: anywhere in the module
    old: str
    new: str


@dataclass(frozen=True)
class Mutant:
    """A planted bug: its edits and the pytest arguments (test ids) expected to catch it."""

    name: str
    why: str
    edits: tuple[Edit, ...]
    tests: tuple[str, ...]


def m(name, why, path, function, old, new, *tests, more=()):
    """A one-edit mutant (``more``: further edits of the same bug)."""
    return Mutant(name, why, (Edit(path, function, old, new), *more), tuple(tests))


CONTROL, TIMING = "so101_kinematics/hw/control.py", "so101_kinematics/hw/timing.py"
CHECKS, RUN, LOG = ("so101_kinematics/hw/cycle_checks.py", "so101_kinematics/hw/run.py",
                    "so101_kinematics/hw/log.py")
FRAMES, SCENE = "so101_kinematics/frames.py", "so101_kinematics/sim/scene.py"
CAL, PICK = "so101_kinematics/calibration.py", "so101_kinematics/sim/pick_place.py"
PROTOCOL = "so101_kinematics/virtual/protocol.py"
MARKERS, OUTPUTS = "so101_kinematics/markers.py", "so101_kinematics/outputs.py"
T_OUT = "tests/core/test_outputs.py"
REGISTERS = "so101_kinematics/virtual/registers.py"
T_SDK = "tests/virtual/test_virtual_feetech_sdk.py"
T_SIM_CLOCK = "tests/virtual/test_sim_clock.py"
VISION_MODEL = "so101_kinematics/vision/camera_model.py"
VISION_DETECT = "so101_kinematics/vision/detect.py"
READINGS = "so101_kinematics/virtual/sensor_registers.py"
T_CONTROL, T_RUN = "tests/hw/test_control.py", "tests/hw/test_hw_run.py"
T_HW = "tests/course_files/test_pick_place_hw.py"
T_IK = "tests/course_files/test_so101_inverse_kinematics.py"
T_FK = "tests/course_files/test_so101_forward_kinematics.py"
T_SIM = "tests/course_files/test_pick_place_sim.py"
T_PROFILES = "tests/lab/test_profile_compare.py"
T_LINE = "tests/planning/test_straight_line.py"
LEAD, T_LEAD = "so101_kinematics/hw/lead.py", "tests/hw/test_lead.py"
GUARDED, T_GUARD = "so101_kinematics/hw/guarded.py", "tests/hw/test_guarded_registers.py"
DRAW_PLAN = "so101_kinematics/drawing/pen_plan.py"
DRAW_SCORE = "so101_kinematics/drawing/ink_score.py"

MUTANTS: list[Mutant] = [
    # --- the servo model (issue 25) --------------------------------------------------------
    m("servo_no_dead_zone", "the firmware's dead zone left out of the duty law",
      "so101_kinematics/servo.py", "duty", "if size <= settings.dead_zone:", "if size < 0:",
      "tests/sim/test_sts3215.py"),
    m("servo_slope_doubled", "the loop's P/4 per count taken as P/2 (twice as stiff)",
      "so101_kinematics/sim/sts3215.py", "ServoBank._derive", "[p / 4.0 for p in self.p]",
      "[p / 2.0 for p in self.p]", "tests/sim/test_sts3215.py"),
    m("servo_no_acceleration_ramp", "the Acceleration register ignored (the target jumps)",
      "so101_kinematics/sim/sts3215.py", "ServoBank._derive",
      "[a * servo.ACCELERATION_UNIT or math.inf for a in self.acceleration]",
      "[math.inf for a in self.acceleration]", "tests/sim/test_sts3215.py"),
    m("servo_supply_ignored", "the torque taken at the nominal voltage, not the supply's",
      "so101_kinematics/sim/sts3215.py", "ServoBank.torques",
      "newtons = self.variant.torque_per_volt * self.volts / 1000.0",
      "newtons = self.variant.torque_per_volt * self.variant.nominal_volts / 1000.0",
      "tests/sim/test_sts3215.py"),
    m("servo_torque_limit_ignored", "Torque_Limit does not cap the duty",
      "so101_kinematics/sim/sts3215.py", "ServoBank._derive",
      "[min(t, servo.DUTY_MAX) for t in self.torque_limit]",
      "[servo.DUTY_MAX for t in self.torque_limit]", "tests/sim/test_sts3215.py"),
    m("gravity_sign", "the holding torque's sign flipped (the feed-forward doubles the sag)",
      "so101_kinematics/gravity.py", "holding_torques_rad",
      "torques.append(float(GRAVITY *", "torques.append(float(-GRAVITY *",
      "tests/sim/test_sts3215.py"),
    m("feedforward_friction_backwards", "the friction offset against the direction of motion",
      "so101_kinematics/gravity.py", "Feedforward.apply",
      "direction[joint] = 1.0 if change > 0 else -1.0",
      "direction[joint] = -1.0 if change > 0 else 1.0", T_SIM),
    # --- the model and the FK ------------------------------------------------------------
    m("fk_g23_sign", "a wrong sign in a get_gxx factor (elbow_flex turned the other way)",
      "so101_forward_kinematics.py", "get_g23",
      'joint_transform("23", check_angle(', 'joint_transform("23", -check_angle(', T_FK),
    m("gripper_tilt_dropped", "the gripper mount's -2.79 deg tilt left out of g45",
      FRAMES, None, '("z", GRIPPER_MOUNT_TILT_DEG)))', '("z", 0.0)))', T_FK),
    m("object_frame_2mm", "the object frame moved 2 mm along x of frame 5",
      FRAMES, None, '"5t": (model_facts.site_position("object_frame"), ()),',
      '"5t": (tuple(np.add(model_facts.site_position("object_frame"), (0.002, 0, 0))), ()),',
      T_FK),
    m("object_frame_half_turned", "the object frame half a turn about y (z down, before the "
      "course's IK assignment redrew it)", FRAMES, None, 'site_position("object_frame"), ()),',
      'site_position("object_frame"), (("y", 180.0),)),', T_FK, "tests/ik/test_call_shapes.py",
      more=(Edit("so101_kinematics/fast_fk.py", "_closed_form_assumptions", '"5t": np.eye(3),',
                 '"5t": Ry(180.0),'),
            Edit("so101_kinematics/fast_fk.py", None, "    Rx,\n", "    Rx,\n    Ry,\n"))),
    m("ik_course_yaw_any_grasp", "the course's IK shapes take any of the cube's grasps, not "
      "the asked frame", "so101_kinematics/ik/call_shapes.py", "get_inverse_kinematics",
      'return solve_keywords(position, "down", 0.0, initial=initial, gripper=gripper,\n'
      '                                  min_height=min_height, exact_yaw=True)',
      'return solve_keywords(position, "down", 0.0, initial=initial, gripper=gripper,\n'
      '                                  min_height=min_height, exact_yaw=False)',
      "tests/ik/test_call_shapes.py",
      more=(Edit("so101_kinematics/ik/call_shapes.py", "_solve_rotation",
                 'return solve_keywords(position, "down", yaw, exact_yaw=True, **solve)',
                 'return solve_keywords(position, "down", yaw, exact_yaw=False, **solve)'),)),
    m("ik_tilted_yaw_uncorrected", "a tilted orientation solved once, its yaw never corrected",
      "so101_kinematics/ik/call_shapes.py", "_solve_rotation", "        yaw += turn",
      "        break",
      "tests/ik/test_call_shapes.py"),
    m("hold_ignores_cfg", "hold_position(m, d, viewer, cfg, duration) holds the old command",
      "so101_kinematics/sim/stepping.py", "hold_position", "d.ctrl[act] = angles[name]", "pass",
      "tests/course_files/test_so101_mujoco_utils.py", "tests/sim/test_ik_demo.py"),
    m("sim_move_jumps_to_start", "move_to_pose's starting_cfg used as the path's start (a jump)",
      "so101_kinematics/sim/stepping.py", "move_to_pose",
      "path = Trajectory(command, goal, duration, profile)",
      "path = Trajectory(dict(command, **(start or {})), goal, duration, profile)",
      "tests/course_files/test_so101_mujoco_utils.py"),
    m("hw_move_jumps_to_start", "the arm's move_to_pose jumps to the starting_position given",
      "so101_kinematics/hw/course_helpers.py", "course_move_to_pose",
      "        session.move(target, seconds, profile=profile, velocity_ff=velocity_ff)",
      "        session.command.update(start or {})\n"
      "        session.move(target, seconds, profile=profile, velocity_ff=velocity_ff)",
      "tests/course_files/test_so101_utils.py"),
    m("start_mismatch_silent", "a starting configuration far from the last command not named",
      "so101_kinematics/inputs.py", "start_mismatch",
      "if gap <= START_MISMATCH + allowance.get(joint, 0.0):", "if True:",
      "tests/course_files/test_so101_mujoco_utils.py",
      "tests/course_files/test_so101_utils.py"),
    m("degrees_off_5", "one joint's degree conversion off by 5 deg (elbow_flex)",
      SCENE, "to_radians", "else math.radians(value)",
      'else math.radians(value + (5.0 if name == "elbow_flex" else 0.0))',
      "tests/course_files/test_so101_mujoco_utils.py"),
    m("sim_gripper_inverted", "the simulator's gripper 0-100 mapping inverted, both ways",
      SCENE, "gripper_to_radians", "return float(lower + (upper - lower) * percent / 100.0)",
      "return float(upper - (upper - lower) * percent / 100.0)",
      "tests/course_files/test_so101_mujoco_utils.py",
      more=(Edit(SCENE, "gripper_from_radians",
                 "return float((angle - lower) / (upper - lower) * 100.0)",
                 "return float((upper - angle) / (upper - lower) * 100.0)"),)),
    m("lerobot_gripper_inverted", "the gripper's ticks <-> 0-100 mapping inverted, both ways",
      CAL, "ticks_to_user", "return 100.0 - value if cal.drive_mode else value",
      "return value if cal.drive_mode else 100.0 - value",
      "tests/core/test_calibration_files.py",
      more=(Edit(CAL, "user_to_ticks", "value = 100.0 - value if cal.drive_mode else value",
                 "value = value if cal.drive_mode else 100.0 - value"),)),
    m("calibration_ranges_swapped", "range_min and range_max swapped in the calibrated limits",
      CAL, "calibrated_limits", "(ticks_to_user(joint, cal.range_min, cal),\n"
      "                             ticks_to_user(joint, cal.range_max, cal))",
      "(ticks_to_user(joint, cal.range_max, cal),\n"
      "                             ticks_to_user(joint, cal.range_min, cal))",
      "tests/core/test_calibration_files.py"),
    m("frame_axes_uncoloured", "the FK frames picture draws its axes without their colours",
      "so101_kinematics/sim/fk_pictures.py", None,
      "AXIS_RGBA = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.7, 0.1, 1.0), (0.1, 0.3, 0.95, 1.0))",
      "AXIS_RGBA = ((0.5, 0.5, 0.5, 1.0),) * 3",
      "tests/course_files/test_fk_mujoco_screenshot.py::test_frames_picture_renders"),
    # --- motion and the simulation ---------------------------------------------------------
    m("minimum_jerk_linear", "minimum jerk replaced by linear time scaling",
      "so101_kinematics/planning/profiles.py", "minimum_jerk",
      "return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))", "return s", T_CONTROL),
    m("ik_elbow_branch", "the IK tries only one elbow branch",
      "so101_kinematics/ik/search.py", "_Search.try_pitch", "for elbow in (1.0, -1.0):",
      "for elbow in (-1.0,):", f"{T_IK}::test_every_reachable_position_is_solved",
      f"{T_IK}::test_every_reachable_top_down_target_is_solved"),
    m("friction_min", "contact-pair friction mixed with min instead of MuJoCo's max",
      "so101_kinematics/sim/contact_pairs.py", "mixed_contact_parameters",
      "friction = np.maximum(", "friction = np.minimum(", "tests/sim/test_contact_pairs.py"),
    m("placement_tolerance_10cm", "the placement tolerance 10 cm instead of 1 cm",
      PICK, None, "PLACEMENT_TOLERANCE = 0.010", "PLACEMENT_TOLERANCE = 0.100",
      f"{T_SIM}::test_success_is_within_10_mm_and_10_deg"),
    m("tilt_not_judged", "tilt dropped from the success criterion",
      PICK, "_report", "and error <= PLACEMENT_TOLERANCE and tilt <= TILT_TOLERANCE)",
      "and error <= PLACEMENT_TOLERANCE)", f"{T_SIM}::test_success_is_within_10_mm_and_10_deg"),
    m("success_without_lift", "a cube pushed along the table (never lifted) counts as placed",
      PICK, "_report", "and monitor.max_lift >= MIN_LIFT", "",
      f"{T_SIM}::test_a_cube_never_lifted_or_dropped_on_the_way_is_no_success"),
    m("drop_never_seen", "the cube monitor never notes a drop",
      "so101_kinematics/sim/cube.py", "CubeMonitor.check", "self.dropped = True", "pass",
      f"{T_SIM}::test_opening_the_jaws_in_the_air_is_reported_as_a_drop"),
    # --- straight lines in task space (issue 27) ----------------------------------------------
    m("straight_line_linear_time", "the line's cubic time scaling dropped (s for f(s)): the "
      "object frame starts and stops at full speed",
      "so101_kinematics/planning/straight_line.py", "straight_path", "f = cubic(s)", "f = s",
      f"{T_LINE}::test_the_ik_line_follows_the_cubic_time_scaling_with_zero_end_speeds"),
    m("cubic_a3_sign", "the cubic's a3 with the wrong sign (3 s^2 + 2 s^3): the line overshoots "
      "its end", "so101_kinematics/planning/profiles.py", "cubic", "return s * s * (3.0 - 2.0 * s)",
      "return s * s * (3.0 + 2.0 * s)",
      f"{T_LINE}::test_the_ik_line_follows_the_cubic_time_scaling_with_zero_end_speeds"),
    m("straight_line_tilt_sign", "the approach axis's tilt error with the wrong sign (cross "
      "product operands swapped): the orientation is pushed away from top-down",
      "so101_kinematics/ik/refine.py", "line_task", "np.cross(z_t, wanted)",
      "np.cross(wanted, z_t)", f"{T_LINE}::test_every_sample_is_on_the_segment_top_down_"
      "within_the_limits"),
    # --- the bus and the protocol ------------------------------------------------------------
    m("checksum_without_id", "the Feetech checksum leaves out the servo id",
      PROTOCOL, "checksum", "return ~sum(body) & 0xFF", "return ~sum(body[1:]) & 0xFF",
      "tests/virtual/test_protocol.py"),
    m("homing_offset_sign_bit_15", "Homing_Offset's sign bit at 15 instead of 11",
      PROTOCOL, None, 'SIGN_BITS = {"Homing_Offset": 11,', 'SIGN_BITS = {"Homing_Offset": 15,',
      "tests/virtual/test_protocol.py"),
    m("virtual_torque_limit_ignored", "the virtual servo's duty capped by Max_Torque_Limit "
      "only: Torque_Limit (48) written through the bus ignored", REGISTERS, "servo_settings",
      'cap = min(servo.get("Torque_Limit"), servo.get("Max_Torque_Limit"))',
      'cap = servo.get("Max_Torque_Limit")',
      f"{T_SDK}::test_torque_limit_30_and_the_shoulder_no_longer_lifts"),
    m("virtual_step_from_stale_goal", "step mode entered from wheel mode steps from the old "
      "position goal, not from where the joint is", REGISTERS, "ServoRegisters.write",
      "if servo.torque and (not was_on or (regs[33] == STEP_MODE and old_mode != STEP_MODE)):",
      "if servo.torque and not was_on:",
      f"{T_SDK}::test_step_mode_moves_by_the_counts_written_from_where_the_joint_is"),
    # --- the simulated clock (virtual/sim_clock.py) ------------------------------------------
    m("sim_clock_physics_slips", "on the simulated clock the physics takes at most 25 steps a "
      "sleep, as the wall clock's catch-up does: the arm lags the program's time",
      REGISTERS, "ServoRegisters.step_physics",
      "due = self.sim_clock.target_ns // self.dt_ns - self.steps",
      "due = min(25, self.sim_clock.target_ns // self.dt_ns - self.steps)",
      f"{T_SIM_CLOCK}::test_the_physics_never_slips_on_the_simulated_clock_but_does_on_the_wall_clock"),
    m("sim_clock_silence_free", "a request nobody answers costs the program no simulated time "
      "(a 0.5 s outage becomes 50 failed cycles instead of 5)",
      "so101_kinematics/virtual/emulator.py", "_Emulator.on_serial",
      "self.sim_clock.charge(LEROBOT_TIMEOUT_S)  # the host waited for a reply in vain", "pass",
      f"{T_SIM_CLOCK}::test_an_unanswered_request_costs_the_program_lerobots_timeout"),
    m("drill_loop_on_the_wall_clock", "the drill's control loop on the wall clock while its arm "
      "waits for the simulated time", "so101_kinematics/lab/fault_drill.py", "run_drill",
      "profile=profile, time_source=arm.clock)", "profile=profile, time_source=None)",
      f"{T_SIM_CLOCK}::test_a_drill_of_the_fault_matrix_ends_as_the_policy_says_on_the_simulated"
      "_clock"),
    # --- the control loop and its fault policy --------------------------------------------------
    m("misread_acted_on", "a reading outside the calibrated range taken as the arm's pose",
      "so101_kinematics/hw/misreads.py", "ReadingCheck.__call__",
      "if not (lower - RANGE_MARGIN <= value <= upper + RANGE_MARGIN):", "if False:",
      "tests/hw/test_misreads.py"),
    m("speed_cap_ignored", "the speed cap ignored: a move never stretched",
      TIMING, "capped_duration", "return max(float(duration), needed)",
      "return float(duration)", T_CONTROL),
    m("speed_cap_1000", "the default speed cap at 1000 deg/s",
      TIMING, None, "MAX_JOINT_SPEED_DEG_S = 100.0", "MAX_JOINT_SPEED_DEG_S = 1000.0",
      f"{T_CONTROL}::test_first_move_ramps_from_the_measured_pose_within_the_speed_cap"),
    m("tracking_tolerance_1000", "the tracking tolerance at 1000 deg: a stall never seen",
      TIMING, None, "TRACKING_TOLERANCE_DEG = 15.0", "TRACKING_TOLERANCE_DEG = 1000.0",
      T_CONTROL),
    m("gripper_tracked", "the gripper's squeeze taken for a stall",
      TIMING, "tracking_tolerances", '(None if j == "gripper" else arm_tolerance)',
      "arm_tolerance", T_CONTROL),
    m("deadline_drift", "the rate loop schedules from now instead of the previous deadline",
      TIMING, "RateLoop.wait", "self.deadline += self.period\n",
      "self.deadline = self.clock() + self.period\n", T_CONTROL),
    m("guard_unchecked", "ArmSession._guard returns the command unchecked",
      "so101_kinematics/hw/goals.py", "guard", "    out = {}\n",
      "    return dict(command)\n    out = {}\n", T_CONTROL),
    m("stop_not_clamped", "the controlled stop sends the measured pose unclamped",
      CONTROL, "ArmSession.stop_here",
      "goal = {j: min(self.limits[j][1], max(self.limits[j][0], pose[j])) for j in JOINTS}",
      "goal = dict(pose)", T_CONTROL),
    # The same bug three times: each of the three tests must catch it on its own.
    m("return_speed_200", "the abort return at 200 deg/s instead of 20 (the commands)",
      CONTROL, None, "RETURN_SPEED_DEG_S = 20.0", "RETURN_SPEED_DEG_S = 200.0",
      f"{T_CONTROL}::test_the_abort_return_goes_at_20_deg_per_s"),
    m("return_speed_200_run", "the abort return at 200 deg/s instead of 20 (a run's ending)",
      CONTROL, None, "RETURN_SPEED_DEG_S = 20.0", "RETURN_SPEED_DEG_S = 200.0",
      f"{T_RUN}::test_stop_request_returns_slowly_to_the_start_and_releases"),
    m("return_speed_200_virtual_arm",
      "the abort return at 200 deg/s instead of 20 (the virtual arm's clock)",
      CONTROL, None, "RETURN_SPEED_DEG_S = 20.0", "RETURN_SPEED_DEG_S = 200.0",
      f"{T_HW}::test_ctrl_c_mid_motion_returns_to_the_start_and_releases"),
    m("first_move_from_home", "the first move ramps from the home pose, not the measured one",
      CONTROL, "ArmSession.move", "self.command = self.read_pose()  # the first move",
      "self.command = {j: 0.0 for j in JOINTS}  # the first move", T_CONTROL),
    m("outage_tolerance_ignored", "an outage of any length ridden through (never stops)",
      CONTROL, "ArmSession._cycle", "if unobserved > self.outage_tolerance:", "if False:",
      T_CONTROL, T_RUN),
    m("outage_not_tolerated", "the first failed read stops the motion (no ride-through)",
      CONTROL, "ArmSession._cycle", "if unobserved > self.outage_tolerance:", "if True:",
      T_CONTROL, T_RUN),
    m("clock_runs_while_blind", "the trajectory clock not paused during an outage",
      CONTROL, "ArmSession._run", "if self.observed:", "if True:", T_CONTROL),
    m("status_bits_ignored", "the servos' error bits ignored",
      CHECKS, "check_status", "        if faults:\n", "        if False:\n", T_CONTROL, T_RUN),
    m("gripper_overload_stops", "the gripper's overload (its squeeze) stops the motion",
      CHECKS, "check_status", "bits &= ~GRIPPER_OVERLOAD", "pass", T_CONTROL),
    m("release_away_from_start", "torque released wherever the run ended",
      RUN, "finish", "        if result.returned_to_start:\n            result.unreleased",
      "        if True:\n            result.unreleased", T_RUN),
    m("no_return_after_abort", "no slow return after an abort: the arm holds where it stopped",
      RUN, "after_abort", "                session.return_slowly(put_down(session, plan, held, "
      "error, start_pose))\n                result.returned_to_start = True",
      "                pass", T_RUN),
    # --- the velocity feed-forward on the arm (issue 27) ---------------------------------------
    m("velocity_lead_sign", "the lead's sign flipped (the goal trails the plan: twice the lag)",
      LEAD, "lead_for", "lead = {j: lag_s.get(j, 0.0) * v", "lead = {j: -lag_s.get(j, 0.0) * v",
      f"{T_LEAD}::test_the_lead_is_lag_times_velocity_with_its_sign"),
    m("velocity_lead_sign_virtual_arm", "the lead's sign flipped (measured on the virtual arm)",
      LEAD, "lead_for", "lead = {j: lag_s.get(j, 0.0) * v", "lead = {j: -lag_s.get(j, 0.0) * v",
      f"{T_LEAD}::test_velocity_ff_removes_most_of_the_lag_the_servo_model_predicts"),
    m("velocity_lead_uncapped", "the lead's cap removed (31 deg ahead at 300 deg/s)",
      LEAD, "lead_for", "scale = cap / largest if largest > cap else 1.0", "scale = 1.0",
      f"{T_LEAD}::test_a_fast_move_is_led_by_less_than_the_tracking_tolerance_in_the_same_"
      "direction"),
    m("velocity_lead_past_the_goal", "the led goal not kept within its move (overshoots the goal)",
      LEAD, "led_goal", "out[joint] = min(high, max(low, value + lead.get(joint, 0.0)))",
      "out[joint] = value + lead.get(joint, 0.0)",
      f"{T_LEAD}::test_the_led_goal_stays_on_the_move_and_is_the_plan_at_rest"),
    m("velocity_lead_while_silent", "the lead kept while the arm does not answer (the goal runs "
      "ahead of the paused plan)", CONTROL, "ArmSession._run",
      "lead_at(elapsed, planned) if lead_at and self.observed else None",
      "lead_at(elapsed, planned) if lead_at else None",
      f"{T_LEAD}::test_the_goal_written_leads_the_plan_and_pauses_with_it"),
    m("log_not_flushed", "the run's log not flushed as the run goes",
      LOG, "CycleLog.__call__", "            self._handle.flush()\n", "            pass\n",
      "tests/hw/test_hw_log.py"),
    m("traj_clipping_unchecked", "so101-check-traj never looks past the duration (a cubic "
      "whose time is not clipped goes unnamed)", "so101_kinematics/checker/traj_compare.py",
      "move_causes", "after = t > duration + timestep / 2", "after = t > math.inf",
      "tests/checker/test_traj_checker.py"),
    # --- the write-up's comparison of profiles from real runs (issue 27, Deliver 8) -------
    m("fitted_jerk_factor", "the fitted cubic's third derivative taken as 2 c3 (not 3! c3)",
      "so101_kinematics/planning/motion_metrics.py", "fitted_derivatives",
      "6.0 * c[:, 3] / scale**3", "2.0 * c[:, 3] / scale**3", T_PROFILES),
    m("misread_window_from_the_ends", "the time between two readings' samples taken from "
      "the reads' ends: a read stamped late makes a swinging joint's step a misread",
      "so101_kinematics/hw/misreads.py", "ReadingCheck.__call__",
      "now if started is None else min(started, now)", "now",
      "tests/hw/test_misreads.py::"
      "test_the_time_between_samples_runs_from_the_last_reads_start_to_this_ones_end"),
    m("misread_reply_kept", "a misread reply (-2900 deg for one cycle) kept in the figures",
      "so101_kinematics/lab/sim_vs_arm.py", "compare_run", "    if wrong:\n", "    if False:\n",
      T_PROFILES),
    m("return_refused_at_rest", "the return to where the released arm slumped refused (the "
      "clearance margin applied to the arm's own rest)", "so101_kinematics/clearance.py",
      "check_path", "    if rest is not None:\n", "    if False:\n",
      "tests/core/test_clearance.py::test_the_return_may_come_down_to_where_the_arm_stood_no_lower"),
    # --- the checkers are honest (issue 33, Deliver 6) ------------------------------------
    m("standin_qposadr_an_int", "the checker's stand-in gives m.joint(...).qposadr as an int "
      "(MuJoCo: an array; the project's own utils scored 0/100)",
      "so101_kinematics/checker/traj_standin.py", "_View.__init__",
      "array[index:index + 1] if array.ndim == 1 else", "array[index] if array.ndim == 1 else",
      "tests/checker/test_checker_honesty.py::test_the_projects_own_cubic_utils_scores_100_through_the_"
      "console_script"),
    m("sandbox_not_confined", "the submission's writes not audited (one writing outside its "
      "folder scored 100)", "so101_kinematics/checker/probe.py", "main",
      "    confine(os.getcwd(), own_files(result_path))\n", "    pass\n",
      "tests/checker/test_checker_honesty.py::test_a_submission_cannot_write_outside_its_temporary_"
      "folder"),
    m("sandbox_parent_allowed", "the confinement allows the temporary folder's parent (../ "
      "reaches the probe's own results)", "so101_kinematics/checker/probe.py", "confine",
      "root = os.path.realpath(folder)", "root = os.path.dirname(os.path.realpath(folder))",
      "tests/checker/test_checker_honesty.py::test_a_submission_cannot_write_outside_its_temporary_"
      "folder"),
    m("fk_input_change_unseen", "the FK probe calls the student's FK on a dict it never looks at "
      "again (a changed input reads as a wrong product order)",
      "so101_kinematics/checker/probe.py", "fk_call", "        if after != before:\n",
      "        if False:\n",
      "tests/checker/test_checker_honesty.py::test_an_fk_that_changes_its_input_is_named_not_a_product_"
      "order"),
    m("feedforward_line_at_zero", "the feed-forward's line shows the all-zero pose's offsets as "
      "the arm's", "so101_kinematics/hw/feedforward.py", "describe_at_pose",
      "pose, where = read_pose(bus), \"the arm's pose as read now\"",
      "pose, where = dict.fromkeys(JOINTS, 0.0), \"the arm's pose as read now\"",
      "tests/core/test_true_messages.py::test_the_feedforward_line_gives_the_offsets_at_the_arms_pose_"
      "and_says_so"),
    m("timing_options_ignored_with_plan", "--move-duration/--hold silently ignored with --plan",
      "so101_kinematics/cli.py", "ignored_with_plan",
      "    if not given or getattr(args, \"plan\", None) is None:\n", "    if True:\n",
      "tests/core/test_true_messages.py::test_timing_options_given_with_a_plan_are_refused_not_ignored"),
    m("hand_check_holds_the_bus", "the virtual hand's table check holds the bus for the whole "
      "path (lerobot-calibrate's 1-try reads time out)", "so101_kinematics/virtual/hand.py",
      None, 'between=getattr(self, "serve_serial", None),', "between=None,",
      "tests/virtual/test_virtual_fidelity.py::test_the_bus_is_answered_while_the_hand_checks_a_long_path"),
    m("replay_drops_the_lead", "the --compare replay sends the plan, not the led goals the "
      "servos got (--velocity-ff)", "so101_kinematics/lab/sim_vs_arm.py", "compare_run",
      'commanded[j] + np.array([r[f"lead_{j}"] for r in rows])', "commanded[j] + 0.0",
      "tests/lab/test_sim_vs_arm.py::test_a_led_run_is_replayed_with_the_goals_the_servos_got"),
    m("replay_on_schedule", "the --compare replay sends each goal at its scheduled time, not "
      "when the late cycle sent it", "so101_kinematics/lab/sim_vs_arm.py", "compare_run",
      "simulated = replay(read_s, commands_inside_limits(",
      "simulated = replay(t, commands_inside_limits(",
      "tests/lab/test_sim_vs_arm.py::test_the_replay_sends_each_goal_when_the_arm_got_it"),
    m("replay_refuses_past_limit", "--compare sends the return to a slumped start (just past a "
      "model limit) as logged: the replay refuses it and stops every log's comparison",
      "so101_kinematics/lab/sim_vs_arm.py", "compare_run",
      "replay(read_s, commands_inside_limits(written, notes), start,",
      "replay(read_s, written, start,",
      f"{T_PROFILES}::test_a_log_that_starts_past_a_limit_is_replayed_from_the_limit"),
    m("aborted_run_pooled", "--compare counts an aborted run in a profile's run-to-run "
      "variation", "so101_kinematics/lab/profile_compare.py", "compare_profiles",
      "if run.profile == profile and not run.comparison.aborted]", "if run.profile == profile]",
      f"{T_PROFILES}::test_an_aborted_run_is_marked_and_not_pooled"),
    m("aborted_figures_with_return", "an aborted run's figures take in the stop and the slow "
      "return", "so101_kinematics/lab/profile_compare.py", "run_figures",
      "n = comparison.stopped_at or len(comparison.t)", "n = len(comparison.t)",
      f"{T_PROFILES}::test_an_aborted_run_is_marked_and_not_pooled"),
    m("sag_free_air", "--compare's sag is the free-air figure (the jaw 16 mm through the "
      "table), not the simulator's with the table", "so101_kinematics/lab/sag.py",
      "simulated_sag", "return ({j: round(reached[j] - pose[j], 2) for j in ARM_JOINTS},",
      "from so101_kinematics.gravity import feedforward\n"
      "    from so101_kinematics.servo import LEROBOT\n"
      "    free = feedforward(pose, LEROBOT.with_(p=p), volts)\n"
      "    return ({j: round(-free[j], 2) for j in ARM_JOINTS},",
      f"{T_PROFILES}::test_the_sag_printed_is_the_simulators_with_the_table"),
    m("table_contact_unseen", "the week-9 log does not record the jaw on the table: the "
      "profiles are ranked on the impact's figures", "so101_kinematics/sim/tracking.py",
      "StepLog.sync", "if touching:", "if False:",
      "tests/planning/test_trajectories.py::"
      "test_a_jaw_on_the_table_is_reported_and_the_profiles_not_ranked"),
    # --- the virtual STS3215's readings and the rest of its table (issue 34) -------------------
    m("virtual_overload_keeps_the_output", "overload protection sets the bit but never drops "
      "the output to Protective_Torque", REGISTERS, "servo_settings", "    if servo.protected:\n",
      "    if False:\n",
      f"{T_SDK}::test_overload_drops_the_output_to_protective_torque_and_says_so"),
    m("virtual_id_254_accepted", "a write of ID 254 accepted (the servo then answers broadcast "
      "READs)", REGISTERS, "ServoRegisters.write", "if regs[5] > MAX_SERVO_ID:", "if False:",
      f"{T_SDK}::test_an_id_above_253_is_refused"),
    m("virtual_pwm_direction_flipped", "a positive PWM duty turns the way Present_Position "
      "counts up", READINGS, None, "PWM_DIRECTION = -1", "PWM_DIRECTION = 1",
      f"{T_SDK}::test_pwm_mode_runs_open_loop_at_the_duty_written"),
    m("virtual_limp_draws_current", "a limp, back-driven servo reports its EMF's current",
      READINGS, "SensorReadings.current", "        if not servo.torque:\n",
      "        if False:\n", f"{T_SDK}::test_a_limp_falling_joint_draws_no_current"),
    m("virtual_duplicate_ids_always_garbled", "two servos with one ID garble every reply, "
      "identical or not", "so101_kinematics/virtual/instructions.py", None,
      "GARBLED_FRACTION = 0.4", "GARBLED_FRACTION = 1.0",
      f"{T_SDK}::test_two_servos_with_one_id_fail_the_sdks_transactions_but_both_obey"),
    m("virtual_load_constant_at_rest", "Present_Load ignores the encoder's count of noise",
      READINGS, "SensorReadings.refresh", "load += self.jitter_duty(servo, jitter)",
      "load += 0.0",
      f"{T_SDK}::test_load_current_and_voltage_at_rest_live_within_a_sensors_band"),
    m("virtual_offset_outside_position_mode", "wheel/PWM/step modes subtract Homing_Offset "
      "from Present_Position", READINGS, None, "ENCODER_OUTSIDE_POSITION_MODE = True",
      "ENCODER_OUTSIDE_POSITION_MODE = False",
      f"{T_SDK}::test_present_position_is_the_bare_encoder_outside_position_mode"),
    m("output_written_in_place", "an output file written in place (lost if the run fails)",
      "so101_kinematics/outputs.py", "atomic_output", "temporary = temporary_beside(target)",
      "temporary = target",
      "tests/core/test_inputs.py::test_atomic_output_keeps_the_old_file_on_an_error"),
    # issue 33: outputs recognised by their content (markers.py), never by their type
    m("png_recognised_by_type", "any PNG taken for one of ours (no Software marker needed)",
      MARKERS, "png_ours", 'head[4:] == b"IEND":\n                    return False',
      'head[4:] == b"IEND":\n                    return True',
      f"{T_OUT}::test_hw_plot_keeps_another_programs_png"),
    m("mp4_recognised_by_type", "any MP4 taken for one of ours (no comment marker needed)",
      MARKERS, "mp4_ours", "return _MARKER in handle.read(size - header)", "return True",
      f"{T_OUT}::test_sim_record_keeps_another_programs_video"),
    m("pdf_recognised_by_type", "any PDF taken for one of ours (no Creator marker needed)",
      MARKERS, "pdf_ours", 'return b"/Creator (" + _MARKER in handle.read()', "return True",
      f"{T_OUT}::test_hw_sheet_keeps_the_courses_handout"),
    m("json_of_another_program", "a JSON report of another of our programs is replaced",
      OUTPUTS, "_stamped", "return program is None or", "return True or",
      f"{T_OUT}::test_sim_json_keeps_another_scripts_report"),
    m("symlink_followed", "an output reached through a symbolic link is written through it",
      OUTPUTS, "check_output_path", "if target.is_symlink() and not overwrite:", "if False:",
      f"{T_OUT}::test_an_output_through_a_symlink_is_refused_and_overwrite_replaces_the_link"),
    m("earlier_log_replaced", "--log replaces the log (and sidecar) of an earlier run",
      OUTPUTS, "check_output_path",
      "if kind is not None and not kind.replaceable and kind.recognise(target):", "if False:",
      f"{T_OUT}::test_hw_log_and_sidecar_of_an_earlier_run_are_never_replaced"),
    m("writable_by_permission_bits", "an output's folder trusted by its permission bits (root "
      "passes /proc; the run dies after it began)", OUTPUTS, "check_output_path",
      "probe = temporary_beside(target)\n        probe.unlink()",
      "probe = target\n        probe.exists()",
      f"{T_OUT}::test_a_simulator_refuses_an_unwritable_output_before_it_runs",
      f"{T_OUT}::test_hw_unwritable_output_is_refused_before_the_port_opens"),
    m("part_left_on_sigterm", "a SIGTERM leaves the hidden .part file of an output",
      OUTPUTS, "_clean_up_on_stop_signals", "if signal.getsignal(signum) == signal.SIG_DFL:",
      "if False:", f"{T_OUT}::test_a_stop_leaves_no_hidden_part_file"),
    m("part_remade_by_a_late_encoder", "a stop removes the .part file but leaves its encoder "
      "running, which opens it again later", OUTPUTS, "_remove_and_die",
      "_stop_writers({temporary.name for temporary in ours})", "pass",
      f"{T_OUT}::test_a_stop_before_the_encoder_opens_its_output_leaves_no_part_file"),
    m("link_replaces_a_users_symlink", "virtual_so101.py --link replaces (and at exit deletes) "
      "a symlink it did not make", "virtual_so101.py", "make_link",
      'if not (target.startswith("/dev/pts/") and not os.path.exists(target)):', "if False:",
      f"{T_OUT}::test_link_never_replaces_or_deletes_a_users_symlink"),
    m("plot_data_closes_its_figure", "plot_data closes its figure (plt.savefig after it: blank)",
      "so101_kinematics/planning/trajectory_log.py", "plot_data", "    return fig\n",
      "    plt.close(fig)\n    return fig\n",
      "tests/planning/test_trajectories.py::test_plot_data_leaves_the_figure_to_the_caller"),
    m("put_down_skipped", "a stop with a cube in the jaws returns with it (the gripper squeezes "
      "it at the rest; issue 33)", RUN, "after_abort",
      "session.return_slowly(put_down(session, plan, held, error, start_pose))",
      "session.return_slowly(start_pose)",
      "tests/hw/test_stop_with_cube.py::"
      "test_ctrl_c_after_the_grasp_puts_the_cube_down_at_the_place_then_returns"),
    m("stop_lets_go_of_the_cube", "the controlled stop sets a holding gripper's goal to its "
      "width: the squeeze ends and the cube slides out of the stopped jaws (12 V: upside down)",
      CONTROL, "ArmSession.stop_here",
      'goal["gripper"] = self.command["gripper"]  # the squeeze goes on', "pass",
      "tests/hw/test_stop_with_cube.py::"
      "test_a_fault_while_holding_puts_the_cube_straight_down_where_it_is"),
    m("held_while_closing", "jaws still closing in free air taken for a held cube (every stop "
      "at a grasp would then put down nothing)", "so101_kinematics/hw/grip.py", "held_grip",
      "if max(recent) - min(recent) > SETTLED_PCT:", "if False:",
      "tests/hw/test_putdown.py::test_jaws_closed_on_nothing_or_still_closing_hold_nothing"),
    m("held_cube_squeezed", "a cube that cannot be put down is squeezed by the return to the "
      "start's narrower gripper", "so101_kinematics/hw/putdown.py", "put_down",
      'target["gripper"] = max(start["gripper"], width)', 'target["gripper"] = start["gripper"]',
      "tests/hw/test_putdown.py::test_a_cube_that_cannot_be_put_down_is_not_squeezed_by_the_return"),
    # --- every register a student writes is guarded, the last line read back (issue 33) --
    m("torque_limit_passed_through", "the guarded bus passes a motion register at any value "
      "(Torque_Limit 0 drops the arm with torque on)", GUARDED, "register_refusal",
      "if register in COURSE and all(", "if register in COURSE or all(",
      f"{T_GUARD}::test_a_write_that_weakens_or_spins_the_arm_is_refused_naming_bus_raw"),
    m("torque_enable_0_passed_through", "Torque_Enable 0 on the guarded bus drops the arm where "
      "it is (not the guarded release)", GUARDED, "GuardedBus._register",
      "if data_name == TORQUE and any(", "if False and any(",
      f"{T_GUARD}::test_torque_enable_0_is_the_guarded_release_not_a_drop"),
    m("leftovers_survive_setup", "setup_motors leaves an earlier program's Goal_Velocity and "
      "Torque_Limit", "so101_kinematics/hw/servo_settings.py", "restore_course_values",
      "            bus.sync_write(register, wrong, normalize=False)", "            pass",
      f"{T_GUARD}::test_setup_motors_puts_back_what_an_earlier_program_left_and_says_so"),
    m("last_line_from_the_command", "the last line says what was commanded (torque ON, "
      "holding), not whether the servos can hold", RUN, "finish",
      "result.torque, result.unable, result.unread = read_back(", "_ = read_back(",
      f"{T_GUARD}::test_the_last_line_says_which_servo_cannot_hold_read_back",
      f"{T_GUARD}::test_the_hardware_scripts_ending_reads_back_too"),
    m("late_reply_believed", "the ending believes one read of each setting: a late reply "
      "of the register before passes for the servo's (P_Coefficient 1000 on a weakened servo)",
      "so101_kinematics/hw/servo_settings.py", "read_registers",
      "if register not in confirm or value in seen:", "if True:",
      f"{T_GUARD}::test_the_ending_believes_a_setting_only_when_two_reads_agree_and_says_what_it_"
      "could_not_read"),
    # --- the servo held to real arms' recordings (issue 34) ------------------------------------
    m("d_scale_one_period", "the D term's scale back to one 1 ms loop period (underdamped: "
      "steps overshoot where the recorded arms do not)", "so101_kinematics/servo.py", None,
      "D_SCALE_S = 0.03\n", "D_SCALE_S = 0.001\n",
      "tests/lab/test_replay.py::"
      "test_the_step_from_rest_does_not_overshoot_and_stops_short_as_the_arm_did"),
    m("elbow_stop_from_the_goals", "the elbow's stop taken from its largest goal (which goes "
      "past the stop) instead of its largest reading: the offset -0.09 deg, the replayed elbow "
      "folds past its goal again", "so101_kinematics/lab/replay.py", "estimated_offsets",
      "np.max(recording.state[:, j])", "np.max(recording.action[:, j])",
      "tests/lab/test_replay.py::"
      "test_with_the_estimated_offsets_every_step_stops_short_as_the_arm_did"),
    m("c001_on_12_v_accepted", "a supply above the variant's Max_Voltage_Limit accepted",
      "so101_kinematics/servo.py", "supply_problem", "if volts <= chosen.max_volts:",
      "if True:",
      "tests/core/test_cli_servo_options.py::test_a_c001_on_12_v_is_refused_with_the_fix"),
    m("ideal_ignores_options", "--servo ideal silently ignores --supply/--variant/--p-coefficient",
      "so101_kinematics/cli.py", "servo_from_arguments", 'if args.servo == "ideal" and given:',
      "if False:",
      "tests/core/test_cli_servo_options.py::test_the_ideal_servo_refuses_the_options_it_would_ignore"),
    m("virtual_arm_kit_default", "the virtual arm powers up on the kit's 5 V, not as the "
      "course's 12 V C018 follower", "so101_kinematics/virtual/electrical.py", None,
      "SUPPLY_V = DEFAULT_SUPPLY_V\n", "SUPPLY_V = 5.0\n",
      "tests/virtual/test_virtual_feetech_sdk.py::"
      "test_the_default_virtual_arm_is_the_courses_12_v_c018_follower"),
    m("unread_supply_kit", "with no Present_Voltage read the feed-forward guesses the kit's 5 V",
      "so101_kinematics/hw/feedforward.py", "read_feedforward",
      "if volts else servo.DEFAULT_SUPPLY_V", "if volts else servo.KIT_SUPPLY_V",
      "tests/hw/test_lead.py::"
      "test_nothing_read_the_feedforward_and_lead_assume_the_courses_12_v_c018"),
    # --- the docs (issue 35): every block runs or says why not -----------------------------
    m("docs_block_unmarked", "a README block that needs an arm loses its not-run marker",
      "README.md", None,
      "<!-- not run: starts a virtual arm that runs until stopped, then drives it for about "
      "30 s -->\n", "",
      "tests/docs/test_code_blocks.py::test_every_block_is_run_or_says_why_not"),
    m("docs_example_drifts", "a docs page's IK example calls an approach the IK does not have",
      "docs/ik.md", None, 'get_inverse_kinematics(p, approach=None)',
      'get_inverse_kinematics(p, approach="sideways")', "tests/docs/test_code_blocks.py"),
    m("docs_command_help_drifts", "the so101 command's help changes and its page keeps the old "
      "usage block", "so101_kinematics/commands/so101_command.py", "build_parser",
      'help="the placement sheet of a plan (PDF, print at 100 %%); no arm needed"',
      'help="the placement sheet of a plan (PDF); no arm needed"',
      "tests/docs/test_so101_command_page.py::test_the_usage_block_is_the_commands_help"),
    m("docs_module_unlisted", "a module of the package goes missing from the architecture "
      "page's table", "docs/architecture.md", None, " `sim_arm` `tag_textures` |",
      " `tag_textures` |",
      "tests/docs/test_architecture_page.py::test_every_module_is_on_the_architecture_page"),
    m("cube_sensor_stale", "the cube sensor keeps its first reading (the gripper is sent where "
      "the cube was)", "so101_kinematics/sensors/cube_reader.py", "CubeSensor.read",
      "data = self._read_block(SENSOR_ID, address(self.index), SIZE)",
      "data = self.__dict__.setdefault(\"_last\", self._read_block(SENSOR_ID, "
      "address(self.index), SIZE))",
      "tests/core/test_arm_interface.py::"
      "test_the_cube_sensor_asks_the_bus_at_every_read_never_a_stale_reading"),
    m("two_arms_first_end_resets", "the first of two arms to end puts back the default SIGTERM "
      "handler and unfreezes the heap under the other arm's moves",
      "so101_kinematics/hw/course_helpers.py", "_end", "    if not _RUNS:\n", "    if True:\n",
      "tests/hw/test_two_course_arms.py"),
    m("bus_arm_jumps", "the arm interface on a bare bus lets a far goal through (the servos "
      "jump there at full speed)", "so101_kinematics/hw/bus_arm.py", "BusArm._check_step",
      "if abs(step) > most:", "if abs(step) > 10 * most:",
      "tests/core/test_arm_interface.py::"
      "test_a_bare_bus_takes_small_steps_and_refuses_a_jump_with_nothing_sent"),
    # --- one home per fact (issue 35): the arm's facts read from model/so101.xml -------------
    m("facts_com_from_body_pos", "the links' centres of mass read from each body's pos (where "
      "it sits in its parent), not its <inertial>", "so101_kinematics/model_facts.py",
      "centre_of_mass", '_find("body", body).find("inertial").get("pos")',
      '_find("body", body).get("pos")', "tests/core/test_facts.py"),
    m("facts_jaw_pads_dropped", "the clearance check reads only class collision, not the jaw "
      "pads' class: the jaws' lowest boxes go unwatched", "so101_kinematics/model_facts.py",
      "collision_boxes", 'if geom.get("class") in BOX_CLASSES',
      'if geom.get("class") == "collision"',
      "tests/core/test_facts.py",
      "tests/core/test_clearance.py::test_the_check_places_every_collision_box_as_the_model_does"),
    m("encoder_resolution_copied", "the encoder's resolution written a second time (lerobot's "
      "max_res back as a literal in calibration.py)", CAL, None,
      "TICKS_PER_TURN = COUNTS_PER_TURN - 1", "TICKS_PER_TURN = 4095",
      "tests/core/test_facts.py::test_each_fact_is_written_once"),
    # --- one address per name (issue 35) --------------------------------------------------------
    m("fetched_through_a_facade", "check_number fetched through planning.motion, not its home",
      "so101_kinematics/hw/preflight.py", None, "from so101_kinematics.inputs import check_number",
      "from so101_kinematics.planning.motion import check_number",
      "tests/core/test_public_names.py::test_every_file_fetches_each_package_name_from_its_home"),
    m("facade_all_back", "planning.motion declares check_number (from inputs) as its own again",
      "so101_kinematics/planning/motion.py", None, '__all__ = ["Plan", ',
      '__all__ = ["check_number", "Plan", ',
      "tests/core/test_public_names.py::test_each_module_declares_only_names_it_defines"),
    m("moved_option_swallowed", "an option that moved to `so101` (pick_place_sim.py --compare) "
      "is silently accepted: the script runs without it", "so101_kinematics/cli.py", None,
      "        parser.exit(EXIT_BAD_INPUT, f", "        return None and parser.exit(2, f",
      "tests/course_files/test_moved_options.py::"
      "test_an_old_option_is_refused_in_one_line_with_its_new_spelling"),
    # --- the camera pipeline (issue 36) ----------------------------------------------------------
    m("fovy_taken_as_horizontal", "the focal length from the image's width: MuJoCo's fovy is the "
      "vertical field of view", VISION_MODEL, "intrinsics_from_fovy",
      "focal = (height / 2.0)", "focal = (width / 2.0)",
      "tests/vision/test_camera_model.py::test_intrinsics_are_the_hand_calculation_from_fovy",
      "tests/vision/test_camera_model.py::test_a_projected_point_lands_where_mujoco_draws_it"),
    m("principal_point_half_a_pixel_off", "the principal point at width / 2: OpenCV's pixel "
      "centres are whole numbers, the image's middle is (width - 1) / 2", VISION_MODEL,
      "intrinsics_from_fovy", "[focal, 0.0, (width - 1) / 2.0]", "[focal, 0.0, width / 2.0]",
      "tests/vision/test_camera_model.py::test_a_projected_point_lands_where_mujoco_draws_it"),
    m("mujoco_camera_axes_kept", "the camera's pose in MuJoCo's axes (-z forward, y up) where "
      "OpenCV's are meant: the half turn about x forgotten", VISION_MODEL,
      "get_camera_pose_base", "@ R_MUJOCO_OPENCV)", ")",
      "tests/vision/test_camera_model.py::test_a_projected_point_lands_where_mujoco_draws_it",
      "tests/vision/test_detect.py::test_a_tags_pose_at_30_cm_is_within_2_mm_and_1_deg"),
    m("flat_tag_yaw_mirrored", "a flat tag's yaw from its edge with y mirrored", VISION_DETECT,
      "flat_pose", "yaw = np.arctan2(across[1], across[0])",
      "yaw = np.arctan2(-across[1], across[0])",
      "tests/vision/test_detect.py::test_a_flat_tags_pose_from_the_overhead_camera_at_640x480"),
    m("camera_calibration_ignored", "see_and_pick.py --camera-calibration is read but the "
      "model's camera is used: a real camera's pose never reaches the detection",
      "so101_kinematics/lab/see_and_pick_arm.py", "camera_view",
      "if camera_calibration is not None:", "if False:",
      "tests/virtual/test_virtual_see_and_pick.py::"
      "test_a_camera_calibration_file_is_the_camera_the_arm_sees_by"),
    m("follow_arm_moves_on_a_lost_tag", "the follower on the arm keeps moving on an old "
      "sighting: a hidden tag's last pose, predicted on at its velocity, drives the arm",
      "so101_kinematics/lab/follow_tag_arm.py", "_Follower.__call__",
      "if tracker.age(now) > FOLLOW_POSE_AGE:", "if False:",
      "tests/virtual/test_virtual_follow_tag.py::"
      "test_a_hidden_tag_leaves_the_arm_holding_torqued_where_it_was"),
    m("follow_arm_reach_unchecked", "the follower on the arm chases a tag out of its reach "
      "(the arm folds towards a pose it cannot take) instead of holding",
      "so101_kinematics/lab/follow_tag_arm.py", "_Follower.__call__",
      "if why is not None:", "if False:",
      "tests/virtual/test_virtual_follow_tag.py::"
      "test_a_tag_out_of_reach_is_refused_and_the_arm_holds"),
    m("video_end_raises_in_its_thread", "a video file read as a camera is lerobot's camera "
      "as is: at the file's end its read thread logs 11 warnings and dies with a traceback",
      "so101_kinematics/vision/webcam.py", "Webcam.__init__",
      "(_video_file_camera(OpenCVCamera) if is_file else OpenCVCamera)(config)",
      "OpenCVCamera(config)",
      "tests/vision/test_webcam.py::test_the_end_of_the_video_is_a_stale_frame_in_one_line_and_"
      "no_thread_traceback"),
    # --- the drawing (issue 37) ---------------------------------------------------------------
    m("drawing_lead_behind", "the servo's lag led the wrong way (the plan minus tau v): the pen "
      "trails twice as far", DRAW_PLAN, "lead_commands", "led = q + tau * rate",
      "led = q - tau * rate",
      "tests/drawing/test_pen_plan.py::test_each_command_leads_the_plan_by_the_lag_times_its_"
      "velocity"),
    m("drawing_strokes_never_reversed", "the ordering never draws a stroke from its far end: "
      "the pen-up travel grows", "so101_kinematics/drawing/strokes.py", "order_strokes",
      "if to_last[i_last] < to_first[i_first]:", "if False:",
      "tests/drawing/test_strokes.py::test_ordering_shortens_the_pen_up_travel_and_may_reverse_"
      "a_stroke"),
    m("drawing_distance_to_lines", "the ink's distance to each segment's line, not the segment "
      "(no clip at its ends): ink beyond a stroke's end scores as on it", DRAW_SCORE,
      "distances_to_strokes", "t = np.clip(((p - a) * ab).sum(axis=2) / length2, 0.0, 1.0)",
      "t = ((p - a) * ab).sum(axis=2) / length2",
      "tests/drawing/test_ink_score.py::test_the_distance_to_a_polyline_by_hand"),
    m("drawing_page_box_not_turned", "the page's box laid with its width along the base's x: "
      "strokes near the page's sides draw in the air", "so101_kinematics/drawing/ink.py",
      "build_drawing_model", "half = [page.size[1] / 2000.0, page.size[0] / 2000.0,",
      "half = [page.size[0] / 2000.0, page.size[1] / 2000.0,",
      "tests/drawing/test_ink.py::test_the_models_page_is_the_page_turned_as_it_lies"),
    m("light_brightness_constant", "the light at full brightness whatever its speed: the "
      "exposure piles up where the arm slows", "so101_kinematics/drawing/light_paint.py",
      "measured_brightness", "np.clip(before / speed, 0.0, HEADROOM)", "np.ones_like(before)",
      "tests/drawing/test_light_paint.py::test_the_brightness_follows_the_read_back_speed_one_"
      "period_late",
      "tests/drawing/test_light_paint.py::test_a_120_mm_star_within_2_mm_and_even_within_20_"
      "percent"),
    # --- the throw (issue 38) -----------------------------------------------------------------
    m("throwing_no_drag_in_simulator", "the simulator's ball flies without the model's drag: "
      "the comparison of model and landing is no longer like for like",
      "so101_kinematics/throwing/throw_scene.py", "Flight.step",
      "d.xfrc_applied[self.body, :3] = self.ball.drag_force(self.ball_state()[1])",
      "d.xfrc_applied[self.body, :3] = 0.0",
      "tests/throwing/test_throw_scene.py::test_the_simulated_flight_has_the_models_drag"),
    m("throwing_opening_delay_ignored", "the gripper told to open at the timed release, not its "
      "opening delay before: the ball leaves 0.15 s late and misses",
      "so101_kinematics/throwing/throw_run.py", "throw_at",
      "run = ThrowRun(m, ball, tuned, open_at=release_at - delay, cup=cup)",
      "run = ThrowRun(m, ball, tuned, open_at=release_at, cup=cup)",
      "tests/throwing/test_throw_run.py::test_a_throw_lands_in_the_cup_where_the_model_says"),
    m("throwing_linear_drag", "the drag linear in the speed, not quadratic: the model's flight "
      "is wrong at every speed but one", "so101_kinematics/throwing/ball.py", "_acceleration",
      "a = -k * speed * v", "a = -k * v",
      "tests/throwing/test_ball.py::test_a_ball_at_its_terminal_speed_keeps_it"),
    m("cup_camera_mat_turn_ignored", "the cup's axis taken OFFSET along the base's +x from its "
      "mat's tag, the tag's yaw ignored: right only for a mat square with the table",
      "so101_kinematics/throwing/cup_camera.py", "find_cup",
      "axis = g_bt[:3, 3] + CUP_TAG_OFFSET * g_bt[:3, 1]",
      "axis = g_bt[:3, 3] + CUP_TAG_OFFSET * np.array([1.0, 0.0, 0.0])",
      "tests/throwing/test_cup_camera.py::test_the_mats_turn_is_read_from_its_tag"),
    m("drawing_arm_tip_pen_up_too", "the read-back tip scored on every cycle, the pen-up travel "
      "between letters too", "so101_kinematics/lab/draw_arm.py", "draw_on_arm",
      "            and path.down[int(c.step[len(SAMPLE):])]]",
      "            and True]",
      "tests/virtual/test_virtual_drawing.py"),
    m("registration_turn_reversed", "the page's fitted turn of the wrong sign (the cross term "
      "swapped)", FRAMES, "rigid_fit_2d",
      "(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])", "(a[:, 1] * b[:, 0] - a[:, 0] * b[:, 1])",
      "tests/drawing/test_registration.py::test_exact_touches_give_the_page_back"),
    m("registration_no_order_hint", "a fit of points touched in the wrong order called a "
      "moved page", "so101_kinematics/drawing/registration.py", "check_fit",
      "        if other.rms_mm <= max_rms_mm:", "        if False:",
      "tests/drawing/test_registration.py::test_touches_in_the_wrong_order_are_refused_with_"
      "the_order_that_fits"),
    m("light_switch_not_led", "the torch pressed when the light is wanted, not the jaw's lag "
      "before", "so101_kinematics/drawing/light_switch.py", "gripper_goals",
      "press, release = round(switch.lead_on_s / dt), round(switch.lead_off_s / dt)",
      "press, release = 0, 0",
      "tests/drawing/test_light_switch.py::test_the_press_starts_its_lead_before_the_light_and_"
      "the_release_its_own", "tests/lab/test_light_arm.py"),
    m("see_and_pick_abort_unexpected", "see_and_pick --port lets the fault policy's abort "
      "through: a stop signal ends as an unexpected error without the arm's last line",
      "so101_kinematics/lab/see_and_pick_arm.py", "see_and_pick_on_arm",
      "    except MotionAborted as error:", "    except ZeroDivisionError as error:",
      "tests/virtual/test_virtual_see_and_pick.py::test_an_aborted_run_ends_with_the_arms_last_"
      "line_not_an_unexpected_error"),
    # --- the throw on an arm (issue 38) ------------------------------------------------------
    m("throw_arm_registers_kept_on_abort", "the register raised for the swing put back only "
      "when the swing completes: a bus fault or a stop signal leaves Acceleration 0 (no ramp)",
      "so101_kinematics/lab/throw_arm.py", "_swing",
      "        finally:  # every ending of the swing: a fault, a stop signal, done\n",
      "        except ZeroDivisionError:\n            pass\n        if True:\n",
      "tests/lab/test_throw_arm.py::test_a_bus_outage_mid_swing_puts_the_raised_register_back_"
      "and_ends_once"),
    m("throw_arm_release_at_first_motion", "the release read back when the jaw first moves "
      "(1 deg) instead of when it has opened enough for the ball (10 deg): 0.1 s early",
      "so101_kinematics/lab/throw_arm.py", "_read_back",
      "point, velocity = measured_release(m, samples, free)",
      "point, velocity = measured_release(m, samples, moved)",
      "tests/lab/test_throw_arm.py::test_a_throw_at_a_cup_0_4_m_away_lands_in_it_from_the_"
      "release_read_back"),
    m("throw_windup_into_the_table", "the swing's 70 deg of the first throw: its wind-up "
      "puts the moving jaw 54 mm below the table top", "so101_kinematics/throwing/throw_plan.py",
      None, "SWING_DEG = 50.0", "SWING_DEG = 70.0",
      "tests/throwing/test_throw_plan.py::test_the_whole_swing_stays_above_the_table"),
    # --- two arms on one board (issue 38) ---------------------------------------------------
    m("two_arms_one_feedforward", "one gravity feed-forward for both arms of a model: its "
      "direction memory mixes them, an arm moves the other", "so101_kinematics/sim/actuation.py",
      "_offset", "feedforward = entry[4][k]\n", "feedforward = entry[4][0]\n",
      "tests/two_arms/test_scene_arm.py::test_moving_one_arm_leaves_the_other_still"),
    m("chess_registered_yaw_reversed", "the base's fitted turn of the wrong sign: the board "
      "registered by touch puts every square 2 deg off (9 mm at 0.26 m)",
      "so101_kinematics/two_arms/board_registration.py", "registered_base",
      "-math.degrees(angle), side)", "math.degrees(angle), side)",
      "tests/two_arms/test_chess.py::test_a_fit_of_exact_touches_gives_the_displaced_base_back"),
    m("tictactoe_registration_unused", "tic-tac-toe registers the board by touch, then plans "
      "with the nominal bases anyway: the bases' 3 mm and 1 deg put pieces 10 mm off",
      "so101_kinematics/two_arms/two_arm_game.py", "run_game",
      "return _play(m, d, scratch, arms, planned,", "return _play(m, d, scratch, arms, bases,",
      "tests/two_arms/test_two_arm_game.py::test_the_game_registered_by_touch_recovers_the_"
      "bases_3_mm_and_1_deg_off"),
    m("two_arms_board_shared", "the shared-workspace rule never asks where the other arm is: "
      "both arms may reach into the board at once", "so101_kinematics/two_arms/shared_workspace.py",
      "check_shared_path", "and in_zone(scratch.site_xpos[other.tool_site], zone)):",
      "and True):",
      "tests/two_arms/test_shared_workspace.py::test_a_path_into_the_board_while_the_other_arm_"
      "is_there_is_refused",
      "tests/two_arms/test_shared_workspace.py::test_a_path_with_the_other_arm_parked_passes_and_"
      "says_how_close"),
    m("two_arms_arm_sensor_frame", "each virtual arm's cube sensor read as if in the world: its "
      "pieces picked and judged in the wrong frame", "so101_kinematics/lab/two_arms_arm.py",
      "_pieces_seen", "(world_from_base(base, cube.position_m),", "(cube.position_m,",
      "tests/virtual/test_virtual_two_arms.py::test_the_whole_game_on_two_virtual_arms_through_"
      "lerobots_bus"),
]


# --- applying a mutant -------------------------------------------------------------------
def _function_span(tree: ast.Module, qualname: str) -> tuple[int, int]:
    """(first, last) line [1-based] of the function or method ``qualname`` in ``tree``."""
    parts = qualname.split(".")
    body = tree.body
    node = None
    for part in parts:
        node = next((n for n in body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                       ast.ClassDef)) and n.name == part), None)
        if node is None:
            raise LookupError(f"no {qualname}")
        body = node.body
    first = min([node.lineno] + [d.lineno for d in node.decorator_list])
    return first, node.end_lineno


def apply_edit(root: Path, edit: Edit) -> None:
    """Apply ``edit`` under ``root``; LookupError when its code is not found exactly once."""
    path = root / edit.path
    text = path.read_text()
    start, end = 0, len(text)
    if edit.function is not None:
        first, last = _function_span(ast.parse(text), edit.function)
        lines = text.splitlines(keepends=True)
        start = sum(len(line) for line in lines[:first - 1])
        end = start + sum(len(line) for line in lines[first - 1:last])
    count = text.count(edit.old, start, end)
    if count != 1:
        where = edit.function or "the module"
        raise LookupError(f"{edit.path}: {edit.old!r} found {count} times in {where}")
    at = text.index(edit.old, start, end)
    path.write_text(text[:at] + edit.new + text[at + len(edit.old):])


@dataclass
class Outcome:
    """What happened to one mutant."""

    name: str
    status: str  # caught, survived, stale, timeout, error
    seconds: float
    tests: list[str] = field(default_factory=list)
    detail: str = ""


def run_tests(root: Path, tests: tuple[str, ...], timeout: float) -> tuple[int | None, str]:
    """Run pytest on ``tests`` in ``root``; (return code or None on timeout, last output line)."""
    env = dict(os.environ, PYTHONPATH=str(root), PYTHONDONTWRITEBYTECODE="1",
               MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    command = [sys.executable, "-m", "pytest", "-q", "-x", "-rfE", "-p", "no:cacheprovider",
               "-o", "addopts=", *tests]
    try:
        done = subprocess.run(command, cwd=root, env=env, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, f"timed out after {timeout:g} s"
    lines = [line for line in done.stdout.splitlines() if line.strip()]
    failed = [line for line in lines if line.startswith(("FAILED tests", "ERROR tests"))]
    last = lines[-1] if lines else done.stderr.strip()[-200:]
    return done.returncode, "; ".join([last] + failed[:1])


def check_mutant(root: Path, mutant: Mutant, timeout: float) -> Outcome:
    """Apply ``mutant`` to the copy at ``root``, run its tests, restore the copy."""
    originals = {edit.path: (root / edit.path).read_text() for edit in mutant.edits}
    t0 = time.perf_counter()
    try:
        try:
            for edit in mutant.edits:
                apply_edit(root, edit)
        except (LookupError, SyntaxError) as error:
            return Outcome(mutant.name, "stale", 0.0, list(mutant.tests), str(error))
        code, last = run_tests(root, mutant.tests, timeout)
    finally:
        for path, text in originals.items():
            (root / path).write_text(text)
    seconds = time.perf_counter() - t0
    if code is None:
        status = "timeout"
    elif code in (1, 2):  # tests failed (or could not be collected: the mutant broke imports)
        status = "caught"
    elif code == 0:
        status = "survived"
    else:
        status = "error"  # usage error, no tests collected: fix the test ids
    return Outcome(mutant.name, status, seconds, list(mutant.tests), last)


def main(argv: list[str] | None = None) -> int:
    """Copy the repository, check the baseline, then each selected mutant; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", dest="select", default="",
                        help="only mutants whose name contains this text")
    parser.add_argument("--json", type=Path, help="also write the outcomes to this JSON file")
    parser.add_argument("--list", action="store_true", help="list the mutants and exit")
    parser.add_argument("--timeout", type=float, default=TIMEOUT_S,
                        help=f"per mutant [s] (default {TIMEOUT_S:g})")
    parser.add_argument("--no-baseline", action="store_true",
                        help="skip running the unmutated tests first")
    args = parser.parse_args(argv)
    chosen = [mu for mu in MUTANTS if args.select in mu.name]
    if args.list or not chosen:
        for mu in MUTANTS:
            print(f"{mu.name:28s} {mu.why}")
        return 0 if args.list else 2
    if args.json is not None and not args.json.parent.is_dir():
        parser.error(f"--json {args.json}: folder {args.json.parent} does not exist")

    with tempfile.TemporaryDirectory(prefix="so101-mutation-") as tmp:
        root = Path(tmp) / "repo"
        shutil.copytree(REPO, root, ignore=IGNORE, symlinks=True)
        # model/assets (the meshes) are ignored by git and materialised on demand: share them.
        if (REPO / "model" / "assets").exists() and not (root / "model" / "assets").exists():
            (root / "model" / "assets").symlink_to(REPO / "model" / "assets")
        if not args.no_baseline:
            tests = tuple(dict.fromkeys(t for mu in chosen for t in mu.tests))
            code, last = run_tests(root, tests, args.timeout * 2)
            print(f"baseline (no mutant): {last}", flush=True)
            if code != 0:
                print("The unmutated tests do not pass: fix them first.", file=sys.stderr)
                return 1
        outcomes = []
        for mutant in chosen:
            outcome = check_mutant(root, mutant, args.timeout)
            outcomes.append(outcome)
            print(f"{outcome.status:9s} {outcome.seconds:6.1f} s  {mutant.name:28s} "
                  f"{outcome.detail}", flush=True)

    caught = sum(o.status in ("caught", "timeout") for o in outcomes)
    print("\n| planted bug | status | tests |\n|---|---|---|")
    for mutant, outcome in zip(chosen, outcomes, strict=True):
        print(f"| {mutant.name}: {mutant.why} | {outcome.status} | "
              f"{', '.join(t.removeprefix('tests/') for t in mutant.tests)} |")
    print(f"\nscore: {caught}/{len(outcomes)} planted bugs caught")
    if args.json is not None:
        args.json.write_text(json.dumps({"caught": caught, "total": len(outcomes),
                                         "mutants": [asdict(o) for o in outcomes]}, indent=2))
    return 0 if caught == len(outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
