"""The built-in mapper for sessions that come without SLAM output.

LiDAR odometry on the sweeps, registered twice (:mod:`rig.sweep_registration`: scan-to-map VGICP
on the raw sweeps, then on the de-skewed static points), then a coarse surface by TSDF
integration of the de-skewed static points at their poses (open3d). Open3D integrates depth
*images*, so each scan is z-buffered into the six faces of a cube map around the LiDAR and those
are integrated.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import trimesh

from rig.errors import InputError
from rig.lidar_odometry import MAP_VOXELS_PER_VOXEL
from rig.messages import Scan
from rig.sweep_registration import RegistrationLog, SweepSettings, registered_sweeps
from rig.trajectory import Trajectory
from rig.transforms import invert, make_transform
from slam_bridge.mapping_quality import MappingQuality, judge_mapping

# Rotations R_face_sensor of the six cube-map cameras: rows are the camera's x (right), y (down) and
# z (forward) axes in the sensor frame.
_CUBE_FACES = [
    np.array([[0, -1, 0], [0, 0, -1], [1, 0, 0]]),  # looking along +x
    np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]]),  # -x
    np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]),  # +y
    np.array([[-1, 0, 0], [0, 0, -1], [0, -1, 0]]),  # -y
    np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]]),  # +z
    np.array([[0, -1, 0], [-1, 0, 0], [0, 0, -1]]),  # -z
]


#: The TSDF voxel as a fraction of the same range, never below MIN_TSDF_VOXEL_M (the rooms' value).
#: A voxel much smaller than the spacing of a spinning LiDAR's rings at range leaves the mesh in
#: stripes: on the 64-beam street (95th percentile 22 m) 0.04 m voxels cover 17 % of the test
#: views' LiDAR pixels and 267 m² in all (91 % within 10 cm of the truth); 0.15 m covers 67 % and
#: 1424 m² (88 %); 0.2 m 71 %, 1609 m² (85 %). 1/150 gives 0.143 m there, 0.0405 m in the room
#: (95th percentile 6.07 m) and 0.04 m in the corridor.
TSDF_VOXEL_PER_RANGE = 1 / 150
MIN_TSDF_VOXEL_M = 0.04


@dataclass(frozen=True)
class MapperConfig(SweepSettings):
    """Settings of the fallback mapper: those of its registration
    (:class:`~rig.sweep_registration.SweepSettings`; its ``dynamic`` test also keeps moving
    objects out of the mesh), and

    Attributes:
        tsdf_voxel_m: TSDF voxel size (the mesh resolution); None picks it from the ranges
            (:func:`tsdf_voxel`).
        face_resolution_px: pixels across each 90° cube-map face (angular resolution of integration).
        min_weight: voxels observed fewer times are left out of the mesh (removes one-off noise).
    """

    tsdf_voxel_m: float | None = None
    face_resolution_px: int = 64
    min_weight: float = 3.0


@dataclass
class MapperResult:
    """The trajectory, the TSDF mesh, how many sweeps went in, the verdict on the trajectory (with
    the fraction of points judged moving, left out of the mesh) and the settings used."""

    trajectory: Trajectory
    mesh: trimesh.Trimesh
    scans_used: int
    quality: MappingQuality
    settings: dict[str, float | int | bool]


def tsdf_voxel(ranges: np.ndarray, config: MapperConfig) -> float:
    """The TSDF voxel size for sweeps whose first usable ranges are ``ranges`` ``(N,)`` (m):
    ``config.tsdf_voxel_m``, else :data:`TSDF_VOXEL_PER_RANGE` of their 95th percentile, at least
    :data:`MIN_TSDF_VOXEL_M`."""
    if config.tsdf_voxel_m is not None:
        return config.tsdf_voxel_m
    return max(MIN_TSDF_VOXEL_M, TSDF_VOXEL_PER_RANGE * float(np.percentile(ranges, 95)))


def cube_depth_images(points: np.ndarray, resolution: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Z-buffered depth images of points ``(N, 3)`` (sensor frame) on the six faces of a cube map.

    Returns:
        Per face: ``T_sensor_face`` ``(4, 4)`` and a depth image ``(R, R)`` float32 (0 = empty),
        for a pinhole camera with focal ``R / 2`` and principal point at the centre (90° field of view).
    """
    f = c = resolution / 2.0
    out = []
    for R in _CUBE_FACES:
        local = points @ R.T  # the points in the face camera's frame
        front = local[:, 2] > 1e-3
        z = local[front, 2]
        u = np.floor(f * local[front, 0] / z + c).astype(np.int64)
        v = np.floor(f * local[front, 1] / z + c).astype(np.int64)
        ok = (u >= 0) & (u < resolution) & (v >= 0) & (v < resolution)
        depth = np.full(resolution * resolution, np.inf)
        np.minimum.at(depth, v[ok] * resolution + u[ok], z[ok])
        depth[np.isinf(depth)] = 0.0
        out.append(
            (make_transform(R.T, np.zeros(3)), depth.reshape(resolution, resolution).astype(np.float32))
        )
    return out


