"""The placement sheet (so101 sheet): measured on the PDF's own vector drawing.

The PDF is parsed here (its content streams, in points of 1/72 inch): the cube
squares, the scale bar and the origin are found by their colours and measured
in mm at 100 % print; the labels are read from the text operators.
"""

from __future__ import annotations

import math
import re
import zlib

import numpy as np
import pytest

import pick_place_hw
from so101_forward_kinematics import get_forward_kinematics, get_gw1
from so101_kinematics.commands import so101_command
from so101_kinematics.lab.sheet import CUBE_COLOR, ORIGIN_COLOR, PAN_AXIS_COLOR, SCALE_BAR_COLOR
from so101_kinematics.planning.plans import FINAL_CONFIGURATION, STARTING_CONFIGURATION

MM_PER_PT = 25.4 / 72.0
PAPER = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}  # ISO 216 and ANSI: [mm]


def pdf_pages(path):
    """[(media box (w, h) [mm], content stream text)] for each page, in order."""
    data = path.read_bytes()
    objects = {int(n): (head, body) for n, head, body in re.findall(
        rb"(\d+) 0 obj\s*<<(.*?)>>\s*(?:stream\r?\n(.*?)endstream)?", data, re.S)}
    page_ids = [int(n) for n in re.findall(rb"/Kids \[ ([\d R]+) \]", data)[0].split()[::3]]
    pages = []
    for n in page_ids:
        head = objects[n][0]
        box = [float(v) for v in re.search(rb"/MediaBox \[ ([^\]]+) \]", head)[1].split()]
        contents = int(re.search(rb"/Contents (\d+) 0 R", head)[1])
        text = zlib.decompress(objects[contents][1]).decode("latin-1")
        pages.append(((box[2] * MM_PER_PT, box[3] * MM_PER_PT), text))
    return pages


def painted_paths(stream):
    """[(stroke colour, fill colour, [(x, y) points in mm], painting operator)] of a stream."""
    tokens = re.findall(r"\((?:\\.|[^\\)])*\)|\[|\]|[^\s\[\]]+", stream)
    stroke, fill, stack, path, found = None, None, [], [], []
    for token in tokens:
        if token in ("RG", "rg"):
            colour = tuple(round(float(v), 3) for v in stack[-3:])
            stroke, fill = (colour, fill) if token == "RG" else (stroke, colour)
        elif token in ("m", "l"):
            path.append((float(stack[-2]) * MM_PER_PT, float(stack[-1]) * MM_PER_PT))
        elif token == "c":
            path.append((float(stack[-2]) * MM_PER_PT, float(stack[-1]) * MM_PER_PT))
        elif token in ("S", "f", "B", "b", "f*", "n"):
            if path:
                found.append((stroke, fill, path, token))
            path = []
        stack = stack[-8:] + [token] if token not in ("q", "Q") else stack
    return found


def texts(stream):
    """The strings shown by each TJ operator, kerning dropped."""
    return ["".join(re.findall(r"\(((?:\\.|[^\\)])*)\)", array)).replace("\\(", "(").replace(
        "\\)", ")") for array in re.findall(r"\[(.*?)\]\s*TJ", stream, re.S)]


def colour(rgb):
    return tuple(round(v, 3) for v in rgb)


def squares(stream):
    """Side lengths [mm] and centres of the cube squares (closed 4-corner paths, cube colour)."""
    found = []
    for stroke, fill, path, _ in painted_paths(stream):
        if stroke == colour(CUBE_COLOR) and fill != stroke and len(path) == 4:  # not the "+"
            corners = np.array(path)
            sides = np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1)
            found.append((sides, corners.mean(axis=0)))
    return found


def make_sheet(tmp_path, *args):
    out = tmp_path / "sheet.pdf"
    assert so101_command.main(["sheet", str(out), *args]) == 0
    return out


@pytest.mark.parametrize("paper", ["a4", "letter"])
def test_the_course_plan_sheet_is_true_to_size_on_every_page(tmp_path, paper, capsys):
    pages = pdf_pages(make_sheet(tmp_path, "--paper", paper))
    assert len(pages) > 1  # the course's cubes are 38 cm apart: more than a page
    found_squares = []
    for size, stream in pages:
        assert sorted(size) == pytest.approx(sorted(PAPER[paper]), abs=0.05)
        bars = [path for _, fill, path, op in painted_paths(stream)
                if fill == colour(SCALE_BAR_COLOR) and op == "f"]
        assert len(bars) == 1
        xs = [x for x, _ in bars[0]]
        assert max(xs) - min(xs) == pytest.approx(100.0, abs=0.5)
        assert any("check with a ruler" in text for text in texts(stream))
        found_squares += squares(stream)
    assert len(found_squares) >= 2
    for sides, _ in found_squares:
        assert sides == pytest.approx([26.0] * 4, abs=0.3)
    # tiles: every alignment mark's letter is on exactly the two pages that overlap there
    letters = [{t for t in texts(stream) if re.fullmatch(r"[A-Z]{1,2}", t)} for _, stream in pages]
    every = set().union(*letters)
    assert every and all(sum(letter in page for page in letters) >= 2 for letter in every)


def test_labels_are_the_fk_positions_of_the_pick_and_place(tmp_path):
    all_text = " ".join(t for _, s in pdf_pages(make_sheet(tmp_path)) for t in texts(s))
    for role, cfg in (("pick", STARTING_CONFIGURATION), ("place", FINAL_CONFIGURATION)):
        position = get_forward_kinematics(cfg)[0]  # the course's FK [m]
        match = re.search(rf"{role} \([^)]*\): x = (-?[\d.]+) cm, y = (-?[\d.]+) cm", all_text)
        assert match, all_text
        assert float(match[1]) == pytest.approx(position[0] * 100.0, abs=0.1)
        assert float(match[2]) == pytest.approx(position[1] * 100.0, abs=0.1)


