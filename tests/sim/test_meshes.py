"""Meshes: installed from the pinned package, hash-verified, clear errors if missing or corrupt."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest
from conftest import REPO

import so101_kinematics.sim.meshes as meshes
from so101_kinematics.errors import MeshError


@pytest.fixture
def asset_copy(tmp_path, model):  # model: makes sure the real meshes are installed
    directory = tmp_path / "assets"
    shutil.copytree(meshes.ASSET_DIR, directory)
    return directory


def test_manifest_lists_every_mesh_the_model_uses():
    names = meshes.read_manifest()
    assert len(names) == 13
    assert all(re.fullmatch(r"[0-9a-f]{64}", digest) for digest in names.values())
    xml = (REPO / "model" / "so101.xml").read_text()
    used = set(re.findall(r'<mesh file="([^"]+)"', xml))
    assert used == set(names)


def test_installed_meshes_verify(model):
    meshes.verify_meshes()
    for name, digest in meshes.read_manifest().items():
        assert meshes.sha256_of(meshes.ASSET_DIR / name) == digest


def test_missing_mesh_names_the_file_and_the_fix(asset_copy):
    victim = sorted(meshes.read_manifest())[3]
    (asset_copy / victim).unlink()
    with pytest.raises(MeshError) as error:
        meshes.verify_meshes(asset_copy)
    message = str(error.value)
    assert victim in message and "missing" in message
    assert meshes.FIX_COMMAND in message


def test_corrupt_mesh_names_the_file_and_the_fix(asset_copy):
    victim = sorted(meshes.read_manifest())[5]
    path = asset_copy / victim
    content = bytearray(path.read_bytes())
    content[100] ^= 0xFF  # one flipped byte
    path.write_bytes(bytes(content))
    with pytest.raises(MeshError) as error:
        meshes.verify_meshes(asset_copy)
    message = str(error.value)
    assert victim in message and "corrupt" in message
    assert meshes.FIX_COMMAND in message
    # ensure_meshes does not silently accept it either; a reinstall repairs it.
    with pytest.raises(MeshError, match=re.escape(victim)):
        meshes.ensure_meshes(asset_copy)
    meshes.install_meshes(asset_copy)
    meshes.verify_meshes(asset_copy)


def test_ensure_meshes_reinstalls_a_missing_file(asset_copy):
    victim = sorted(meshes.read_manifest())[0]
    (asset_copy / victim).unlink()
    meshes.ensure_meshes(asset_copy)
    assert meshes.sha256_of(asset_copy / victim) == meshes.read_manifest()[victim]


def test_command_line_check_passes_on_the_installed_meshes(model):
    result = subprocess.run([sys.executable, "-m", "so101_kinematics.sim.meshes", "--check"],
                            cwd=REPO, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "13 meshes verified" in result.stdout


def test_a_reinstall_never_rewrites_a_mesh_another_process_may_be_reading(asset_copy):
    # ./dev.sh installs the meshes on every call; in CI a second test leg does that while the
    # first one loads the model (a truncated-in-place copy was read as "STL file is empty").
    inodes = {path.name: path.stat().st_ino for path in asset_copy.glob("*.stl")}
    meshes.install_meshes(asset_copy)
    assert {path.name: path.stat().st_ino for path in asset_copy.glob("*.stl")} == inodes
    victim = asset_copy / sorted(meshes.read_manifest())[2]
    victim.write_bytes(b"not a mesh")
    with open(victim, "rb") as reader:  # a loader that opened the old file keeps reading it
        meshes.install_meshes(asset_copy)
        assert reader.read() == b"not a mesh"
    assert meshes.sha256_of(victim) == meshes.read_manifest()[victim.name]
    assert not list(asset_copy.glob(".*partial"))
