"""Output files that are never lost: checked before a run, written beside, renamed when complete.

Every script of the project that writes a file (a log, a plot, a video, a
JSON report, a calibration) goes through here:
  - every file it writes carries this project's marker (:data:`GENERATOR`):
    a PNG its ``Software`` text chunk (:func:`png_metadata`), an MP4 its
    ``comment`` tag (:func:`mp4_params`), a PDF its ``Creator``
    (:func:`pdf_metadata`), a JSON report its ``generator`` key (:func:`stamp`),
    a CSV its header line;
  - :func:`check_output_path` before anything runs: not a folder, not a
    symbolic link, its folder creatable and proven writable (a file is created
    there and removed), never one of the run's input files, and an existing file
    is replaced only when its content carries the marker of this kind of output
    (an :class:`OutputKind`), or with an explicit ``--overwrite``; a kind that
    is never replaced silently (a log of an earlier run) is refused even then
    without ``--overwrite``;
  - :func:`atomic_output`: the file is written under a temporary name in the
    same folder and renamed over the target only when complete, so an
    existing file is never replaced by a partial one; a SIGTERM or SIGHUP that
    would end the program removes the temporary files first.
"""

from __future__ import annotations

import json
import os
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from so101_kinematics.errors import OutputPathError
from so101_kinematics.markers import (
    GENERATOR,
    head_bytes,
    mp4_ours,
    pdf_ours,
    png_metadata,
    png_ours,
)

__all__ = [
    "JSON_REPORT", "MP4", "OutputKind", "PDF", "PNG", "add_overwrite_argument",
    "atomic_output", "check_output_path", "csv_kind", "forget_temporary", "report_of", "stamp",
    "temporary_beside", "text_kind", "write_png_atomic", "write_text_atomic",
]

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
    replaceable: bool = True
    """False: an existing file of this kind (a log of an earlier run) is refused too."""


def _magic(magic: bytes, offset: int = 0) -> Callable[[Path], bool]:
    return lambda path: head_bytes(path, offset + len(magic))[offset:] == magic


def stamp(report, program: str):
    """``report`` (a dict, or a list of dicts) with the ``generator`` key that marks it as ours.

    Example:
        >>> stamp({"score": 1}, "so101-check-fk")
        {'generator': 'so101-kinematics so101-check-fk', 'score': 1}
    """
    if isinstance(report, list):
        return [stamp(item, program) for item in report]
    return {"generator": f"{GENERATOR} {program}", **report}


def _stamped(item, program: str | None = None) -> bool:
    """A dict with our ``generator`` key (in Gradescope's results.json: under ``extra_data``).

    With ``program``: written by that program (the generator's word after ours).
    """
    if not isinstance(item, dict):
        return False
    extra = item.get("extra_data")
    generator = item.get("generator") or (extra.get("generator") if isinstance(extra, dict)
                                          else None)
    if not (isinstance(generator, str) and generator.startswith(GENERATOR)):
        return False
    return program is None or generator.split()[1:2] == [program]


def _our_json(path: Path, program: str | None = None) -> bool:
    try:
        if path.stat().st_size > MAX_RECOGNISED_JSON_BYTES:
            return False
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return _stamped(data, program) or (isinstance(data, list) and bool(data)
                                       and all(_stamped(item, program) for item in data))


def report_of(program: str) -> OutputKind:
    """A JSON report that ``program`` wrote (its ``generator`` key).

    Another program's report, ours or not, is not replaced without ``--overwrite``.

    Example:
        >>> report_of("test_ik_mujoco.py").description
        'a JSON report of test_ik_mujoco.py (its "generator" key)'
    """
    return OutputKind(f"a JSON report of {program} (its \"generator\" key)",
                      lambda path: _our_json(path, program))


def csv_kind(header: Sequence[str], description: str) -> OutputKind:
    """A CSV of ours: its first line is exactly ``header`` (comma-separated)."""
    line = (",".join(header) + "\n").encode()
    return OutputKind(description, lambda path: head_bytes(path, len(line) + 1).replace(
        b"\r\n", b"\n")[:len(line)] == line)


def text_kind(first_words: str, description: str) -> OutputKind:
    """A text file of ours: it begins with ``first_words``."""
    return OutputKind(description, _magic(first_words.encode()))


PNG = OutputKind("a PNG image written by this project (its Software text chunk)", png_ours)
PDF = OutputKind("a PDF written by this project (its Creator)", pdf_ours)
MP4 = OutputKind("an MP4 video written by this project (its comment tag)", mp4_ours)
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

    An existing file is replaced only when ``kind`` recognises it (by its
    content: our marker) as this kind of output written by this project and
    ``kind.replaceable``, or with ``overwrite``; never when it is one of
    ``inputs``. A symbolic link is refused without ``overwrite`` (with it, the
    link itself is replaced, never the file it points to). The folder is
    proven writable by creating a file there (removed at once).

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
    if target.is_symlink() and not overwrite:
        raise OutputPathError(f"{option} {path}: is a symbolic link (to {os.readlink(target)}); "
                              "writing through it would replace a file this run did not choose "
                              "(nothing was run). Fix: give the real file's path, or pass "
                              f"{overwrite_option} to replace the link itself.")
    if target.exists() and not overwrite:
        if kind is not None and not kind.replaceable and kind.recognise(target):
            raise OutputPathError(f"{option} {path}: holds {kind.description} of an earlier run; "
                                  "this run would replace it (nothing was run). Fix: choose a new "
                                  f"name, e.g. {option} {free_name(target)}, or pass "
                                  f"{overwrite_option} to replace it.")
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
    if target.exists() and not target.is_symlink() and not os.access(target, os.W_OK):
        raise OutputPathError(f"{option} {path}: the file is read-only. Fix: choose another "
                              "file name.")
    try:  # proof, not permission bits (which say yes to root on /proc or a read-only share)
        probe = temporary_beside(target)
        probe.unlink()
        forget_temporary(probe)
    except OSError as error:
        raise OutputPathError(f"{option} {path}: cannot write in its folder {folder} "
                              f"({error.strerror or error}). Fix: choose a writable place."
                              ) from None
    return folder.resolve() / target.name