class _TsdfIntegrator:
    """Open3D voxel-block-grid TSDF fed with cube-map depth images of each scan.

    Open3D's grid extracts meshes only when it also holds colour, so a constant colour is
    integrated alongside (the mesh is geometry only).
    """

    def __init__(self, config: MapperConfig, voxel_m: float) -> None:
        from rig.open3d_lite import o3d

        o3c = o3d.core
        self._o3d, self._o3c = o3d, o3c
        self.config, self.voxel_m = config, voxel_m
        res = config.face_resolution_px
        self.grid = o3d.t.geometry.VoxelBlockGrid(
            attr_names=("tsdf", "weight", "color"),
            attr_dtypes=(o3c.float32, o3c.float32, o3c.float32),
            attr_channels=((1), (1), (3)),
            voxel_size=voxel_m,
            block_resolution=8,
            block_count=50_000,
            device=o3c.Device("CPU:0"),
        )
        self.K = o3c.Tensor(
            [[res / 2, 0, res / 2 - 0.5], [0, res / 2, res / 2 - 0.5], [0, 0, 1]], dtype=o3c.float64
        )
        self.colour = o3d.t.geometry.Image(o3c.Tensor(np.zeros((res, res, 3), np.float32)))

    def integrate(self, points_sensor: np.ndarray, T_world_sensor: np.ndarray) -> None:
        o3d, o3c = self._o3d, self._o3c
        for T_sensor_face, depth in cube_depth_images(points_sensor, self.config.face_resolution_px):
            if not depth.any():
                continue
            image = o3d.t.geometry.Image(o3c.Tensor(fill_small_holes(depth)))
            extrinsic = o3c.Tensor(invert(T_world_sensor @ T_sensor_face))
            try:
                blocks = self.grid.compute_unique_block_coordinates(
                    image, self.K, extrinsic, 1.0, self.config.max_range_m, trunc_voxel_multiplier=3.0
                )
            except RuntimeError as exc:  # Open3D aborts when a face's few returns touch no block
                if "No block is touched" not in str(exc):
                    raise
                continue
            self.grid.integrate(
                blocks,
                image,
                self.colour,
                self.K,
                self.K,
                extrinsic,
                1.0,
                self.config.max_range_m,
                trunc_voxel_multiplier=3.0,
            )

    def mesh(self) -> trimesh.Trimesh:
        """The surface in canonical order (Open3D's hash map hands out blocks in a different order
        on every run: the same triangles, numbered differently)."""
        extracted = self.grid.extract_triangle_mesh(weight_threshold=self.config.min_weight)
        vertices = extracted.vertex.positions.numpy().astype(np.float64)
        faces = extracted.triangle.indices.numpy().astype(np.int64)
        return trimesh.Trimesh(*canonical_order(vertices, faces), process=False)


