"""light_paint.py --port: the light's path on the virtual arm, the torch switched by the gripper."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytestmark = [pytest.mark.hw, pytest.mark.slow]  # a real-time run of about 33 s

import light_paint  # noqa: E402
from so101_kinematics.drawing.glyphs import DEFAULT_FONT, text_strokes  # noqa: E402
from so101_kinematics.drawing.strokes import prepare  # noqa: E402
from so101_kinematics.virtual.arm import VirtualSO101  # noqa: E402


def test_a_text_painted_on_the_virtual_arm_switches_the_light_on_time(tmp_path, capsys):
    report_path = tmp_path / "light.json"
    with VirtualSO101() as arm:
        code = light_paint.main(["--text", "EE", "--size-mm", "40", "--port", arm.port,
                                 "--json", str(report_path)])
    assert code == 0, capsys.readouterr().err
    report = json.loads(report_path.read_text())
    light = report["light"]
    strokes = len(prepare(text_strokes("EE", DEFAULT_FONT)[0]))  # E: four strokes each
    assert report["aborted"] is None and strokes == 8
    # the light went on once per stroke, where the gripper's read-back crossed the click
    assert len(light["planned"]) == len(light["measured"]) == strokes
    # led by the jaw's lag, each switching within 6 control cycles of the plan (unled, the
    # presses were 130-140 ms late): at 15 mm/s under 1 mm of the stroke
    errors = np.array(light["measured"]) - np.array(light["planned"])  # [s]
    assert np.abs(errors).max() <= 0.06 and light["switch"]["worst_ms"] <= 60.0
    # while on, the read-back light is on the strokes (the drawing's bounds)
    assert light["mean_mm"] <= 1.5 and light["worst_mm"] <= 3.0
