"""splat.export: render mesh files, the welded collision mesh, and that a physics engine stands on it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from rig.errors import InputError
from splat.export import export_mesh
from splat.model import TriangleModel

GRID = 4  # cells per side: (GRID + 1)² = 25 shared corners, 2 GRID² = 32 triangles
CELL_M = 0.5
N_GRID = 2 * GRID * GRID


def grid_triangles(rng: np.random.Generator, jitter_m: float) -> np.ndarray:
    """``(32, 3, 3)`` independent triangles tiling a 2 m square at z = 0, corners jittered in x, y."""
    corners = []
    for i in range(GRID):
        for j in range(GRID):
            a, b, c, d = (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)
            corners += [(a, b, c), (a, c, d)]
    tri = np.zeros((N_GRID, 3, 3))
    tri[..., :2] = np.array(corners, dtype=float) * CELL_M
    tri[..., :2] += rng.uniform(-jitter_m, jitter_m, size=(N_GRID, 3, 2))
    return tri


def scene(jitter_m: float = 2e-4) -> tuple[TriangleModel, torch.Tensor, np.ndarray]:
    """A model of 32 opaque, seen grid triangles plus 2 exact duplicates, 3 transparent, 2 unseen and
    1 collinear triangle, its ``seen`` mask and its per-vertex colours ``(40, 3, 3)`` (multiples of
    1/255, so they survive the uint8 round trip exactly)."""
    rng = np.random.default_rng(0)
    grid = grid_triangles(rng, jitter_m)
    duplicates = grid[[3, 7]]
    elsewhere = grid[:5] + np.array([0.0, 0.0, 1.0])  # above the grid: transparent or unseen
    collinear = np.array([[[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [2.0, 0.0, 2.0]]])
    triangles = np.concatenate([grid, duplicates, elsewhere, collinear])
    n = len(triangles)
    opacity = np.full(n, 0.99)
    opacity[34:37] = 0.1
    seen = torch.ones(n, dtype=torch.bool)
    seen[37:39] = False
    colors = rng.integers(0, 256, size=(n, 3, 3)) / 255.0
    model = TriangleModel.from_triangles(
        torch.from_numpy(triangles), torch.from_numpy(colors), torch.from_numpy(opacity)
    )
    return model, seen, colors


def load(path: Path) -> trimesh.Trimesh:
    return trimesh.load(path, force="mesh", process=False)


def test_render_files_hold_every_triangle_with_its_colours(tmp_path: Path) -> None:
    model, seen, colors = scene()
    result = export_mesh(model, tmp_path, seen=seen)
    expected_rgb = np.round(colors.reshape(-1, 3) * 255).astype(np.uint8)
    assert result.n_triangles == 40
    for name in ("mesh.ply", "mesh.obj", "mesh.glb"):
        mesh = load(tmp_path / name)
        assert len(mesh.faces) == 40, name
        assert len(mesh.vertices) == 120, name  # independent triangles: never welded
        corners = np.asarray(mesh.vertices)[mesh.faces].reshape(-1, 3)
        np.testing.assert_allclose(corners, model.params["vertices"].detach().reshape(-1, 3), atol=1e-6)
        rgb = np.asarray(mesh.visual.vertex_colors)[mesh.faces].reshape(-1, 4)[:, :3]
        np.testing.assert_array_equal(rgb, expected_rgb, err_msg=name)
    assert b"format binary_little_endian" in (tmp_path / "mesh.ply").read_bytes()[:200]
    assert not list(tmp_path.glob("*.tmp"))


def test_collision_mesh_is_filtered_and_welded(tmp_path: Path) -> None:
    model, seen, _ = scene()
    result = export_mesh(model, tmp_path, seen=seen)
    assert result.n_removed_transparent == 3
    assert result.n_removed_unseen == 2
    assert result.n_removed_degenerate == 1
    assert result.n_removed_duplicate == 2
    assert result.n_collision_triangles == N_GRID
    assert result.n_collision_vertices == (GRID + 1) ** 2  # 96 jittered corners welded to 25
    for name in ("collision.ply", "collision.obj"):
        mesh = load(tmp_path / name)
        assert (len(mesh.faces), len(mesh.vertices)) == (N_GRID, (GRID + 1) ** 2), name
        assert mesh.is_winding_consistent and len(mesh.split(only_watertight=False)) == 1, name
        assert mesh.area == pytest.approx((GRID * CELL_M) ** 2, rel=1e-3), name


def test_camera_only_triangles_are_flagged_in_the_render_mesh(tmp_path: Path) -> None:
    model, seen, _ = scene()
    camera_only = np.zeros(model.n_triangles, dtype=bool)
    camera_only[8:13] = True
    result = export_mesh(model, tmp_path, seen=seen, camera_only=camera_only)
    assert result.n_collision_triangles == N_GRID
    assert len(load(tmp_path / "mesh.ply").faces) == 40
    raw = trimesh.load(tmp_path / "mesh.ply", process=False).metadata["_ply_raw"]["face"]["data"]
    np.testing.assert_array_equal(raw["camera_only"], camera_only.astype(np.uint8))
    with pytest.raises(InputError, match="flags"):
        export_mesh(model, tmp_path, seen=seen, camera_only=camera_only[:3])


def test_floor_no_view_sees_stays_in_the_collision_mesh(tmp_path: Path) -> None:
    """Grid triangles flagged as floor are kept though unseen (the completed floor); an unseen
    triangle off the floor is still left out."""
    model, seen, _ = scene()
    seen[8:12] = False  # four grid triangles no view saw (no duplicates among them)
    floor = np.zeros(model.n_triangles, dtype=bool)
    floor[8:12] = True
    result = export_mesh(model, tmp_path, seen=seen, floor=floor)
    assert result.n_kept_unseen_floor == 4
    assert result.n_removed_unseen == 2  # the two above the grid
    assert result.n_collision_triangles == N_GRID
    without = export_mesh(model, tmp_path / "without", seen=seen)
    assert without.n_collision_triangles == N_GRID - 4 and without.n_kept_unseen_floor == 0
    with pytest.raises(InputError, match="flags"):
        export_mesh(model, tmp_path, seen=seen, floor=floor[:3])


def test_weld_distance_is_respected(tmp_path: Path) -> None:
    """Corners jittered by up to 2 mm (pairs up to ~5.7 mm apart) stay apart at a 0.1 mm weld."""
    model, seen, _ = scene(jitter_m=2e-3)
    result = export_mesh(model, tmp_path, seen=seen, weld_m=1e-4)
    assert result.n_collision_vertices == 3 * N_GRID
    assert result.n_removed_duplicate == 2  # exact duplicates still share their corners


def test_without_seen_mask_unseen_triangles_are_kept(tmp_path: Path) -> None:
    model, _, _ = scene()
    result = export_mesh(model, tmp_path)
    assert result.n_removed_unseen == 0
    assert result.n_collision_triangles == N_GRID + 2


def test_nothing_left_for_collision_is_an_error(tmp_path: Path) -> None:
    model, seen, _ = scene()
    with pytest.raises(InputError, match="no triangle is left") as err:
        export_mesh(model, tmp_path, seen=torch.zeros_like(seen))
    assert err.value.path == str(tmp_path / "collision.ply")
    assert not any(tmp_path.iterdir())  # nothing half-written


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"seen": torch.ones(3, dtype=torch.bool)}, "seen"),
        ({"seen": torch.ones(40)}, "seen"),
        ({"min_opacity": 1.5}, "min_opacity"),
        ({"weld_m": -1.0}, "weld_m"),
    ],
)
def test_bad_arguments_name_the_field(tmp_path: Path, kwargs: dict, field: str) -> None:
    model, _, _ = scene()
    with pytest.raises(InputError) as err:
        export_mesh(model, tmp_path, **kwargs)
    assert err.value.field == field


def test_sphere_rests_on_collision_mesh_in_pybullet(tmp_path: Path) -> None:
    p = pytest.importorskip("pybullet")
    model, seen, _ = scene()
    export_mesh(model, tmp_path, seen=seen)
    client = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=client)
        ground = p.createCollisionShape(
            p.GEOM_MESH,
            fileName=str(tmp_path / "collision.obj"),
            flags=p.GEOM_FORCE_CONCAVE_TRIMESH,
            physicsClientId=client,
        )
        assert ground >= 0
        p.createMultiBody(0, ground, physicsClientId=client)
        radius = 0.1
        ball = p.createCollisionShape(p.GEOM_SPHERE, radius=radius, physicsClientId=client)
        body = p.createMultiBody(1.0, ball, basePosition=[1.1, 0.9, 0.5], physicsClientId=client)
        for _ in range(480):  # 2 s at the default 240 Hz
            p.stepSimulation(physicsClientId=client)
        (x, y, z), _ = p.getBasePositionAndOrientation(body, physicsClientId=client)
        velocity, _ = p.getBaseVelocity(body, physicsClientId=client)
    finally:
        p.disconnect(client)
    assert z == pytest.approx(radius, abs=5e-3)
    assert (x, y) == pytest.approx((1.1, 0.9), abs=1e-2)
    assert np.linalg.norm(velocity) < 1e-2
