"""The hardware run's CSV log and plot."""

from __future__ import annotations

from pathlib import Path

import pytest
from hw_fakes import HOME, FakeBus, FakeClock, make_session  # noqa: F401

import so101_kinematics.hw.log as hwlog
from so101_forward_kinematics import JOINTS

REPO = Path(__file__).resolve().parents[2]
VIRTUAL_CALIBRATION = REPO / "calibration" / "virtual_so101.json"


def test_log_csv_has_time_command_and_measurement_per_cycle(calibration, clock, tmp_path):
    session, bus = make_session(calibration, clock)
    session.move(dict(HOME, wrist_flex=40.0), 0.3)
    path = hwlog.write_log_csv(session.cycles, tmp_path / "run.csv")
    rows = path.read_text().splitlines()
    header = rows[0].split(",")
    assert header[:3] == ["t_s", "wall_s", "step"]
    assert header[3:] == ([f"cmd_{j}" for j in JOINTS] + [f"meas_{j}" for j in JOINTS]
                          + [f"trim_{j}" for j in JOINTS] + [f"lead_{j}" for j in JOINTS])
    assert len(rows) == 1 + len(session.cycles)
    last = dict(zip(header, rows[-1].split(","), strict=True))
    assert float(last["cmd_wrist_flex"]) == pytest.approx(40.0)
    assert float(last["meas_wrist_flex"]) == pytest.approx(40.0)
    assert all(float(last[f"trim_{j}"]) == 0.0 for j in JOINTS)  # no trims: zeros, said
    assert all(last[f"lead_{j}"] == "" for j in JOINTS)  # no velocity lead: the plan sent


def test_a_trimmed_run_logs_model_angles_and_its_trims(calibration, clock, tmp_path):
    """The servo gets command + trim; the log keeps the model's angles and says the trims."""
    trims = {"shoulder_lift": 2.0, "elbow_flex": -4.0}
    log = hwlog.CycleLog(tmp_path / "run.csv")
    session, bus = make_session(calibration, clock, on_cycle=log, trims=trims)
    session.move(dict(HOME, wrist_flex=40.0), 0.3)
    log.close()
    assert bus.goals[-1]["shoulder_lift"] == pytest.approx(HOME["shoulder_lift"] + 2.0)
    assert bus.goals[-1]["elbow_flex"] == pytest.approx(HOME["elbow_flex"] - 4.0)
    assert bus.pose["elbow_flex"] == pytest.approx(HOME["elbow_flex"] - 4.0)  # the servo's own
    rows = (tmp_path / "run.csv").read_text().splitlines()
    last = dict(zip(rows[0].split(","), rows[-1].split(","), strict=True))
    assert float(last["cmd_elbow_flex"]) == pytest.approx(HOME["elbow_flex"])
    assert float(last["meas_elbow_flex"]) == pytest.approx(HOME["elbow_flex"])
    assert (float(last["trim_shoulder_lift"]), float(last["trim_elbow_flex"])) == (2.0, -4.0)
    assert float(last["trim_wrist_flex"]) == 0.0


def test_plot_is_written(calibration, clock, tmp_path):
    session, _ = make_session(calibration, clock)
    session.move(dict(HOME, wrist_flex=40.0), 0.3)
    path = hwlog.plot_log(session.cycles, tmp_path / "run.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_the_log_reaches_the_disk_as_the_run_goes(calibration, clock, tmp_path):
    """Rows are flushed at least every 0.5 s of run time to a file beside the target."""
    target = tmp_path / "run.csv"
    log = hwlog.CycleLog(target)
    session, _ = make_session(calibration, clock, on_cycle=log)
    on_disk = []
    session.on_cycle = lambda s, c: (log(s, c), on_disk.append(
        (c.wall_s, len(log.temporary.read_text().splitlines()) - 1)))
    session.move(dict(HOME, wrist_flex=40.0), 2.0)
    assert not target.exists() and log.temporary.parent == tmp_path
    for wall, rows in on_disk:  # what a SIGKILL at that cycle would leave
        assert wall - on_disk[rows - 1][0] <= 0.5 + 1e-6 if rows else wall <= 0.5 + 1e-6
    assert log.close() == target and not log.temporary.exists()
    assert len(target.read_text().splitlines()) == 1 + len(session.cycles)


def test_a_refused_run_leaves_an_existing_log_untouched(tmp_path):
    target = tmp_path / "run.csv"
    target.write_text("yesterday's run\n")
    log = hwlog.CycleLog(target)
    log.discard()
    assert target.read_text() == "yesterday's run\n"
    assert list(tmp_path.iterdir()) == [target]


def test_outputs_get_the_permissions_of_an_ordinary_file(tmp_path):
    """Written through a temporary file, a log is still readable by others (umask 022: 0644)."""
    import os
    import stat

    old = os.umask(0o022)
    try:
        path = hwlog.write_log_csv([], tmp_path / "run.csv")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
