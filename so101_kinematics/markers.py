"""The marker this project puts in every file it writes, and how it is found again.

An output of ours is recognised by its content, never by its file type
(``outputs.check_output_path`` replaces only such a file without ``--overwrite``):

- a PNG: a ``Software`` text chunk (tEXt or iTXt) that begins with :data:`GENERATOR`
  (matplotlib: ``savefig(metadata=png_metadata(...))``; Pillow: ``PngInfo``);
- an MP4: ffmpeg's ``comment`` tag, inside the ``moov`` box (``mp4_params``);
- a PDF: the Info dictionary's ``Creator`` (matplotlib: ``PdfPages(metadata=...)``);
- a JSON report: its ``generator`` key (``outputs.stamp``); a CSV: its header line.

The boxes and chunks read are those of the PNG specification (W3C, "Portable Network
Graphics (PNG) Specification", 2nd ed., sections 5.3 and 11.3.4) and of ISO/IEC 14496-12
(an MP4 is a sequence of boxes: a 32-bit size, a 4-byte type; size 1: a 64-bit size
follows; size 0: to the end of the file).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = [
    "GENERATOR", "head_bytes", "mp4_ours", "mp4_params", "pdf_metadata", "pdf_ours",
    "png_metadata", "png_ours",
]

GENERATOR = "so101-kinematics"
"""Every file this project writes carries this: a JSON report's ``generator`` key begins so, a
PNG's ``Software`` chunk, an MP4's ``comment``, a PDF's ``Creator``."""

_MARKER = GENERATOR.encode()
_PDF_TAIL_BYTES = 1024 * 1024  # matplotlib writes a PDF's Info dictionary near its end
_MAX_MOOV_BYTES = 64 * 1024 * 1024  # an MP4's metadata box; a larger one is not ours


def png_metadata(program: str) -> dict[str, str]:
    """Matplotlib's ``savefig(metadata=...)`` for a PNG of ours: the ``Software`` text chunk."""
    return {"Software": f"{GENERATOR} {program}"}


def pdf_metadata(program: str) -> dict[str, str]:
    """Matplotlib's ``PdfPages(metadata=...)`` for a PDF of ours: its ``Creator``."""
    return {"Creator": f"{GENERATOR} {program}"}


def mp4_params(program: str) -> list[str]:
    """The ffmpeg output options (imageio's ``ffmpeg_params``) that mark an MP4 as ours."""
    return ["-metadata", f"comment={GENERATOR} {program}"]


def head_bytes(path: Path, size: int) -> bytes:
    """The first ``size`` bytes of ``path`` (empty when it cannot be read)."""
    try:
        with path.open("rb") as handle:
            return handle.read(size)
    except OSError:
        return b""


def png_ours(path: Path) -> bool:
    """A PNG with a ``Software`` text chunk (tEXt or iTXt) that begins with our marker."""
    try:
        with path.open("rb") as handle:
            if handle.read(8) != b"\x89PNG\r\n\x1a\n":
                return False
            for _ in range(100_000):
                head = handle.read(8)
                if len(head) < 8 or head[4:] == b"IEND":
                    return False
                size, kind = int.from_bytes(head[:4], "big"), head[4:]
                if kind in (b"tEXt", b"iTXt") and size <= 65536:
                    keyword, _, text = handle.read(size).partition(b"\0")
                    if kind == b"iTXt":  # compression flag, method, language, keyword: skip
                        text = text[2:].split(b"\0", 2)[-1]
                    if keyword == b"Software" and text.startswith(_MARKER):
                        return True
                    handle.seek(4, os.SEEK_CUR)
                else:
                    handle.seek(size + 4, os.SEEK_CUR)
    except OSError:
        return False
    return False


def mp4_ours(path: Path) -> bool:
    """An MP4 whose metadata box (``moov``: ffmpeg's tags) holds our marker."""
    try:
        end = path.stat().st_size
        with path.open("rb") as handle:
            position, first = 0, True
            while position + 8 <= end:
                handle.seek(position)
                head = handle.read(16)
                size, kind = int.from_bytes(head[:4], "big"), head[4:8]
                if first and kind != b"ftyp":
                    return False
                first = False
                header = 8
                if size == 1:
                    size, header = int.from_bytes(head[8:16], "big"), 16
                elif size == 0:
                    size = end - position
                if size < header:
                    return False
                if kind == b"moov":
                    if size > _MAX_MOOV_BYTES:
                        return False
                    handle.seek(position + header)
                    return _MARKER in handle.read(size - header)
                position += size
    except OSError:
        return False
    return False


def pdf_ours(path: Path) -> bool:
    """A PDF whose Info dictionary (near its end) names us as its ``Creator``."""
    if head_bytes(path, 5) != b"%PDF-":
        return False
    try:
        with path.open("rb") as handle:
            handle.seek(max(0, path.stat().st_size - _PDF_TAIL_BYTES))
            return b"/Creator (" + _MARKER in handle.read()
    except OSError:
        return False
