"""The warm start (ours): a SLAM mesh's faces decoupled into independent, scaled triangles.

Also the two preparations of the warm-start mesh that keep training within a CPU budget and fill
what a level-mounted LiDAR never sees: quadric simplification to a face budget, and a ground
fill — the floor plane, fitted to the mesh, extended under the pixels of the training views that
see no warm-start surface (a 360° LiDAR mounted level at robot height never sees the floor within a
few metres, which the camera looks at all the time) and completed where the room encloses it out
of every camera's sight (:mod:`splat.floor_cells`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.camera import CameraModel
from rig.mesh_rays import cast_camera_rays, mesh_raycaster
from rig.plane_fit import ransac_plane
from splat.floor_cells import (
    GROUND_BAND_M,
    NEAR_FLOOR_M,
    PlaneGrid,
    ReturnColumns,
    enclosed_hidden_cells,
    range_scaled_cells,
)

#: The ground fill's note where the scene has no floor plane.
NO_FLOOR = "no floor plane in the warm-start mesh; ground fill skipped"


def decouple_and_scale(vertices: np.ndarray, faces: np.ndarray, scale: float = 2.0) -> np.ndarray:
    """Independent triangles ``(F, 3, 3)`` from a mesh (``(V, 3)``, ``(F, 3)``), each scaled about
    its centroid ``g``: ``v' = g + scale (v - g)`` (centroids kept, areas × scale²)."""
    triangles = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    centroid = triangles.mean(axis=1, keepdims=True)
    return centroid + scale * (triangles - centroid)


#: open3d's quadric decimation slows down far more than linearly on some meshes of millions of
#: faces (the 4 M-face ground truth of ``lts sim --preset floor``: over 25 min; 3.5 M faces of it:
#: 70 s; a 1.8 M-face block of it: over 2 min). A mesh of more than this many times the faces
#: wanted is first brought down by vertex clustering (linear) to :data:`CLUSTER_TO` times them.
CLUSTER_ABOVE = 20
CLUSTER_TO = 10


def simplify(mesh: trimesh.Trimesh, max_faces: int) -> trimesh.Trimesh:
    """The mesh with at most ``max_faces`` faces (open3d quadric decimation, after vertex clustering
    above :data:`CLUSTER_ABOVE` times ``max_faces``; unchanged if smaller)."""
    if len(mesh.faces) <= max_faces:
        return mesh
    from rig.open3d_lite import o3d

    legacy = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(mesh.vertices, dtype=np.float64)),
        o3d.utility.Vector3iVector(np.asarray(mesh.faces, dtype=np.int32)),
    )
    if len(mesh.faces) > CLUSTER_ABOVE * max_faces:
        # A surface of area A in cells of side v has about 2 A / v^2 triangles.
        voxel = float(np.sqrt(2.0 * mesh.area / (CLUSTER_TO * max_faces)))
        legacy = legacy.simplify_vertex_clustering(voxel, o3d.geometry.SimplificationContraction.Quadric)
        # Clustering leaves repeated and non-manifold faces, which stop quadric decimation early.
        legacy.remove_degenerate_triangles()
        legacy.remove_duplicated_triangles()
        legacy.remove_duplicated_vertices()
        legacy.remove_non_manifold_edges()
    small = legacy.simplify_quadric_decimation(target_number_of_triangles=int(max_faces))
    small.remove_degenerate_triangles()
    small.remove_unreferenced_vertices()
    return trimesh.Trimesh(np.asarray(small.vertices), np.asarray(small.triangles), process=False)


@dataclass(frozen=True)
class GroundFill:
    """Floor triangles added to a warm start, and why there are none when there are none.

    Attributes:
        triangles: ``(G, 3, 3)`` world-frame floor triangles the cameras see (two per grid cell),
            and upright patches where the LiDAR returns close a hole the cameras see through.
        hidden: ``(H, 3, 3)`` floor triangles no camera sees, completed where the room encloses
            them (:func:`splat.floor_cells.enclosed_hidden_cells`).
        plane: ``(4,)`` ``n·x + d = 0`` with ``n`` pointing up, or None when no floor was found.
        reason: a one-line account (cells added, or why nothing was).
    """

    triangles: np.ndarray
    hidden: np.ndarray
    plane: np.ndarray | None
    reason: str


def up_direction(poses_world_cam: np.ndarray) -> np.ndarray:
    """Approximate world up ``(3,)``: minus the mean camera y axis (OpenCV y points down); off by
    the cameras' mean pitch, hence the generous tilt tolerance of the floor search."""
    down = poses_world_cam[:, :3, 1].mean(axis=0)
    return -down / np.linalg.norm(down)


def _level_points(
    points: np.ndarray, up: np.ndarray, max_tilt_deg: float, neighbours: int = 16
) -> np.ndarray:
    """The points ``(N, 3)`` whose local surface (the plane of their ``neighbours`` nearest) is
    within ``max_tilt_deg`` of level: floor and tops, not walls. A level LiDAR's lowest beam draws
    a ring at one height on every wall round it, which a plane fit alone takes for a floor."""
    from rig.open3d_lite import o3d

    if len(points) < neighbours:
        return points
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(neighbours))
    return points[np.abs(np.asarray(cloud.normals) @ up) > np.cos(np.radians(max_tilt_deg))]


