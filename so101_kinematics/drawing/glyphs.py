"""Text in a Hershey stroke font and the simple shapes (star, circle, square), as strokes [mm].

A Hershey font draws each glyph as single pen strokes (not outlines), as a plotter or a
robot with a pen does: the ``hershey-fonts`` package (PyPI, ``HersheyFonts``) carries the
fonts and their glyphs' strokes in the font's units (y down, the cap line at -12 and the
base line at 9 in the Roman simplex fonts, the descenders' bottom line at 16).

The text's size is the font's line height, as the package's ``normalize_rendering`` means
it: from the cap line to the descenders' bottom line (28 units in ``futural``), so a
capital is 21/28 of ``height`` tall (22.5 mm at 30 mm) and a line of text stacks with the
next without touching it.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from so101_kinematics.errors import PlanError

__all__ = ["DEFAULT_FONT", "SHAPES", "cap_height", "shape_strokes", "text_strokes"]

DEFAULT_FONT = "futural"
"""The Hershey font by default: "Futura light", the Roman simplex: one stroke per line."""

SHAPES = ("star", "circle", "square")
"""The simple shapes :func:`shape_strokes` draws."""

CIRCLE_SEGMENTS = 180  # a 2 deg step: a 120 mm circle strays 0.03 mm from its chords


@functools.lru_cache(maxsize=4)
def _font(name: str):
    """The ``HersheyFonts`` object with font ``name`` loaded (once per font)."""
    from HersheyFonts import HersheyFonts  # the hershey-fonts package (base dependency)

    font = HersheyFonts()
    if name not in font.default_font_names:
        raise PlanError(f"font {name!r} is not one of the Hershey fonts "
                        f"({', '.join(font.default_font_names)}). Fix: use {DEFAULT_FONT}.")
    font.load_default_font(name)
    return font


def _lines(font) -> tuple[float, float]:
    """The font's (cap line, bottom line) in its units (y down)."""
    options = font.render_options
    return float(options["cap_line"]), float(options["bottom_line"])


def cap_height(height: float, font: str = DEFAULT_FONT) -> float:
    """A capital's height [mm] in text of line height ``height`` [mm].

    Example:
        >>> round(cap_height(30.0), 2)  # futural: base line 9, cap line -12, bottom 16
        22.5
    """
    loaded = _font(font)
    cap, bottom = _lines(loaded)
    return height * (float(loaded.render_options["base_line"]) - cap) / (bottom - cap)


def text_strokes(text: str, font: str = DEFAULT_FONT) -> tuple[list[np.ndarray], tuple]:
    """The strokes of ``text`` in the font's units, y up, and its (bottom, cap) lines.

    Args:
        text: one line of printable characters.
        font: a Hershey font's name (``DEFAULT_FONT``).

    Returns:
        ``(strokes, (bottom, top))``: the polylines (x to the right, y up, the glyphs
        advanced by their widths) and the font's descender and cap lines in the same
        units, for :func:`strokes.fit_to_height`.

    Raises:
        PlanError: an empty (or blank) text, a character the font has no glyph for.
    """
    if not text or not text.strip():
        raise PlanError("--text is empty: there is nothing to draw. Fix: give the words, "
                        "e.g. --text \"ECE 4560\".")
    loaded = _font(font)
    glyphs = loaded.all_glyphs
    unknown = sorted({c for c in text if c not in glyphs or c == "\x7f"})
    if unknown:
        shown = ", ".join(repr(c) for c in unknown)
        raise PlanError(f"--text {text!r}: the font {font} has no glyph for {shown} (it draws "
                        "the printable ASCII characters, space to ~). Fix: leave "
                        f"{'it' if len(unknown) == 1 else 'them'} out or spell it in ASCII.")
    strokes, advance = [], 0.0
    for char in text:
        glyph = glyphs[char]
        for stroke in glyph.strokes:
            points = np.array(stroke, dtype=float)
            strokes.append(np.column_stack([advance + points[:, 0] - glyph.left_offset,
                                            -points[:, 1]]))
        advance += glyph.char_width
    cap, bottom = _lines(loaded)
    return [s for s in strokes if len(s) >= 2], (-bottom, -cap)


def shape_strokes(shape: str) -> list[np.ndarray]:
    """A simple shape as strokes, 1 unit high (y up), centred on the origin.

    Args:
        shape: "star" (five points, one closed stroke through them all), "circle" or
            "square".

    Example:
        >>> shape_strokes("square")[0][:2].ravel().round(3).tolist()
        [-0.5, -0.5, 0.5, -0.5]
    """
    if shape == "square":
        return [np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5], [-0.5, -0.5]])]
    if shape == "circle":
        angles = np.linspace(0.0, 2.0 * math.pi, CIRCLE_SEGMENTS + 1)
        return [0.5 * np.column_stack([np.cos(angles), np.sin(angles)])]
    if shape == "star":  # the pentagram: every second of five points on a circle
        angles = math.pi / 2 + np.arange(6) * 4.0 * math.pi / 5
        points = np.column_stack([np.cos(angles), np.sin(angles)])
        low, high = points[:, 1].min(), points[:, 1].max()
        return [points / (high - low)]
    raise PlanError(f"--shape {shape!r} is not one of {', '.join(SHAPES)}. Fix: use one of them.")
