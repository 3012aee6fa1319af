from pathlib import Path

import numpy as np
import pytest
import trimesh

from rig import InputError
from rig.mesh_io import load_mesh


def test_load_mesh_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such mesh file"):
        load_mesh(tmp_path / "missing.ply")
    empty = tmp_path / "points.ply"
    trimesh.PointCloud(np.random.default_rng(0).normal(size=(10, 3))).export(empty)
    with pytest.raises(InputError, match="no faces"):
        load_mesh(empty)
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nend_header\n\x00\x01")
    with pytest.raises(InputError):
        load_mesh(garbage)
    notes = tmp_path / "notes.txt"
    notes.write_text("not a mesh")
    with pytest.raises(InputError, match=r"\.txt: not a mesh file type \(expected \.ply, \.obj"):
        load_mesh(notes)


def test_face_indexing_a_missing_vertex_is_named(tmp_path: Path) -> None:
    path = tmp_path / "bad.ply"
    header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    header += "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    path.write_text(header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(InputError) as info:
        load_mesh(path)
    assert str(info.value).startswith(f"{path}: ")
