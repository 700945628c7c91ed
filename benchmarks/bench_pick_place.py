"""Benchmark group "pick_place": headless speed of the simulated pick-and-place and video recording.

Figures (medians over repeats, with spread):
  - sim_realtime_factor: simulated seconds per wall second of the whole
    default plan with the free cube, headless, on the default servo (the STS3215 model
    with the gravity feed-forward) (goal >= 100);
  - sim_realtime_factor_ideal_servo: reference, the same run with --servo ideal (the
    upstream position actuator: no Python per physics step), and servo_model_cost, the
    ratio of the two;
  - pick_place_us_per_step: the same as wall time per physics step (the
    model's timestep, 4 ms);
  - sim_realtime_factor_half_step: reference, the same run with a 2 ms step
    (MuJoCo's default, which the model's 4 ms matches: tests/course_files/test_pick_place_sim.py);
  - mujoco_arm_step_us: reference measured in the same run, one mj_step of the
    arm alone at rest (no cube, no contacts), and pick_place_step_vs_arm_step,
    the ratio (load on a shared machine slows both alike);
  - record_wall_over_video_duration: wall time to record the full 640x480 30 fps video
    divided by the video's duration (goal <= 1: recording keeps up with real time);
  - record_fps: frames rendered and encoded per wall second while recording;
  - record_cpu_ms_per_frame: CPU time (this process, its render threads and
    the encoder) per frame, which does not depend on what else runs;
  - render_fps_<quality>: frames per second of FrameRenderer alone, per preset.
"""

from __future__ import annotations

import resource
import tempfile
import time
from pathlib import Path


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def bench_pick_place(quick: bool) -> dict:
    """Run the group; ``quick`` uses fewer repeats."""
    import mujoco

    from benchmarks.common import summarize
    from pick_place_sim import CubeStart, build_model, run_pick_place
    from so101_kinematics.planning.plans import FINAL_CONFIGURATION, STARTING_CONFIGURATION
    from so101_kinematics.sim.render import QUALITY, FrameRenderer, target_cubes

    out: dict = {}
    run_pick_place()  # warm-up: compile caches, meshes
    timestep = build_model(physics_only=True).opt.timestep  # [s]
    factors, per_step, half_step, ideal = [], [], [], []
    for _ in range(3 if quick else 7):
        report = run_pick_place()
        factors.append(report.realtime_factor)
        ideal.append(run_pick_place(servo={"mode": "ideal"}).realtime_factor)
        per_step.append(report.wall_time_s / round(report.sim_time_s / timestep) * 1e6)
        half_step.append(run_pick_place(timestep=timestep / 2).realtime_factor)
    out["sim_realtime_factor"] = summarize(factors)
    out["pick_place_us_per_step"] = summarize(per_step)
    out["sim_realtime_factor_half_step"] = summarize(half_step)
    out["sim_realtime_factor_ideal_servo"] = summarize(ideal)
    out["servo_model_cost"] = (out["sim_realtime_factor_ideal_servo"]["median"]
                               / out["sim_realtime_factor"]["median"])
    arm = build_model(render_meshes=True)
    d = mujoco.MjData(arm)
    mujoco.mj_resetDataKeyframe(arm, d, arm.key("home").id)
    reference = []
    for _ in range(3 if quick else 7):
        start = time.perf_counter()
        for _ in range(2000):
            mujoco.mj_step(arm, d)
        reference.append((time.perf_counter() - start) / 2000 * 1e6)
    out["mujoco_arm_step_us"] = summarize(reference)
    out["pick_place_step_vs_arm_step"] = (out["pick_place_us_per_step"]["median"]
                                          / out["mujoco_arm_step_us"]["median"])

    ratios, cpu_per_frame, fps = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(1 if quick else 3):
            cpu0, child0 = time.process_time(), _children_cpu()
            report = run_pick_place(mode="record", video=Path(tmp) / "v.mp4", progress=False)
            cpu = time.process_time() - cpu0 + _children_cpu() - child0
            ratios.append(report.wall_time_s / (report.frames_written / 30.0))
            fps.append(report.frames_written / report.wall_time_s)
            cpu_per_frame.append(cpu / report.frames_written * 1e3)
    out["record_wall_over_video_duration"] = summarize(ratios)
    out["record_fps"] = summarize(fps)
    out["record_cpu_ms_per_frame"] = summarize(cpu_per_frame)

    frames = {"fast": 30, "shadows": 15, "high": 5} if quick else {"fast": 90, "shadows": 30,
                                                                   "high": 10}
    for name, count in frames.items():
        m = build_model(cube=CubeStart(), render_meshes=QUALITY[name].light_meshes)
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        mujoco.mj_forward(m, d)
        renderer = FrameRenderer(m, d, overlays=target_cubes(STARTING_CONFIGURATION,
                                                             FINAL_CONFIGURATION),
                                 quality=QUALITY[name])
        renderer.render()
        start = time.perf_counter()
        for i in range(count):
            d.qpos[m.joint("shoulder_pan").qposadr[0]] = -0.8 + 1.6 * i / count
            renderer.render()
        out[f"render_fps_{name}"] = count / (time.perf_counter() - start)
        renderer.close()
    return out