def free_name(path: str | Path) -> Path:
    """The first ``NAME-2.EXT``, ``NAME-3.EXT``, ... beside ``path`` that does not exist."""
    path = Path(path)
    number = 2
    while (candidate := path.with_name(f"{path.stem}-{number}{path.suffix}")).exists() \
            or candidate.is_symlink():
        number += 1
    return candidate


def add_overwrite_argument(parser) -> None:
    """The ``--overwrite`` option every script with an output shares."""
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing output file even when it does not carry this "
                        "project's marker for its kind, is an earlier run's --log, or is a "
                        "symbolic link (the link is replaced); never one of the run's inputs")


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
    _clean_up_on_stop_signals()
    handle, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".part{target.suffix}",
                                    dir=target.parent)
    _LIVE[Path(name)] = os.getpid()
    umask = os.umask(0)
    os.umask(umask)
    os.fchmod(handle, 0o666 & ~umask)  # mkstemp makes it 0600; the output is an ordinary file
    os.close(handle)
    return Path(name)


_LIVE: dict[Path, int] = {}
"""The temporary files made by :func:`temporary_beside` not yet renamed or removed, and the
process that made each (a forked child, e.g. a virtual arm, never removes its parent's)."""


def forget_temporary(temporary: str | Path) -> None:
    """``temporary`` was renamed over its target or removed: a stop need not remove it."""
    _LIVE.pop(Path(temporary), None)


WRITER_STOP_S = 2.0
"""[s] How long a stop waits for a killed writer of a temporary file to be gone."""


def _writers_of(paths: set[str]) -> list[int]:
    """Our child processes that name one of the files ``paths`` on their command line.

    The encoders (ffmpeg, started by imageio with the temporary file as its output), found in
    Linux's /proc; matched by the file's name, which is random (however a writer spells the
    folder).
    """
    me, found = str(os.getpid()), []
    names = {os.path.basename(path) for path in paths}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parent = stat.read_text().rsplit(")", 1)[1].split()[1]
            argv = (stat.parent / "cmdline").read_bytes().split(b"\0")
        except (OSError, IndexError):  # gone meanwhile, or not readable
            continue
        if parent == me and any(os.path.basename(arg.decode(errors="replace")) in names
                                for arg in argv):
            found.append(int(stat.parent.name))
    return found


def _stop_writers(paths: set[str]) -> None:
    """Kill the writers of ``paths`` and wait until each is gone.

    Gone is a zombie (it is our child): none opens its output again after the file is removed.
    """
    writers = _writers_of(paths)
    for pid in writers:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + WRITER_STOP_S
    for pid in writers:
        while time.monotonic() < deadline:
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                break
            if state in ("Z", "X"):
                break
            time.sleep(0.01)


def _remove_and_die(signum, _frame) -> None:
    """End on a SIGTERM/SIGHUP as its default would, our temporary files removed first.

    Their writers are stopped before that: an encoder that had not yet opened its output
    would make it again after the removal and leave it behind.
    """
    ours = [temporary for temporary, owner in list(_LIVE.items()) if owner == os.getpid()]
    if ours:
        _stop_writers({temporary.name for temporary in ours})
    for temporary in ours:
        temporary.unlink(missing_ok=True)
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def _clean_up_on_stop_signals() -> None:
    """Install :func:`_remove_and_die` for SIGTERM and SIGHUP where nothing else handles them.

    A program that handles them itself (the hardware script: a controlled stop that
    raises KeyboardInterrupt) keeps its handler; its ``finally`` blocks remove the files.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(signum) == signal.SIG_DFL:
            signal.signal(signum, _remove_and_die)


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
        forget_temporary(temporary)


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file; returns the path."""
    with atomic_output(path) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return Path(path)


def write_png_atomic(path: str | Path, pixels, program: str) -> Path:
    """Write an (height, width, 3) uint8 image as a PNG of ours (``markers.py``) to ``path``.

    Through a temporary file, as :func:`write_text_atomic`; ``program`` names the writer in
    the PNG's ``Software`` chunk (what :data:`PNG` recognises before replacing a file).
    """
    from PIL import Image, PngImagePlugin

    marker = PngImagePlugin.PngInfo()
    for key, text in png_metadata(program).items():
        marker.add_text(key, text)
    with atomic_output(path) as temporary:
        Image.fromarray(pixels).save(temporary, format="PNG", pnginfo=marker)
    return Path(path)