def test_on_one_page_the_squares_sit_at_their_positions_from_the_origin(tmp_path):
    pick, place, yaw = (0.16, 0.06, 0.013), (0.16, -0.06, 0.013), 20.0
    out = make_sheet(tmp_path, "--pick", *map(str, pick), "--place", *map(str, place),
                     "--cube-yaw", str(yaw))
    (size, stream), = pdf_pages(out)
    (origin,) = [np.mean(path, axis=0) for _, fill, path, _ in painted_paths(stream)
                 if fill == colour(ORIGIN_COLOR)]
    found = squares(stream)
    assert len(found) == 2
    for sides, _ in found:
        assert sides == pytest.approx([26.0] * 4, abs=0.3)
    # x up the page, y to the left: paper (right, up) = (-y, x) [mm]
    expected = sorted([(-p[1] * 1000.0, p[0] * 1000.0) for p in (pick, place)])
    measured = sorted(tuple(centre - origin) for _, centre in found)
    assert np.array(measured) == pytest.approx(np.array(expected), abs=1.0)
    # the squares are turned by the cube's yaw: an edge at yaw (mod 90) from the x axis
    corners = [path for stroke, fill, path, _ in painted_paths(stream)
               if stroke == colour(CUBE_COLOR) and fill != stroke and len(path) == 4][0]
    edge = np.subtract(corners[1], corners[0])
    angle = math.degrees(math.atan2(-edge[0], edge[1]))  # from paper (u, v) back to (y, x)
    assert (angle - yaw) % 90.0 == pytest.approx(0.0, abs=0.5) or \
        (angle - yaw) % 90.0 == pytest.approx(90.0, abs=0.5)


def test_a_sheet_needs_a_pdf_name_and_leaves_an_existing_file_when_refused(tmp_path, capsys):
    out = tmp_path / "sheet.txt"
    assert so101_command.main(["sheet", str(out)]) == 2
    assert "so101 sheet" in capsys.readouterr().err and not out.exists()


def test_the_pan_axis_is_marked_38_8_mm_in_front_of_the_origin_as_printed(tmp_path):
    """The origin is the base frame's; the arm turns about a vertical 38.8 mm further in x.

    A TA who centred the arm's axis on the origin would put every cube 3.9 cm off
    (issue 28). 38.8 mm: the issue's measurement, and the course FK's g_w1 offset.
    """
    assert get_gw1(0.0)[:2, 3] * 1000.0 == pytest.approx([38.8, 0.0], abs=0.05)
    assert get_gw1(70.0)[:2, 3] * 1000.0 == pytest.approx([38.8, 0.0], abs=0.05)  # the axis
    out = make_sheet(tmp_path, "--pick", "0.16", "0.06", "0.013", "--place", "0.16", "-0.06",
                     "0.013")
    (_, stream), = pdf_pages(out)
    marks = {name: [np.mean(path, axis=0) for _, fill, path, _ in painted_paths(stream)
                    if fill == colour(rgb)] for name, rgb in (("origin", ORIGIN_COLOR),
                                                               ("pan", PAN_AXIS_COLOR))}
    (origin,), (pan,) = marks["origin"], marks["pan"]
    right, up = pan - origin  # x is up the page
    assert up == pytest.approx(38.8, abs=0.3) and right == pytest.approx(0.0, abs=0.3)
    words = " ".join(texts(stream))
    assert "base frame origin" in words and "under the shoulder_pan axis" not in words
    assert "shoulder_pan axis: 38.8 mm in front of" in words


def positioned_texts(stream):
    """[(x, y) [mm] where each text starts (left end, baseline), its string]."""
    found = []
    for match in re.finditer(r"1 0 -?0 1 ([-\d.]+) ([-\d.]+) cm\s*BT.*?\[(.*?)\]\s*TJ", stream,
                             re.S):
        text = "".join(re.findall(r"\(((?:\\.|[^\\)])*)\)", match[3]))
        found.append((float(match[1]) * MM_PER_PT, float(match[2]) * MM_PER_PT,
                      text.replace("\\(", "(").replace("\\)", ")")))
    return found


def test_the_stacking_sheets_labels_stay_inside_the_drawing_of_their_page(tmp_path):
    """Issue 28: every page printed every block's label, over the header and off the paper.

    The drawing's window on the paper: 10 mm margins, a 17 mm header above it and
    a 14 mm footer below it (the sheet's layout, measured here in the PDF).
    """
    pages = pdf_pages(make_sheet(tmp_path, "--stack", "0.15", "0.10"))
    assert len(pages) > 1
    labelled = set()
    for (width, height), stream in pages:
        left, right = 10.0, width - 10.0
        bottom, top = 10.0 + 14.0, height - 10.0 - 17.0
        for x, y, text in positioned_texts(stream):
            if re.match(r"(block \d+ \(start\)|stack \(\d+ blocks\)): x = ", text):
                labelled.add(text)
                assert left <= x <= right and bottom <= y <= top, (x, y, text)
    assert {t.split(":")[0] for t in labelled} == {"block 1 (start)", "block 2 (start)",
                                                   "stack (2 blocks)"}


def test_the_old_sheet_options_are_refused_in_one_line_with_the_new_spelling(capsys):
    """Issue 35: --sheet and --paper moved to `so101 sheet`; the old spelling says so."""
    for old in (["--sheet", "s.pdf"], ["--dry-run", "--paper", "letter"]):
        assert pick_place_hw.main(old) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "moved to the so101 command" in err[0]
        assert "Fix: run `so101 sheet PATH.pdf" in err[0]
