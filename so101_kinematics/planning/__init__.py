"""Motion and planning, shared by every backend (no MuJoCo, no lerobot).

The time scalings (``profiles``) and the one runner (``motion.run_plan``); the plans
(``plans``, ``cartesian_plan``, ``straight_line``, ``stacking`` and its report
``stack_report``); the figures of a trajectory (``trajectory_log``, ``motion_metrics``).
"""

__all__: list[str] = []