def fit_floor_plane(
    mesh: trimesh.Trimesh,
    poses_world_cam: np.ndarray,
    lidar: np.ndarray | None = None,
    max_tilt_deg: float = 30.0,
    min_faces: int = 30,
) -> np.ndarray | None:
    """The floor ``(4,)`` (unit normal up, ``n·x + d = 0``), or None when fewer than ``min_faces``
    faces (ten times as many LiDAR points) support it: a RANSAC plane within ``max_tilt_deg`` of
    level through the LiDAR points ``(N, 3)`` below every camera on level surfaces (by their
    neighbours' plane) when there are enough of them,
    else through the centroids of the mesh's up-facing faces below every camera. The returns come
    first: a TSDF surface seen at grazing angles sits centimetres off the floor, and a warm start's
    floor simplified to a few faces tilts by degrees (3° on a 3 s recording: 17 cm of floor
    below the truth under its first camera)."""
    up = up_direction(poses_world_cam)
    lowest_camera = float((poses_world_cam[:, :3, 3] @ up).min())
    level = (up, max_tilt_deg)
    plane, support = np.zeros(4), 0
    if lidar is not None:
        candidates = _level_points(lidar[lidar @ up < lowest_camera - 0.1], up, max_tilt_deg)
        if len(candidates) >= 10 * min_faces:  # points, noisier than faces
            plane, inliers = ransac_plane(candidates, 0.03, normal_near=level)
            support = len(inliers) // 10
    if support < min_faces:
        # Faces are oriented towards the trajectory, so the floor's faces point up; TSDF back
        # faces below the floor point down and are left out.
        facing_up = np.asarray(mesh.face_normals) @ up > np.cos(np.radians(max_tilt_deg))
        centroids = np.asarray(mesh.triangles_center)
        candidates = centroids[facing_up & (centroids @ up < lowest_camera - 0.1)]
        if len(candidates) < min_faces:
            return None
        plane, inliers = ransac_plane(candidates, 0.03, normal_near=level)
        support = len(inliers)
    if support < min_faces:
        return None
    return plane if plane[:3] @ up > 0 else -plane


def _behind_wall(scene, origin: np.ndarray, points: np.ndarray, up: np.ndarray, margin: float) -> np.ndarray:
    """``(N,)`` True where a level ray at the camera's height towards the point above each floor
    point ``(N, 3)`` hits the mesh first: the floor there lies beyond a wall (seen through a hole
    in it), not in the room."""
    from rig.open3d_lite import o3d

    above = points + np.outer((origin - points) @ up, up)
    offset = above - origin
    distance = np.linalg.norm(offset, axis=1)
    direction = offset / np.maximum(distance, 1e-9)[:, None]
    rays = np.hstack([np.broadcast_to(origin, direction.shape), direction]).astype(np.float32)
    t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    return t_hit < distance - margin


