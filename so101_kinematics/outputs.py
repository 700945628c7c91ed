"""Output files that are never lost: checked before a run, written beside, renamed when complete.

Every script of the project that writes a file (a log, a plot, a video, a
JSON report, a calibration) goes through here:
  - :func:`check_output_path` before anything runs: not a folder, its folder
    creatable and writable, never one of the run's input files, and an
    existing file is replaced only when it is recognisably this kind of output
    written by this project (an :class:`OutputKind`: a CSV log with its header,
    a JSON report with its ``generator`` key, an MP4, a PNG, a PDF), or with
    an explicit ``--overwrite``;
  - :func:`atomic_output`: the file is written under a temporary name in the
    same folder and renamed over the target only when complete, so an
    existing file is never replaced by a partial one.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from so101_kinematics.errors import OutputPathError as OutputPathError

GENERATOR = "so101-kinematics"
"""The ``generator`` key's value begins so in every JSON report this project writes."""

MAX_RECOGNISED_JSON_BYTES = 64 * 1024 * 1024  # a larger .json is not one of our reports


@dataclass(frozen=True)
class OutputKind:
    """What an output file is, and how an existing file of that kind written by us is recognised.

    Attributes:
        description: for messages, e.g. ``"an MP4 video"``.
        recognise: True when the existing file at this path is such an output.
    """

    description: str
    recognise: Callable[[Path], bool]


def _head(path: Path, size: int) -> bytes:
    try:
        with path.open("rb") as handle:
            return handle.read(size)
    except OSError:
        return b""


def _magic(magic: bytes, offset: int = 0) -> Callable[[Path], bool]:
    return lambda path: _head(path, offset + len(magic))[offset:] == magic


def stamp(report, program: str):
    """``report`` (a dict, or a list of dicts) with the ``generator`` key that marks it as ours.

    Example:
        >>> stamp({"score": 1}, "so101-check-fk")
        {'generator': 'so101-kinematics so101-check-fk', 'score': 1}
    """
    if isinstance(report, list):
        return [stamp(item, program) for item in report]
    return {"generator": f"{GENERATOR} {program}", **report}


def _stamped(item) -> bool:
    """A dict with our ``generator`` key (in Gradescope's results.json: under ``extra_data``)."""
    if not isinstance(item, dict):
        return False
    extra = item.get("extra_data")
    generator = item.get("generator") or (extra.get("generator") if isinstance(extra, dict)
                                          else None)
    return isinstance(generator, str) and generator.startswith(GENERATOR)


def _our_json(path: Path) -> bool:
    try:
        if path.stat().st_size > MAX_RECOGNISED_JSON_BYTES:
            return False
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return _stamped(data) or (isinstance(data, list) and bool(data)
                              and all(_stamped(item) for item in data))


def csv_kind(header: Sequence[str], description: str) -> OutputKind:
    """A CSV of ours: its first line is exactly ``header`` (comma-separated)."""
    line = (",".join(header) + "\n").encode()
    return OutputKind(description, lambda path: _head(path, len(line) + 1).replace(
        b"\r\n", b"\n")[:len(line)] == line)


def text_kind(first_words: str, description: str) -> OutputKind:
    """A text file of ours: it begins with ``first_words``."""
    return OutputKind(description, _magic(first_words.encode()))


