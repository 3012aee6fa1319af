"""The built-in mapper for sessions that come without SLAM output.

LiDAR odometry (scan-to-map VGICP, :class:`rig.lidar_odometry.SweepOdometry`) on the raw sweeps,
each pose stamped at its sweep's information-weighted point time, then a coarse surface
by TSDF integration of the scans de-skewed with that trajectory (open3d). Open3D integrates depth
*images*, so each scan is z-buffered into the six faces of a cube map around the LiDAR and those
are integrated.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
import trimesh

from rig.deskew import deskewed_points
from rig.dynamic_points import DEFAULT_DYNAMIC, DynamicConfig, label_dynamic
from rig.errors import InputError
from rig.lidar_odometry import (
    MAP_VOXELS_PER_VOXEL,
    SweepOdometry,
    nearest_rotation,
    usable_sweep,
    voxel_for_ranges,
)
from rig.messages import Scan
from rig.trajectory import Trajectory
from rig.transforms import invert, make_transform, transform_points
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
class MapperConfig:
    """Settings of the fallback mapper.

    Attributes:
        voxel_size_m: the odometry's voxel size; None picks it from the ranges (:func:`odometry_voxel`).
        tsdf_voxel_m: TSDF voxel size (the mesh resolution); None picks it from the ranges
            (:func:`tsdf_voxel`).
        face_resolution_px: pixels across each 90° cube-map face (angular resolution of integration).
        min_range_m, max_range_m: points outside are ignored.
        min_weight: voxels observed fewer times are left out of the mesh (removes one-off noise).
        dynamic: the see-through test that keeps moving objects out of the mesh (None: off).
        max_points_per_sweep: larger sweeps are thinned (:func:`~rig.lidar_odometry.thinned`)
            before anything else:
            every step costs in proportion to the points, and a 64-beam sweep has 4 to 5 times
            more than its registration and see-through test need. It costs the mesh detail: on 78
            sweeps of the virtual street with the HDL-64E's 125k points, the mapper takes 4.6 /
            7.9 / 11.5 s with 32k / 64k / all points, ATE 0.93 / 0.83 / 0.78 cm, and 56 / 69 /
            72 % of the mesh lies within 5 cm of the truth (85–88 % within 10 cm with any).
    """

    voxel_size_m: float | None = None
    tsdf_voxel_m: float | None = None
    face_resolution_px: int = 64
    min_range_m: float = 0.2
    max_range_m: float = 60.0
    min_weight: float = 3.0
    dynamic: DynamicConfig | None = DEFAULT_DYNAMIC
    max_points_per_sweep: int = 32_000


@dataclass
class MapperResult:
    """The trajectory, the TSDF mesh, how many sweeps went in, the verdict on the trajectory (with
    the fraction of points judged moving, left out of the mesh) and the settings used."""

    trajectory: Trajectory
    mesh: trimesh.Trimesh
    scans_used: int
    quality: MappingQuality
    settings: dict[str, float | int | bool]


def odometry_voxel(ranges: np.ndarray, config: MapperConfig) -> float:
    """The odometry's voxel size (each sweep is downsampled to it) for sweeps whose first usable
    ranges are ``ranges`` ``(N,)`` (m): ``config.voxel_size_m``, else
    :func:`~rig.lidar_odometry.voxel_for_ranges`."""
    if config.voxel_size_m is not None:
        return config.voxel_size_m
    return voxel_for_ranges(ranges)


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
        self.config = config
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
    scans' host clock when each holds (:func:`~rig.lidar_odometry.sweep_information`). A scan is
    de-skewed once the next one's pose is known (with the poses before, at and after it) and its
    moving points are found once the sweeps it is compared with are in
    (:func:`~rig.dynamic_points.label_dynamic`). Its static points are then registered
    again, by a second odometry that never sees a moving point, and integrated at that pose; the
    difference between the two trajectories goes into the :class:`MappingQuality`.
    """
    tsdf: _TsdfIntegrator | None = None  # made once the first sweep has set its voxel size
    log = _OdometryLog()
    static_odometry: SweepOdometry | None = None
    static_poses: list[np.ndarray] = []
    counts = {"points": 0, "dynamic": 0}
    for _, view, dynamic in label_dynamic(_deskewed_sweeps(scans, config, log, progress), config.dynamic):
        counts["points"] += len(dynamic)
        counts["dynamic"] += int(dynamic.sum())
        pose = view.T_world_sensor
        sensor = transform_points(invert(pose), view.points_world)
        static = sensor[~dynamic]
        if config.dynamic is not None:
            if static_odometry is None:
                static_odometry = SweepOdometry(log.voxel_m, config.max_range_m, config.min_range_m)
            pose = static_odometry.register_rigid(static if len(static) >= 100 else sensor)
        static_poses.append(pose)
        tsdf = tsdf or _TsdfIntegrator(config, log.tsdf_voxel_m)
        tsdf.integrate(static, pose)
    if tsdf is None or len(log.poses) < 2:
        raise InputError(
            f"only {len(log.poses)} usable LiDAR scans; the mapper needs at least 2", field="scans"
        )
    poses = np.stack(static_poses)
    trajectory = Trajectory.from_poses(np.array(log.t_ns, dtype=np.int64), poses)
    dynamic_fraction = counts["dynamic"] / max(counts["points"], 1)
    written = static_odometry or log.odometry  # the registration whose poses are written
    quality = judge_mapping(
        np.stack(log.poses)[:, :3, 3], poses[:, :3, 3], dynamic_fraction, np.array(log.weakest_information),
        np.einsum("nij,nj->ni", poses[:, :3, :3], np.array(log.weakest_direction)),
        np.array(written.corrections_m), np.array(written.inlier_fractions),
    )  # fmt: skip
    settings = {
        "voxel_m": log.voxel_m, "map_voxel_m": MAP_VOXELS_PER_VOXEL * log.voxel_m,
        "max_range_m": config.max_range_m, "tsdf_voxel_m": log.tsdf_voxel_m,
        "static_reregistration": config.dynamic is not None,
    }  # fmt: skip
    return MapperResult(trajectory, tsdf.mesh(), len(poses), quality, settings)