def ground_fill(
    mesh: trimesh.Trimesh,
    camera: CameraModel,
    poses_world_cam: np.ndarray,
    lidar: np.ndarray | None = None,
    cell_m: float = 0.15,
    max_range_m: float = NEAR_FLOOR_M,
    pixel_stride: int = 4,
    complete_hidden: bool = True,
    closing_m: float = 0.6,
    enclosing: trimesh.Trimesh | None = None,
    plane: np.ndarray | None = None,
) -> GroundFill:
    """The floor the warm-start mesh lacks: cells the cameras see through its holes, and hidden
    cells the room encloses.

    Rays of every ``pixel_stride``-th pixel of each view (``poses_world_cam`` ``(K, 4, 4)``) that
    hit no warm-start face before the floor plane are intersected with it (within
    ``max_range_m``, or as far as the LiDAR returns on the floor reach), unless a wall stands
    between the camera and the point; each grid cell they land in becomes two triangles: cells of
    ``cell_m`` within ``max_range_m`` and coarser beyond (:func:`range_scaled_cells`). A street's
    road beyond 40 m lies between the rings of a spinning LiDAR, too far apart for the warm
    start's surface to bridge. Where the wall between is in the LiDAR returns
    only (a hole of the mesh), an upright ``cell_m`` square closes the hole where the sight line
    meets the returns. ``lidar`` ``(N, 3)``: the returns the plane is fitted to and the walls are
    found in (without them, the mesh's faces alone). With ``complete_hidden``, the floor no camera
    sees and the LiDAR does not reach is completed where the room encloses it (gaps up to
    ``2 * closing_m`` bridged), within ``max_range_m`` of a camera along the floor, by the walls
    and objects of ``enclosing`` (default ``mesh``: pass the warm start before it was simplified,
    whose thin stretches of wall a simplification breaks up). ``plane`` ``(4,)``: the floor when
    the caller has fitted it already (default: :func:`fit_floor_plane` of ``mesh`` and ``lidar``).
    """
    empty = np.zeros((0, 3, 3))
    if plane is None:
        plane = fit_floor_plane(mesh, poses_world_cam, lidar)
    if plane is None:
        return GroundFill(empty, empty, None, NO_FLOOR)
    scene = mesh_raycaster(mesh)
    ys, xs = np.mgrid[0 : camera.height : pixel_stride, 0 : camera.width : pixel_stride]
    pixels = np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float64)
    rays_cam = camera.unproject(pixels, 1.0)
    rays_cam /= np.linalg.norm(rays_cam, axis=1, keepdims=True)
    n, d = plane[:3], plane[3]
    grid = PlaneGrid(plane, cell_m)
    columns = ReturnColumns(grid, lidar) if lidar is not None else None
    reach = max(max_range_m, floor_reach(grid, lidar, poses_world_cam[:, :3, 3]))
    hits, ranges, crossings, cameras = [], [], [], []
    for pose in poses_world_cam:
        origin = pose[:3, 3]
        dirs = rays_cam @ pose[:3, :3].T
        t_mesh = cast_camera_rays(scene, pose, rays_cam)["t_hit"]
        denom = dirs @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t_floor = -(origin @ n + d) / denom
        through_hole = (denom < -1e-3) & (t_floor > 0) & (t_floor < reach) & (t_mesh > t_floor + cell_m)
        points, t = origin + t_floor[through_hole, None] * dirs[through_hole], t_floor[through_hole]
        behind = _behind_wall(scene, origin, points, n, cell_m)
        if columns is not None:
            crossed, at = columns.first_crossing(origin, points, cell_m)
            behind |= crossed
            walled = crossed & (t < max_range_m)  # far, a column of returns is a pole or a trunk
            crossings.append(at[walled])
            cameras.append(np.broadcast_to(origin, at[walled].shape))
        hits.append(points[~behind])
        ranges.append(t[~behind])
    points = np.concatenate(hits) if hits else np.zeros((0, 3))
    ranges = np.concatenate(ranges) if ranges else np.zeros(0)
    walls = _wall_patches(grid, np.concatenate(crossings), np.concatenate(cameras)) if crossings else empty
    far = ranges >= max_range_m
    seen = np.unique(grid.cells(points[~far]), axis=0) if (~far).any() else np.zeros((0, 2), dtype=np.int64)
    coarse = range_scaled_cells(plane, cell_m, max_range_m, points[far], ranges[far])
    hidden = seen[:0]
    if complete_hidden:
        enclosing = mesh if enclosing is None else enclosing
        hidden = enclosed_hidden_cells(enclosing, grid, seen, closing_m, lidar=lidar)
    hidden = hidden[grid.near(hidden, poses_world_cam[:, :3, 3], max_range_m)]
    reason = (
        f"{len(seen)} floor cells of {cell_m:g} m added under mesh holes the cameras see through"
        if len(seen) or len(coarse)
        else "the warm-start mesh covers the floor the cameras see"
    )
    if len(coarse):
        reason += f", and {len(coarse) // 2} coarser ones beyond {max_range_m:g} m (to {reach:.0f} m)"
    if len(walls):
        reason += f"; {len(walls) // 2} upright {cell_m:g} m patches where LiDAR returns close those holes"
    if complete_hidden:
        reason += f"; {len(hidden)} hidden floor cells completed where walls and objects enclose them"
    floor = np.concatenate([grid.triangles(seen), coarse, walls])
    return GroundFill(floor, grid.triangles(hidden), plane, reason)


def floor_reach(grid: PlaneGrid, lidar: np.ndarray | None, cameras: np.ndarray) -> float:
    """How far (m) from the nearest camera ``(K, 3)`` the LiDAR returns ``(N, 3)`` on the floor
    (within :data:`~splat.floor_cells.GROUND_BAND_M` of ``grid``'s plane) reach; 0 without returns."""
    if lidar is None:
        return 0.0
    on_floor = lidar[np.abs(grid.heights(lidar)) < GROUND_BAND_M]
    if len(on_floor) == 0:
        return 0.0
    return float(cKDTree(cameras).query(on_floor)[0].max())


def _wall_patches(grid: PlaneGrid, crossings: np.ndarray, cameras: np.ndarray) -> np.ndarray:
    """Upright squares ``(2W, 3, 3)``, one per ``grid.cell_m`` cube that sight lines through the
    warm start's holes cross a column of LiDAR returns in (``crossings`` ``(N, 3)``, seen from
    ``cameras`` ``(N, 3)``): the wall the camera sees there, facing the first camera that does."""
    if len(crossings) == 0:
        return np.zeros((0, 3, 3))
    cube = np.column_stack([grid.cells(crossings), np.floor(grid.heights(crossings) / grid.cell_m)])
    _, first = np.unique(cube.astype(np.int64), axis=0, return_index=True)
    return grid.upright_squares(crossings[first], cameras[first])