PNG = OutputKind("a PNG image", _magic(b"\x89PNG\r\n\x1a\n"))
PDF = OutputKind("a PDF", _magic(b"%PDF-"))
MP4 = OutputKind("an MP4 video", _magic(b"ftyp", offset=4))
JSON_REPORT = OutputKind("a JSON report written by this project (its \"generator\" key)",
                         _our_json)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_output_path(path: str | Path, option: str, inputs: Iterable[str | Path | None] = (),
                      overwrite: bool = False, suffixes: Iterable[str] = (),
                      kind: OutputKind | None = None,
                      overwrite_option: str = "--overwrite") -> Path:
    """Check that ``path`` can be written, before anything runs; creates its folder.

    An existing file is replaced only when ``kind`` recognises it as this kind
    of output written by this project, or with ``overwrite``; never when it
    is one of ``inputs``.

    Args:
        path: the output file.
        option: how the user named it (for the message), e.g. ``"--log"``.
        inputs: the run's input files; the output may not be one of them.
        overwrite: the user asked to replace whatever is there (``overwrite_option``).
        suffixes: the file name must end in one of these (case-insensitive),
            e.g. ``(".mp4",)``; empty: any name.
        kind: what the output is (:data:`PNG`, :data:`JSON_REPORT`, :func:`csv_kind`,
            ...); None: an existing file is never replaced without ``overwrite``.
        overwrite_option: the option that sets ``overwrite``, for the message.

    Returns:
        The path, absolute.

    Raises:
        OutputPathError: naming the option, the path and the fix.
    """
    if "\0" in str(path):
        raise OutputPathError(f"{option} {str(path)!r}: a file name cannot contain a NUL "
                              "character. Fix: choose another file name.")
    target = Path(path).expanduser()
    if str(path) == "" or target.is_dir() or str(path).endswith(os.sep):
        raise OutputPathError(f"{option} {path}: is a folder. Fix: give a file name, e.g. "
                              f"{option} {target / 'out'}{_suffix_hint(option)}.")
    suffixes = tuple(suffixes)
    if suffixes and target.suffix.lower() not in suffixes:
        raise OutputPathError(f"{option} {path}: the file name must end in "
                              f"{' or '.join(suffixes)}. Fix: e.g. {option} "
                              f"{target.with_suffix(suffixes[0])}.")
    for source in inputs:
        if source is not None and (_same_file(target, Path(source))
                                   or target.resolve() == Path(source).expanduser().resolve()):
            raise OutputPathError(f"{option} {path}: is one of this run's input files; "
                                  "writing it would destroy it. Fix: choose another file name.")
    if target.exists() and not overwrite:
        if kind is None:
            raise OutputPathError(f"{option} {path}: exists already. Fix: choose another file "
                                  f"name, or pass {overwrite_option} to replace it.")
        if not kind.recognise(target):
            raise OutputPathError(f"{option} {path}: exists and is not {kind.description}; "
                                  "replacing it would destroy it (nothing was run). Fix: choose "
                                  f"another file name, or pass {overwrite_option} to replace it.")
    folder = target.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputPathError(f"{option} {path}: cannot create its folder {folder} "
                              f"({error.strerror}). Fix: choose a writable place.") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"{option} {path}: the folder {folder} is not writable. "
                              "Fix: choose a writable place.")
    if target.exists() and not os.access(target, os.W_OK):
        raise OutputPathError(f"{option} {path}: the file is read-only. Fix: choose another "
                              "file name.")
    return target.resolve()


def add_overwrite_argument(parser) -> None:
    """The ``--overwrite`` option every script with an output shares."""
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing output file even when it is not this kind of "
                        "output written by this project (never one of the run's inputs)")


def _suffix_hint(option: str) -> str:
    return {"--log": ".csv", "--plot": ".png", "--json": ".json", "--record": ".mp4",
            "--screenshot": ".png", "--frames": ".png", "--table": ".md"}.get(option, "")


def temporary_beside(path: str | Path) -> Path:
    """A new, empty temporary file in the folder of ``path`` (same file system: rename works).

    Its name ends in the target's suffix (``.clip.mp4.k2j4.part.mp4``), so writers
    that choose the format by the extension (ffmpeg, imageio, matplotlib) write
    the target's format.
    """
    target = Path(path)
    handle, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".part{target.suffix}",
                                    dir=target.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.fchmod(handle, 0o666 & ~umask)  # mkstemp makes it 0600; the output is an ordinary file
    os.close(handle)
    return Path(name)


@contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` when the block succeeds.

    If the block raises (or the program is interrupted), the temporary file is
    removed and ``path`` is untouched.

    Example:
        >>> import tempfile, pathlib
        >>> out = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
        >>> with atomic_output(out) as tmp:
        ...     _ = tmp.write_text("complete")
        >>> out.read_text()
        'complete'
    """
    target = Path(path)
    temporary = temporary_beside(target)
    try:
        yield temporary
        os.replace(temporary, target)
    finally:
        temporary.unlink(missing_ok=True)


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file; returns the path."""
    with atomic_output(path) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return Path(path)