@dataclass
class _OdometryLog:
    """Per registered sweep: its stamp (ns), pose, smallest translation information and its
    direction (sensor frame); the voxel sizes chosen (odometry, TSDF) and the odometry."""

    voxel_m: float = 0.0
    tsdf_voxel_m: float = 0.0
    odometry: SweepOdometry | None = None
    t_ns: list[int] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    weakest_information: list[float] = field(default_factory=list)
    weakest_direction: list[np.ndarray] = field(default_factory=list)


def _deskewed_sweeps(
    scans: Iterable[Scan],
    config: MapperConfig,
    log: _OdometryLog,
    progress: Callable[[int], None] | None,
) -> Iterator[tuple[float, np.ndarray, np.ndarray]]:
    """Register each usable scan (recording it in ``log``) and yield the one before it de-skewed:
    ``(t_s, points (N, 3) in the sensor frame, T_world_sensor)``."""
    pending: tuple[np.ndarray, np.ndarray] | None = None  # the last scan's points and their times (ns)
    t_ns, poses = log.t_ns, log.poses

    def deskew_pending(pose_index: int) -> tuple[float, np.ndarray, np.ndarray]:
        recent = extended_at_both_ends(np.array(t_ns[-3:], dtype=np.int64), np.stack(poses[-3:]))
        points, point_t_ns = pending
        pose = poses[pose_index]
        return (
            t_ns[pose_index] * 1e-9,
            transform_points(invert(pose), deskewed_points(points, point_t_ns, recent)),
            pose,
        )

    for index, scan in enumerate(scans):
        sweep = usable_sweep(
            scan.points,
            scan.point_time_s,
            config.max_points_per_sweep,
            config.min_range_m,
            config.max_range_m,
        )
        if sweep is None:
            continue
        points, times, ranges = sweep
        if log.odometry is None:
            log.voxel_m = odometry_voxel(ranges, config)
            log.tsdf_voxel_m = tsdf_voxel(ranges, config)
            log.odometry = SweepOdometry(log.voxel_m, config.max_range_m, config.min_range_m)
        pose, information = log.odometry.register(points, times)
        t_ns.append(int(scan.t_host) + round(information.held_s * 1e9))
        poses.append(pose)
        log.weakest_information.append(float(information.translation_information[0]))
        log.weakest_direction.append(information.weakest_direction)
        if pending is not None:
            yield deskew_pending(-2)
        pending = (points, int(scan.t_host) + np.round(times * 1e9).astype(np.int64))
        if progress is not None:
            progress(index)
    if len(poses) >= 2:
        yield deskew_pending(-1)


def extended_at_both_ends(t_ns: np.ndarray, poses: np.ndarray) -> Trajectory:
    """The trajectory of poses ``(K, 4, 4)`` at ``t_ns`` ``(K,)`` (K ≥ 2) with one more pose at each
    end, the motion of the end pair repeated: the first and last sweeps reach beyond the poses
    around them, and holding the end pose there left them half de-skewed (at 3 m/s the second
    registration's first step came out 7 cm short, as its map began with that sweep)."""
    before = nearest_rotation(poses[0] @ invert(poses[1]) @ poses[0])
    after = nearest_rotation(poses[-1] @ invert(poses[-2]) @ poses[-1])
    times = np.concatenate([[2 * t_ns[0] - t_ns[1]], t_ns, [2 * t_ns[-1] - t_ns[-2]]])
    return Trajectory.from_poses(times.astype(np.int64), np.concatenate([[before], poses, [after]]))


def world_points(scan_points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Scan points ``(N, 3)`` in the world frame given the scan's pose ``(4, 4)``."""
    return transform_points(pose, scan_points)
