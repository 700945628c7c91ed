"""Output files that are never lost: checked before a run, written beside, renamed when complete.

Every script of the project that writes a file (a log, a plot, a video, a
JSON report, a calibration) goes through here:
  - :func:`check_output_path` before anything runs: not a folder, its folder
    creatable and writable, never one of the run's input files;
  - :func:`atomic_output`: the file is written under a temporary name in the
    same folder and renamed over the target only when complete, so an
    existing file is never replaced by a partial one.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from so101_kinematics.errors import OutputPathError as OutputPathError


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_output_path(path: str | Path, option: str, inputs: Iterable[str | Path | None] = (),
                      overwrite: bool = True, suffixes: Iterable[str] = ()) -> Path:
    """Check that ``path`` can be written, before anything runs; creates its folder.

    Args:
        path: the output file.
        option: how the user named it (for the message), e.g. ``"--log"``.
        inputs: the run's input files; the output may not be one of them.
        overwrite: False refuses an existing file (the message names ``--force``).
        suffixes: the file name must end in one of these (case-insensitive),
            e.g. ``(".mp4",)``; empty: any name.

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
        raise OutputPathError(f"{option} {path}: exists already. Fix: pass --force to replace "
                              "it, or choose another file name.")
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
