"""Runs in a child process: imports one student's FK, IK or vision module and calls its functions.

Started by :mod:`so101_kinematics.checker.sandbox` as ``python -I -B probe.py
REQUEST RESULT`` in a temporary working folder. It uses only the standard
library and numpy (never ``so101_kinematics``), so the student's module is
the only code of interest in this process. The student's prints are kept up
to ``OUTPUT_LIMIT`` characters; the results are rewritten after each function
(for an IK, every ``IK_SAVE_EVERY`` targets), so a submission that hangs in
``get_forward_kinematics`` still has its factors checked. The current stage is
written to ``RESULT.stage`` for the time-out message.

The student's folder comes first on ``sys.path`` (an IK imports its own
``so101_forward_kinematics`` from beside it); the request's ``fallback_modules``
are written to a folder at the end of ``sys.path``, found only when the
student's folder has no module of that name.
"""

from __future__ import annotations

import importlib.util
import io
import json
import os
import resource
import sys
import traceback

__all__: list[str] = []

OUTPUT_LIMIT = 4000
"""Characters of the student's own output kept for the report."""

FILE_SIZE_LIMIT = 32 * 1024 * 1024
"""Largest file this process may write [bytes] (a module printing without end)."""

FACTORS = ("get_gw1", "get_g12", "get_g23", "get_g34", "get_g45")

IK_SAVE_EVERY = 25
"""IK targets between two writes of the results (a hang keeps the answers before it)."""

REFUSED: list[str] = []
"""The writes outside the working folder :func:`confine` refused ("open for writing PATH")."""

_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND

_WRITES = {"os.remove": ("remove", ((0, 1),)), "os.rmdir": ("remove the folder", ((0, 1),)),
           "os.mkdir": ("make the folder", ((0, 2),)), "os.rename": ("rename", ((0, 2), (1, 3))),
           "os.link": ("link", ((1, 3),)), "os.symlink": ("link", ((1, 2),)),
           "os.truncate": ("truncate", ((0, None),)), "os.chmod": ("chmod", ((0, 2),)),
           "os.chown": ("chown", ((0, 3),)), "os.utime": ("touch", ((0, 3),)),
           "shutil.rmtree": ("remove the tree", ((0, 1),))}
"""Audit event -> (what it does, (index of a path it changes, index of that path's ``dir_fd``
or None) for each such path): every file-changing event of the standard library
(``os.replace`` and ``os.unlink`` raise ``os.rename`` and ``os.remove``; ``open`` is checked
apart, by its mode)."""


def confine(folder: str, own_files: tuple[str, ...] = ()) -> None:
    """From now on, refuse every write outside ``folder`` in this process (an audit hook).

    A write outside (``open`` for writing, remove, rename, mkdir, link, chmod, ...) raises
    ``PermissionError`` naming the path, and is recorded in :data:`REFUSED`, so the checker
    names it even when the student's code catches the error. Paths are resolved (``..``,
    symlinks, ``dir_fd``) before they are compared. ``own_files`` are the probe's results.
    The hook cannot be removed, but it is no security boundary against deliberately hostile
    code: a C extension (``ctypes``) or a program the module starts is not audited.
    """
    root = os.path.realpath(folder)
    own = {os.path.realpath(path) for path in own_files}

    def inside(path, dir_fd=None) -> bool:
        if isinstance(path, int):
            return True  # an open descriptor: its opening was checked
        path = os.fsdecode(os.fspath(path))
        if isinstance(dir_fd, int) and dir_fd >= 0 and not os.path.isabs(path):
            path = os.path.join(os.readlink(f"/proc/self/fd/{dir_fd}"), path)
        real = os.path.realpath(path)
        return real == root or real.startswith(root + os.sep) or real in own

    def hook(event: str, args: tuple) -> None:
        if event == "open":
            path, mode, flags = args
            writes = (any(c in mode for c in "wax+") if isinstance(mode, str)
                      else bool((flags or 0) & _WRITE_FLAGS))
            changes = [("open for writing", path, None)] if writes else []
        elif event in _WRITES:
            what, paths = _WRITES[event]
            changes = [(what, args[i], args[fd] if fd is not None and fd < len(args) else None)
                       for i, fd in paths]
        else:
            return
        for what, path, dir_fd in changes:
            if path is not None and not inside(path, dir_fd):
                refused = f"{what} {os.fsdecode(os.fspath(path))}"
                if len(REFUSED) < 20:  # a loop of writes: the first ones name it
                    REFUSED.append(refused)
                raise PermissionError(
                    f"so101-check refused to {refused}: a submission runs in a temporary "
                    "folder and may write only there (e.g. a plain file name)")

    sys.addaudithook(hook)


class BoundedOutput(io.TextIOBase):
    """A text stream that keeps the first ``OUTPUT_LIMIT`` characters and counts the rest."""

    def __init__(self):
        self.kept = []
        self.size = 0

    def writable(self) -> bool:
        """It is."""
        return True

    def write(self, text) -> int:
        """Keep what fits, count everything."""
        text = str(text)
        room = OUTPUT_LIMIT - min(self.size, OUTPUT_LIMIT)
        if room > 0:
            self.kept.append(text[:room])
        self.size += len(text)
        return len(text)

    def text(self) -> str:
        """What was kept."""
        return "".join(self.kept)


