"""The built-in mapper for sessions that come without SLAM output.

LiDAR odometry with KISS-ICP on the raw sweeps, each pose stamped at its sweep's
information-weighted point time (:func:`calib.motion.information_time`), then a coarse surface by
TSDF integration of the scans de-skewed with that trajectory (open3d). KISS-ICP's own de-skew
(the previous sweep's motion applied to this one) was left off: on the virtual rig's 20 s room,
whose robot pitches and rolls at 2–4 Hz, it left roll and pitch 0.40° / 0.32° rms off the truth;
without it 0.07° / 0.05° (yaw 0.15° → 0.12°). Open3D integrates depth *images*, so each scan is
z-buffered into the six faces of a cube map around the LiDAR and those are integrated.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import trimesh

from calib.motion import ODOMETRY_POINTS_PER_VOXEL, information_time
from rig.errors import InputError
from rig.messages import Scan
from rig.trajectory import Trajectory
from rig.transforms import invert, make_transform, transform_points

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


#: Point times are binned to this (ns) for de-skewing: turning at 0.5 rad/s moves a point 5 m away
#: by 2.5 mm in 1 ms.
_DESKEW_BIN_NS = 1_000_000


@dataclass(frozen=True)
class MapperConfig:
    """Settings of the fallback mapper.

    Attributes:
        voxel_size_m: KISS-ICP voxel size; None picks 1/30 of the median point range, at least 0.1 m
            (smaller voxels cost much more time for no accuracy gain indoors).
        tsdf_voxel_m: TSDF voxel size (the mesh resolution).
        face_resolution_px: pixels across each 90° cube-map face (angular resolution of integration).
        min_range_m, max_range_m: points outside are ignored.
        min_weight: voxels observed fewer times are left out of the mesh (removes one-off noise).
    """

    voxel_size_m: float | None = None
    tsdf_voxel_m: float = 0.04
    face_resolution_px: int = 64
    min_range_m: float = 0.2
    max_range_m: float = 60.0
    min_weight: float = 3.0


@dataclass
class MapperResult:
    trajectory: Trajectory
    mesh: trimesh.Trimesh
    scans_used: int


def _voxel_size(scan: Scan, config: MapperConfig) -> float:
    if config.voxel_size_m is not None:
        return config.voxel_size_m
    ranges = np.linalg.norm(scan.points, axis=1)
    return float(np.clip(np.median(ranges) / 30.0, 0.1, 1.0))


def _kiss_icp(voxel_size: float, config: MapperConfig):
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    kiss_config = KISSConfig()
    kiss_config.data.max_range = config.max_range_m
    kiss_config.data.min_range = config.min_range_m
    kiss_config.data.deskew = False
    kiss_config.mapping.voxel_size = voxel_size
    # As in calib.motion (room session, 0.1 m voxels): 5 instead of KISS-ICP's 20 points per voxel
    # took roll / pitch / yaw from 0.15 / 0.08 / 0.23° to 0.12 / 0.07 / 0.14° rms, ATE 1.04 to
    # 0.86 cm, and the odometry from 48 to 20 s.
    kiss_config.mapping.max_points_per_voxel = ODOMETRY_POINTS_PER_VOXEL
    return KissICP(kiss_config)


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

    def __init__(self, config: MapperConfig) -> None:
        import open3d as o3d
        import open3d.core as o3c

        self._o3d, self._o3c = o3d, o3c
        self.config = config
        res = config.face_resolution_px
        self.grid = o3d.t.geometry.VoxelBlockGrid(
            attr_names=("tsdf", "weight", "color"),
            attr_dtypes=(o3c.float32, o3c.float32, o3c.float32),
            attr_channels=((1), (1), (3)),
            voxel_size=config.tsdf_voxel_m,
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
            blocks = self.grid.compute_unique_block_coordinates(
                image, self.K, extrinsic, 1.0, self.config.max_range_m, trunc_voxel_multiplier=3.0
            )
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
        extracted = self.grid.extract_triangle_mesh(weight_threshold=self.config.min_weight)
        vertices = extracted.vertex.positions.numpy().astype(np.float64)
        faces = extracted.triangle.indices.numpy().astype(np.int64)
        return trimesh.Trimesh(vertices, faces, process=False)


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


def _deskewed(
    points: np.ndarray, point_t_ns: np.ndarray, trajectory: Trajectory, pose: np.ndarray
) -> np.ndarray:
    """Sweep points ``(N, 3)`` taken at ``point_t_ns`` ``(N,)``, moved into the LiDAR frame of
    ``pose`` ``(4, 4)`` with the poses ``trajectory`` interpolates (held at its ends), at
    ``_DESKEW_BIN_NS`` steps."""
    bins = (point_t_ns - point_t_ns.min()) // _DESKEW_BIN_NS
    first, inverse = np.unique(bins, return_inverse=True)
    at = trajectory.interpolate(point_t_ns.min() + first * _DESKEW_BIN_NS, clamp=True)
    relative = np.einsum("ij,bjk->bik", invert(pose), at)[inverse]
    return np.einsum("nij,nj->ni", relative[:, :3, :3], points) + relative[:, :3, 3]


def run_mapper(
    scans: Iterable[Scan],
    config: MapperConfig = MapperConfig(),
    progress: Callable[[int], None] | None = None,
) -> MapperResult:
    """Odometry and a TSDF mesh from LiDAR scans (in time order).

    Poses are ``T_world_lidar`` with the world = the LiDAR frame of the first scan, stamped on the
    scans' host clock at each sweep's :func:`~calib.motion.information_time`. A scan is integrated
    once the next one's pose is known, de-skewed with the poses before, at and after it.
    """
    icp = None
    tsdf = _TsdfIntegrator(config)
    t_ns: list[int] = []
    poses: list[np.ndarray] = []
    pending: tuple[np.ndarray, np.ndarray] | None = None  # the last scan's points and their times (ns)

    def integrate_pending(pose_index: int) -> None:
        """Integrate the pending scan, whose pose is ``poses[pose_index]``."""
        recent = Trajectory.from_poses(np.array(t_ns[-3:], dtype=np.int64), np.stack(poses[-3:]))
        points, point_t_ns = pending
        pose = poses[pose_index]
        tsdf.integrate(_deskewed(points, point_t_ns, recent, pose), pose)

    for index, scan in enumerate(scans):
        ranges = np.linalg.norm(scan.points, axis=1)
        keep = (ranges > config.min_range_m) & (ranges < config.max_range_m)
        if keep.sum() < 100:
            continue
        points = scan.points[keep].astype(np.float64)
        times = scan.point_time_s[keep].astype(np.float64)
        if icp is None:
            icp = _kiss_icp(_voxel_size(scan, config), config)
        _, source = icp.register_frame(points, np.zeros(0))
        t_ns.append(int(scan.t_host) + round(information_time(np.asarray(source), points, times) * 1e9))
        poses.append(icp.last_pose.copy())
        if pending is not None:
            integrate_pending(-2)
        pending = (points, int(scan.t_host) + np.round(times * 1e9).astype(np.int64))
        if progress is not None:
            progress(index)
    if len(poses) < 2:
        raise InputError(f"only {len(poses)} usable LiDAR scans; the mapper needs at least 2", field="scans")
    integrate_pending(-1)
    trajectory = Trajectory.from_poses(np.array(t_ns, dtype=np.int64), np.stack(poses))
    return MapperResult(trajectory, tsdf.mesh(), len(poses))


def world_points(scan_points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Scan points ``(N, 3)`` in the world frame given the scan's pose ``(4, 4)``."""
    return transform_points(pose, scan_points)