def canonical_order(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``vertices`` ``(V, 3)`` sorted by x, y, z and ``faces`` ``(F, 3)`` renumbered to match, each
    face turned to start at its smallest index (winding kept) and the faces sorted: one numbering
    for one surface, whatever order it was built in."""
    order = np.lexsort(vertices.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    faces = rank[faces]
    first = np.argmin(faces, axis=1)
    faces = np.take_along_axis(faces, (first[:, None] + np.arange(3)) % 3, axis=1)
    return vertices[order], faces[np.lexsort(faces.T[::-1])]


def fill_small_holes(depth: np.ndarray, agree: float = 0.05) -> np.ndarray:
    """Fill empty pixels ``(R, R)`` between two returns (along a row or column) that agree within
    ``agree`` (relative), so sparse scans still give voxels complete neighbourhoods; gaps at depth
    edges and larger gaps stay empty."""
    filled = depth.copy()
    for axis in (0, 1):
        before = np.roll(depth, 1, axis=axis)
        after = np.roll(depth, -1, axis=axis)
        both = (
            (filled == 0)
            & (before > 0)
            & (after > 0)
            & (np.abs(before - after) <= agree * np.maximum(before, after))
        )
        filled[both] = (0.5 * (before + after))[both]
    return filled


def run_mapper(
    scans: Iterable[Scan],
    config: MapperConfig = MapperConfig(),
    progress: Callable[[int], None] | None = None,
) -> MapperResult:
    """Odometry and a TSDF mesh from LiDAR scans (in time order).

    Poses are ``T_world_lidar`` with the world = the LiDAR frame of the first scan, stamped on the
    scans' host clock when each holds. Each sweep is registered twice
    (:func:`~rig.sweep_registration.registered_sweeps`: the second time de-skewed and without its
    moving points) and its static points integrated at the second pose; the difference between
    the two trajectories goes into the :class:`MappingQuality`.
    """
    tsdf: _TsdfIntegrator | None = None  # made once the first sweep has set its voxel size
    log = RegistrationLog()
    static_poses: list[np.ndarray] = []
    counts = {"points": 0, "dynamic": 0}
    for sweep in registered_sweeps(scans, config, log, progress):
        counts["points"] += len(sweep.dynamic)
        counts["dynamic"] += int(sweep.dynamic.sum())
        static_poses.append(sweep.pose)
        tsdf = tsdf or _TsdfIntegrator(config, tsdf_voxel(log.first_ranges, config))
        tsdf.integrate(sweep.points[~sweep.dynamic], sweep.pose)
    if tsdf is None or len(log.poses) < 2:
        raise InputError(
            f"only {len(log.poses)} usable LiDAR scans; the mapper needs at least 2", field="scans"
        )
    poses = np.stack(static_poses)
    trajectory = Trajectory.from_poses(np.array(log.t_ns, dtype=np.int64), poses)
    dynamic_fraction = counts["dynamic"] / max(counts["points"], 1)
    written = log.static_odometry or log.odometry  # the registration whose poses are written
    quality = judge_mapping(
        np.stack(log.poses)[:, :3, 3], poses[:, :3, 3], dynamic_fraction, np.array(log.weakest_information),
        np.einsum("nij,nj->ni", poses[:, :3, :3], np.array(log.weakest_direction)),
        np.array(written.corrections_m), np.array(written.inlier_fractions),
    )  # fmt: skip
    settings = {
        "voxel_m": log.voxel_m, "map_voxel_m": MAP_VOXELS_PER_VOXEL * log.voxel_m,
        "max_range_m": config.max_range_m, "tsdf_voxel_m": tsdf.voxel_m,
        "static_reregistration": config.dynamic is not None,
    }  # fmt: skip
    return MapperResult(trajectory, tsdf.mesh(), len(poses), quality, settings)