def describe_error(error: BaseException) -> str:
    """``Type: message`` and the student's line where it happened."""
    where = ""
    for frame in reversed(traceback.extract_tb(error.__traceback__)):
        if frame.filename == MODULE_PATH:
            where = f" (line {frame.lineno}: {(frame.line or '').strip()[:80]})"
            break
    message = " ".join(str(error).split())[:300]
    return f"{type(error).__name__}: {message}{where}"


def as_matrix(value):
    """``(list, shape)`` of a returned value, or ``(None, description)``."""
    import numpy as np

    try:
        array = np.asarray(value, dtype=float)
    except Exception as error:  # not numbers
        return None, f"not an array of numbers ({type(value).__name__}: {error})"
    return array.tolist(), list(array.shape)


def call(function, *args):
    """``{"value": ..., "shape": ...}`` or ``{"error": ...}`` of one call."""
    try:
        value = function(*args)
    except BaseException as error:  # the student's code may raise anything, even SystemExit
        if isinstance(error, KeyboardInterrupt):
            raise
        return {"error": describe_error(error)}
    return value


def matrix_result(value) -> dict:
    """A factor's return value as JSON."""
    if isinstance(value, dict) and "error" in value:
        return value
    numbers, shape = as_matrix(value)
    if numbers is None:
        return {"error": shape}
    return {"value": numbers, "shape": shape, "type": type(value).__name__}


def fk_result(value) -> dict:
    """``get_forward_kinematics``'s return value as JSON: the parts of the tuple."""
    if isinstance(value, dict) and "error" in value:
        return value
    if not isinstance(value, (tuple, list)):
        numbers, shape = as_matrix(value)
        return {"parts": None, "type": type(value).__name__, "value": numbers, "shape": shape}
    parts = []
    for part in value:
        numbers, shape = as_matrix(part)
        parts.append({"value": numbers, "shape": shape} if numbers is not None
                     else {"error": shape})
    return {"parts": parts, "type": type(value).__name__}


def fk_call(fk, configuration: dict) -> dict:
    """:func:`fk_result` of one call on a copy of ``configuration``, with ``"changed"``.

    ``"changed"``: what the call changed in the dict it was given (key -> [before, after];
    before None for a key it added, after "deleted" for one it removed).
    """
    given = dict(configuration)
    result = fk_result(call(fk, given))
    changed = {}
    for key in list(configuration) + [k for k in given if k not in configuration]:
        before, after = configuration.get(key), given.get(key, "deleted")
        try:
            after = float(after)
        except Exception:  # deleted, or not a number
            after = after if isinstance(after, str) else repr(after)[:40]
        if after != before:
            changed[str(key)] = [before, after]
    return {**result, "changed": changed} if changed else result


def add_import_paths(request: dict, result_path: str) -> str:
    """Put the student's folder first on ``sys.path``, the fallback modules' last.

    The request's fallback modules are the course's own files, for a student file that
    imports one it did not hand in. Returns the fallback folder.
    """
    sys.path.insert(0, os.path.dirname(request["module"]))
    fallback = os.path.join(os.path.dirname(result_path), "fallback")
    os.makedirs(fallback, exist_ok=True)
    for name, source in request.get("fallback_modules", {}).items():
        with open(os.path.join(fallback, name + ".py"), "w", encoding="utf-8") as handle:
            handle.write(source)
    sys.path.append(fallback)
    return fallback


def own_files(result_path: str) -> tuple[str, ...]:
    """The files the probe itself writes after the student's import (its results)."""
    return tuple(result_path + suffix for suffix in ("", ".part", ".stage"))


