"""Small valid sample files of every format the toolkit reads (meshes, point clouds,
trajectories, a calibration, a session): what the reader stress area mutates, and what the
stress tests damage by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from rig.calibration import Calibration, save_calibration
from rig.camera import CameraModel
from rig.messages import Frame, ImuSample, Scan
from rig.open3d_lite import o3d
from rig.session import SessionWriter
from rig.trajectory import Trajectory
from rig.trajectory_io import write_trajectory

#: Formats :func:`write_sample` writes and :func:`~lts.stress.readers.read_back` reads.
READER_KINDS = (
    "ply_ascii",
    "ply_binary",
    "obj",
    "pcd_ascii",
    "pcd_binary",
    "pcd_compressed",
    "kitti_bin",
    "tum",
    "euroc",
    "calib_yaml",
    "mcap",
)


def _sample_points(n: int = 40, seed: int = 0) -> np.ndarray:
    """``(n, 3)`` float32 points, the same for a given seed."""
    return np.random.default_rng(seed).normal(size=(n, 3)).astype(np.float32)


def write_sample(kind: str, path: Path) -> Path:
    """Write a small valid file of ``kind`` (one of :data:`READER_KINDS`) at ``path``; returns
    ``path``."""
    if kind in ("ply_ascii", "ply_binary", "obj"):
        mesh = trimesh.creation.icosphere(subdivisions=1)
        encoding = "ascii" if kind == "ply_ascii" else "binary"
        data = (
            mesh.export(file_type="ply", encoding=encoding) if kind != "obj" else mesh.export(file_type="obj")
        )
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
    elif kind.startswith("pcd"):
        pts = _sample_points()
        cloud = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts))
        cloud.point.intensity = o3d.core.Tensor(np.arange(len(pts), dtype=np.float32)[:, None])
        o3d.t.io.write_point_cloud(
            str(path), cloud, write_ascii=kind == "pcd_ascii", compressed=kind == "pcd_compressed"
        )
    elif kind == "kitti_bin":
        pts = _sample_points()
        np.c_[pts, np.ones(len(pts), np.float32)].astype("<f4").tofile(path)
    elif kind in ("tum", "euroc"):
        rng = np.random.default_rng(0)
        q = rng.normal(size=(20, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        t = Trajectory.from_quaternions(np.arange(20, dtype=np.int64) * 10**8, rng.normal(size=(20, 3)), q)
        write_trajectory(t, path, kind)
    elif kind == "calib_yaml":
        camera = CameraModel(
            "pinhole", 320, 240, [[200, 0, 160], [0, 200, 120], [0, 0, 1]], [0.1, -0.05, 0, 0, 0]
        )
        save_calibration(Calibration(camera, np.eye(4), 0.015, {"rms_px": 0.3}), path)
    elif kind == "mcap":
        rng = np.random.default_rng(0)
        with SessionWriter(path, image_format="png", chunk_size=4096) as w:
            w.write_camera_info(
                CameraModel("pinhole", 16, 12, [[15, 0, 8], [0, 15, 6], [0, 0, 1]], []), 10**9
            )
            for i in range(12):
                t = 10**9 + i * 10**7
                w.write_frame(Frame(rng.integers(0, 255, (12, 16, 3), dtype=np.uint8), t, t, "cam"))
                w.write_imu(ImuSample(np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 9.8]), t, t))
                if i % 4 == 0:
                    pts = rng.normal(size=(50, 3)).astype(np.float32)
                    w.write_scan(Scan(pts, np.zeros(50, np.float32), np.ones(50, np.float32), t, t))
    else:
        raise ValueError(f"unknown sample kind {kind!r}")
    return path


def sample_suffix(kind: str) -> str:
    """The file name suffix of a ``kind`` sample (``".ply"``, ``".pcd"``, ...)."""
    return {
        "ply_ascii": ".ply",
        "ply_binary": ".ply",
        "obj": ".obj",
        "kitti_bin": ".bin",
        "tum": ".tum",
        "euroc": ".csv",
        "calib_yaml": ".yaml",
        "mcap": ".mcap",
    }.get(kind, ".pcd")
