"""How a hardware run ended, read from its log: ran its plan to the end, or aborted.

``so101 compare`` marks an aborted run and keeps it apart from the complete ones: its
figures end at the stop and do not measure the profile as a whole run does, so its
spread against a complete run is not the run-to-run variation.

What the log records (``hw/log.py``, ``hw/control.py``, ``hw/run.py``):

- the sidecar's ``aborted``: the reason ``pick_place_hw.py`` gave (``RunResult.aborted``),
  null for a complete run (logs written since issue 33);
- a ``stop`` cycle: the controlled stop (``ArmSession.stop_here``), then the slow
  return's cycles, step ``abort_return`` (``ArmSession.return_slowly``);
- the last step: a complete run ends in the plan's ``return_to_start`` (or its last
  step with ``return_to_start: false``); a log ending in another step was cut short
  (the USB lost, a kill: no stop cycle was written).
"""

from __future__ import annotations

__all__ = ["run_ending", "stop_index"]

STOP_STEP = "stop"  # ArmSession.stop_here's cycle (hw/control.py)
RETURN_STEP = "abort_return"  # ArmSession.return_slowly's moves (hw/control.py)
FINAL_RETURN_STEP = "return_to_start"  # planning.motion.run_plan's last step


def final_step(plan: object) -> str | None:
    """The step a complete run of the sidecar's ``plan`` record ends in (None: unknown)."""
    if not isinstance(plan, dict) or not isinstance(plan.get("steps"), list) or \
            not plan["steps"]:
        return None
    if plan.get("return_to_start", True):
        return FINAL_RETURN_STEP
    last = plan["steps"][-1]
    return last.get("name") if isinstance(last, dict) else None


def run_ending(steps: list[str], t_s: list[float], info: dict) -> str | None:
    """None when the log's run ran its plan to the end; else how it ended, in words.

    Args:
        steps: each logged cycle's step, in order.
        t_s: [s] each cycle's time (the same length).
        info: the sidecar (``{}`` when missing).
    """
    recorded = info.get("aborted", "")
    if recorded is None:
        return None  # the script said: complete
    stops = [k for k, step in enumerate(steps) if step == STOP_STEP]
    if isinstance(recorded, str) and recorded:
        reason = recorded
    elif stops:
        before = next((s for s in reversed(steps[:stops[0]]) if s != STOP_STEP), "")
        reason = f"stopped at t = {t_s[stops[0]]:.2f} s" + (f" during '{before}'" if before
                                                            else "")
    else:
        final = final_step(info.get("plan"))
        if final is None or not steps or steps[-1] == final:
            return None
        return (f"the log ends during '{steps[-1]}', before the plan's last step "
                f"'{final}' (cut short: the USB lost, or the script killed)")
    return reason + (", then the slow return" if RETURN_STEP in steps else "")


def stop_index(steps: list[str]) -> int | None:
    """The first cycle of the stop (the figures of an aborted run end before it), or None."""
    return steps.index(STOP_STEP) if STOP_STEP in steps else None