def main() -> None:
    """Import the module named in the request and evaluate what it asks for."""
    global MODULE_PATH
    request_path, result_path = sys.argv[1], sys.argv[2]
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_SIZE_LIMIT, FILE_SIZE_LIMIT))
    with open(request_path, encoding="utf-8") as handle:
        request = json.load(handle)
    MODULE_PATH = request["module"]
    results = {"stage": "import", "functions": {}, "output": "", "output_size": 0}
    captured = BoundedOutput()

    def save(stage: str, keep: bool = True) -> None:
        """Record the stage; with ``keep``, also the results so far (not after every call)."""
        with open(result_path + ".stage", "w", encoding="utf-8") as handle:
            handle.write(stage)
        if keep:
            results["stage"] = stage
            results["output"], results["output_size"] = captured.text(), captured.size
            with open(result_path + ".part", "w", encoding="utf-8") as handle:
                handle.write(json.dumps(results))  # the C encoder: json.dump is 10x slower
            os.replace(result_path + ".part", result_path)

    save("import")
    fallback = add_import_paths(request, result_path)
    results["refused_writes"] = REFUSED
    confine(os.getcwd(), own_files(result_path))
    sys.stdout = sys.stderr = captured
    module_name = request.get("module_name", "so101_forward_kinematics")
    spec = importlib.util.spec_from_file_location(module_name, MODULE_PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException as error:
        results["import_error"] = describe_error(error)
        save("import failed")
        return
    results["names"] = sorted(name for name in dir(module)
                              if not name.startswith("__") and callable(getattr(module, name)))
    if request.get("kind") == "ik":
        probe_ik(module, request, results, save, fallback)
    elif request.get("kind") == "vision":
        probe_vision(module, request, results, save)
    else:
        probe_fk(module, request, results, save)
    save("done")


def probe_fk(module, request: dict, results: dict, save) -> None:
    """Call the FK's factors and ``get_forward_kinematics`` as the request asks."""
    for name in FACTORS:
        save(f"calling {name}", keep=False)
        function = getattr(module, name, None)
        if callable(function):
            results["functions"][name] = [matrix_result(call(function, angle))
                                          for angle in request["angles"][name]]
    save("calling get_g5t", keep=False)
    if callable(getattr(module, "get_g5t", None)):
        results["functions"]["get_g5t"] = [matrix_result(call(module.get_g5t))]
    fk = getattr(module, "get_forward_kinematics", None)
    if callable(fk):
        save("calling get_forward_kinematics")
        results["functions"]["get_forward_kinematics"] = [
            fk_call(fk, configuration) for configuration in request["configurations"]]
        save("calling get_forward_kinematics without a gripper key", keep=False)
        results["without_gripper"] = fk_result(call(fk, dict(request["without_gripper"])))
    if request.get("product_configurations"):
        save("multiplying the factors", keep=False)
        products = []
        for configuration in request["product_configurations"]:
            row = {}
            for name, joint in zip(FACTORS, request["joints"], strict=True):
                function = getattr(module, name, None)
                row[name] = matrix_result(call(function, configuration[joint])) \
                    if callable(function) else {"error": "missing"}
            products.append(row)
        results["products"] = products


def _rotation_z(yaw: float):
    """Rz(yaw) as the course builds it (a numpy array) [rad]."""
    import numpy as np

    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def config_result(value) -> dict:
    """An IK's return value as JSON: ``{"value": {joint: number}}`` or what it was instead."""
    if isinstance(value, dict) and set(value) == {"error"}:
        return value
    if not isinstance(value, dict):
        numbers, shape = as_matrix(value)
        return {"error": f"returns a {type(value).__name__}" + (
            f" of shape {tuple(shape)}" if numbers is not None else "") + "; expected a dict"}
    config, odd = {}, []
    for key, number in value.items():
        try:
            config[str(key)] = float(number)
        except Exception:  # a value that is not a number
            odd.append(str(key))
    return {"value": config, **({"not_numbers": odd} if odd else {})}


def probe_ik(module, request: dict, results: dict, save, fallback: str) -> None:
    """Call ``get_inverse_kinematics(position, Rz(yaw))`` at each target, then the own FK."""
    ik = getattr(module, "get_inverse_kinematics", None)
    fk_module = sys.modules.get("so101_forward_kinematics")
    fk_file = getattr(fk_module, "__file__", None) or ""
    results["fk_module"] = ("" if fk_module is None else "fallback"
                            if os.path.dirname(os.path.abspath(fk_file)) == fallback else fk_file)
    if not callable(ik):
        return
    answers = results["functions"]["get_inverse_kinematics"] = []
    for index, (x, y, z, yaw) in enumerate(request["targets"]):
        save(f"calling get_inverse_kinematics at target {index} ({x:.3f}, {y:.3f}, {z:.3f}) m, "
             f"yaw {yaw:.3f} rad", keep=index % IK_SAVE_EVERY == 0)
        answers.append(config_result(call(ik, [x, y, z], _rotation_z(yaw))))
    own_fk = getattr(fk_module, "get_forward_kinematics", None)
    if callable(own_fk) and results["fk_module"] not in ("", "fallback"):
        save("calling your own get_forward_kinematics on the answers")
        results["own_fk"] = [
            fk_result(call(own_fk, dict(answer["value"]))) if "value" in answer else None
            for answer in answers]


def probe_vision(module, request: dict, results: dict, save) -> None:
    """Call ``camera_to_base`` at each case's points and ``tag_pose_in_base`` at each case."""
    import numpy as np

    for name in ("camera_to_base", "tag_pose_in_base"):
        function = getattr(module, name, None)
        if not callable(function):
            continue
        answers = results["functions"][name] = []
        for index, case in enumerate(request["cases"]):
            save(f"calling {name} with camera {index}")
            position, xmat = np.array(case["cam_pos"]), np.array(case["cam_xmat"])
            if name == "camera_to_base":
                answers.append([matrix_result(call(function, position.copy(), xmat.copy(),
                                                   np.array(point)))
                                for point in case["points"]])
            else:
                answers.append(fk_result(call(function, np.array(case["corners"]),
                                              np.array(case["K"]), position, xmat)))


MODULE_PATH = ""

if __name__ == "__main__":
    main()
