"""The course's tracking log (week 8): a DataFrame of target and actual joints, and its plot.

Both backends' ``move_to_pose_with_logging`` build the course's DataFrame here
(``time`` [s] from the move's start, ``target_<joint>``, ``actual_<joint>``: [deg],
gripper [0, 100]) and ``plot_data(df)`` draws it as the course's page does: one panel
per joint, target solid, actual dashed, the joint's limits as the panel's range.
pandas is optional: the hardware extra brings it (through lerobot); without it the
helpers say so in one line before anything moves.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from so101_kinematics.frames import GRIPPER_RANGE, JOINT_RANGES_RAD, JOINTS

__all__ = ["logging_frame", "plot_data", "require_pandas"]


def require_pandas(what: str = "move_to_pose_with_logging"):
    """The pandas module, or an ImportError in one line naming the extra.

    Args:
        what: the helper that needs it, for the message.
    """
    try:
        import pandas
    except ImportError:
        raise ImportError(f"{what} returns a pandas DataFrame, and pandas is not installed. "
                          "Fix: pip install -e '.[hw]' (lerobot brings pandas) or pip install "
                          "pandas.") from None
    return pandas


def logging_frame(times: Sequence[float], targets: Sequence[Mapping[str, float]],
                  actuals: Sequence[Mapping[str, float] | None]):
    """The course's DataFrame from a move's samples.

    Args:
        times: [s] of each sample, from the move's start.
        targets: the commanded configuration at each sample ([deg], gripper [0, 100]).
        actuals: the measured one (None when the arm was not read: a row of NaN).
    """
    pd = require_pandas()
    nan = dict.fromkeys(JOINTS, math.nan)
    return pd.DataFrame({
        "time": list(times),
        **{f"target_{j}": [t.get(j, math.nan) for t in targets] for j in JOINTS},
        **{f"actual_{j}": [(a or nan).get(j, math.nan) for a in actuals] for j in JOINTS},
    })


def plot_limits() -> dict[str, tuple[float, float]]:
    """Each joint's range as the course's plot draws it: [deg], the gripper (0, 100)."""
    return {j: GRIPPER_RANGE if j == "gripper" else
            (math.degrees(JOINT_RANGES_RAD[j][0]), math.degrees(JOINT_RANGES_RAD[j][1]))
            for j in JOINTS}


def plot_data(df, path=None):
    """The course's plot: target vs actual per joint, within the joint's limits.

    The figure is left to the caller, as matplotlib's own functions leave it:
    ``plot_data(df)`` then ``plt.savefig("run.png")`` saves this plot (it is the
    current figure). With a display (an interactive backend) it is shown first,
    as the course's ``plot_data(df)`` does; without one nothing is shown.

    Args:
        df: from ``move_to_pose_with_logging`` (or several, ``pd.concat``-ed).
        path: also save the figure there (any format matplotlib writes); not shown then.

    Returns:
        The matplotlib figure (``plt.close(fig)`` when done with it).
    """
    import matplotlib
    import matplotlib.pyplot as plt

    limits = plot_limits()
    fig, axes = plt.subplots(len(JOINTS), 1, figsize=(10, 2 * len(JOINTS)), sharex=True)
    for ax, joint in zip(axes, JOINTS, strict=True):
        ax.plot(df["time"], df[f"target_{joint}"], label=f"Target {joint}")
        ax.plot(df["time"], df[f"actual_{joint}"], label=f"Actual {joint}", linestyle="--")
        ax.set_ylabel("[%]" if joint == "gripper" else "[deg]")
        ax.set_ylim(*limits[joint])
        ax.legend(loc="upper right")
    axes[-1].set_xlabel("Time (s)")
    fig.suptitle("Target vs Actual Joint Positions")
    fig.tight_layout(rect=[0, 0.03, 1, 0.95])
    if path is not None:
        fig.savefig(path, dpi=100)
    elif matplotlib.get_backend().lower() not in NON_INTERACTIVE_BACKENDS:
        plt.show()  # a window closed by the user: pyplot forgets the figure, as always
    return fig


NON_INTERACTIVE_BACKENDS = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template", "inline",
                            "module://matplotlib_inline.backend_inline"}
"""Backends where ``plot_data`` does not call ``plt.show()``: matplotlib's own without a window
(``matplotlib.backends.BackendFilter.NON_INTERACTIVE``: showing there only warns) and
Jupyter's inline backend (it shows the figure at the cell's end; showing earlier would close
it before the caller's ``plt.savefig``)."""
