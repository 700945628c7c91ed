"""How a stack stands: each block's offset, height and tilt, the lean, the verdict.

One judgement for the simulator (``so101_kinematics.sim.stack``, from the
cubes' poses) and the hardware script (:func:`stack_outcome`, from the virtual
arm's cube sensor), against the plan's targets (``so101_kinematics.planning.stacking``).
"""

from __future__ import annotations

import math

import numpy as np

from so101_kinematics.planning.stacking import CLEARANCE, StackPlan

__all__ = ["STACK_TILT_TOLERANCE", "STACK_TOLERANCE", "measure_stack", "stack_outcome"]

STACK_TOLERANCE = 0.005
"""[m] each block's centre this close to the one below it horizontally (the bottom one: to the
stack's (x, y)) and to its level's height: a stack (the issue's 5 mm)."""

STACK_TILT_TOLERANCE = 10.0
"""[deg] each block's nearest face normal this close to the vertical: upright."""


def measure_stack(positions, tilts_deg, stack: StackPlan) -> dict:
    """How blocks at ``positions`` stand against the plan: offsets, lean, success.

    Args:
        positions: each block's centre (x, y, z) [m], bottom block first.
        tilts_deg: each block's tilt from upright [deg].
        stack: the plan's blocks (their targets) and base height.

    Returns:
        ``blocks_final_position_m``, ``blocks_target_position_m``, ``blocks_tilt_deg``,
        ``blocks_offset_m`` (horizontal: the bottom block from the stack's spot, each
        other block from the one below it), ``lean_deg`` (the line from the bottom
        block's centre to the top one's, from the vertical), ``base_height_m`` and
        ``success`` (every offset and height within ``STACK_TOLERANCE``, every tilt
        within ``STACK_TILT_TOLERANCE``).
    """
    finals = [np.asarray(p, dtype=float) for p in positions]
    targets = [np.asarray(b.target, dtype=float) for b in stack.blocks]
    offsets = [float(np.linalg.norm(finals[0][:2] - targets[0][:2]))]
    offsets += [float(np.linalg.norm(finals[i][:2] - finals[i - 1][:2]))
                for i in range(1, len(finals))]
    rise = finals[-1] - finals[0]
    lean = math.degrees(math.atan2(float(np.linalg.norm(rise[:2])), float(rise[2]))) \
        if len(finals) > 1 else 0.0
    heights = all(abs(f[2] - t[2]) <= STACK_TOLERANCE for f, t in zip(finals, targets,
                                                                     strict=True))
    success = (len(finals) == len(targets) and heights
               and all(o <= STACK_TOLERANCE for o in offsets)
               and all(t <= STACK_TILT_TOLERANCE for t in tilts_deg))
    return dict(blocks_final_position_m=[[float(v) for v in f] for f in finals],
                blocks_target_position_m=[[float(v) for v in t] for t in targets],
                blocks_tilt_deg=[float(t) for t in tilts_deg], blocks_offset_m=offsets,
                lean_deg=lean, base_height_m=stack.base_height, success=success)


def stack_outcome(stack: StackPlan, cubes) -> str | None:
    """What the virtual lab's cube sensor says of the stack (None on a real arm: no readings).

    Args:
        stack: the plan that ran.
        cubes: ``so101_kinematics.sensors.cube_wire.CubeReading`` of every cube, any order;
            the lowest ``len(stack.blocks)`` of those near the stack are its blocks.

    Returns:
        Lines for the student: each block bottom first, the lean and the verdict.
    """
    if not cubes:
        return None
    x, y = stack.blocks[0].target[:2]
    near = sorted((c for c in cubes if math.dist(c.position_m[:2], (x, y)) <= CLEARANCE / 2),
                  key=lambda c: c.position_m[2])[:len(stack.blocks)]
    if len(near) < len(stack.blocks):
        return (f"Stack (the virtual arm's sensor): {len(near)} of {len(stack.blocks)} blocks at "
                f"({100 * x:.1f}, {100 * y:.1f}) cm: FAILED.")
    found = measure_stack([c.position_m for c in near], [c.tilt_deg for c in near], stack)
    lines = [f"Block {i + 1} (the virtual arm's sensor): x = {100 * p[0]:.1f} cm, "
             f"y = {100 * p[1]:.1f} cm, z = {100 * p[2]:.1f} cm (target {100 * t[2]:.1f} cm), "
             f"{1e3 * o:.1f} mm off, tilted {tilt:.1f} deg"
             for i, (p, t, o, tilt) in enumerate(zip(
                 found["blocks_final_position_m"], found["blocks_target_position_m"],
                 found["blocks_offset_m"], found["blocks_tilt_deg"], strict=True))]
    lines.append(f"Stack lean {found['lean_deg']:.1f} deg: "
                 + ("stacked." if found["success"] else "FAILED (a block is off or tilted)."))
    return "\n".join(lines)
