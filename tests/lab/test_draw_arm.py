"""draw.py --port: the drawing's plan through lerobot's bus on the virtual arm."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("lerobot")
pytestmark = pytest.mark.hw

import draw  # noqa: E402
from so101_kinematics.drawing.draw_run import drawing_strokes, ready_strokes  # noqa: E402
from so101_kinematics.drawing.page import PAGES, Page  # noqa: E402
from so101_kinematics.drawing.pen import PenPose  # noqa: E402
from so101_kinematics.drawing.pen_plan import DEFAULT_SPEED_MM_S, plan_drawing  # noqa: E402
from so101_kinematics.lab.draw_arm import drawing_plan  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402


def test_the_plan_is_one_step_per_control_cycle_after_the_approach():
    page = Page("a5", PAGES["a5"])
    prepared, _ = ready_strokes(drawing_strokes(10.0, page, shape="square"), page, PenPose())
    path = plan_drawing(page, prepared, PenPose(), DEFAULT_SPEED_MM_S, 0.01)
    plan = drawing_plan(path)
    assert len(plan.steps) == 1 + len(path.commands)
    assert {s.duration for s in plan.steps[1:]} == {0.01} and plan.steps[0].name == "approach"


@pytest.mark.slow
def test_a_square_drawn_on_the_virtual_arm_follows_its_strokes(tmp_path, capsys):
    report = tmp_path / "arm.json"
    with VirtualSO101() as arm:
        code = draw.main(["--shape", "square", "--height-mm", "20", "--port", arm.port,
                          "--no-pen", "--json", str(report)])
    assert code == 0, capsys.readouterr().err
    tip = json.loads(report.read_text())["arm_tip"]
    # the servos' read-back, quantised to 0.088 deg (0.3 mm at the page): as the simulator's
    # ink, within the 1.5 mm mean and 3 mm worst
    assert tip["mean_mm"] <= 1.5 and tip["worst_mm"] <= 3.0 and tip["cycles"] > 500
