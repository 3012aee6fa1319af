"""PCD (ascii, binary, binary_compressed) and KITTI .bin readers."""

from __future__ import annotations

import numpy as np
import pytest

from rig.errors import InputError
from rig.pointcloud_io import read_kitti_bin, read_pcd, read_point_cloud


def _cloud(n: int = 500) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    return rng.normal(0, 10, (n, 3)).astype(np.float32), rng.uniform(0, 255, n).astype(np.float32)


@pytest.mark.parametrize(
    ("ascii", "compressed", "encoding"),
    [(True, False, "ascii"), (False, False, "binary"), (False, True, "binary_compressed")],
)
def test_pcd_encodings_round_trip(tmp_path, ascii: bool, compressed: bool, encoding: str) -> None:
    import open3d as o3d

    xyz, inten = _cloud()
    cloud = o3d.t.geometry.PointCloud(o3d.core.Tensor(xyz))
    cloud.point.intensity = o3d.core.Tensor(inten.reshape(-1, 1))
    path = tmp_path / "c.pcd"
    o3d.t.io.write_point_cloud(str(path), cloud, write_ascii=ascii, compressed=compressed)
    assert f"DATA {encoding}" in path.read_bytes()[:400].decode("ascii", "replace")
    read = read_pcd(path)
    np.testing.assert_allclose(read.points, xyz, rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(read.intensity, inten, rtol=1e-6, atol=1e-4)


def test_kitti_bin_round_trip_and_truncation(tmp_path) -> None:
    xyz, inten = _cloud()
    path = tmp_path / "000000.bin"
    np.column_stack([xyz, inten / 255]).astype("<f4").tofile(path)
    read = read_point_cloud(path)
    np.testing.assert_allclose(read.points, xyz, rtol=1e-6)
    np.testing.assert_allclose(read.intensity, inten / 255, rtol=1e-6)
    path.write_bytes(path.read_bytes()[:-2])
    with pytest.raises(InputError, match=r"000000\.bin"):
        read_kitti_bin(path)


def test_nuscenes_pcd_bin_is_five_fields_not_kitti(tmp_path) -> None:
    """A nuScenes sweep ``*.pcd.bin`` (x y z intensity ring) whose size happens to be a whole number
    of KITTI records was read as KITTI's four fields: every point after the first was garbage."""
    xyz, inten = _cloud()
    xyz, inten = xyz[:8], inten[:8]  # 8 records of 5 fields = 10 records of 4
    path = tmp_path / "n015__LIDAR_TOP__1.pcd.bin"
    np.column_stack([xyz, inten, np.arange(8)]).astype("<f4").tofile(path)
    read = read_point_cloud(path)
    np.testing.assert_allclose(read.points, xyz, rtol=1e-6)
    np.testing.assert_allclose(read.intensity, inten, rtol=1e-6)
    path.write_bytes(path.read_bytes()[:-4])
    with pytest.raises(InputError, match=r"1\.pcd\.bin: data: .*20-byte records"):
        read_point_cloud(path)


def test_bad_files_name_file_and_field(tmp_path) -> None:
    bad = tmp_path / "bad.pcd"
    bad.write_text(
        "VERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
        "DATA ascii\n1 2\n"
    )
    with pytest.raises(InputError, match=r"bad\.pcd: FIELDS"):
        read_pcd(bad)
    with pytest.raises(InputError, match="unknown point cloud format"):
        read_point_cloud(tmp_path / "x.ply")
    with pytest.raises(InputError, match="file not found"):
        read_pcd(tmp_path / "missing.pcd")


def test_real_clouds(real_data) -> None:
    manual = read_point_cloud(real_data / "lidar_camera_pjlab/manual/0.pcd")  # ascii
    auto = read_point_cloud(real_data / "lidar_camera_pjlab/auto/calib.pcd")  # binary_compressed
    kitti = read_point_cloud(real_data / "kitti_frames/velodyne/000000.bin")
    (nuscenes,) = (read_point_cloud(p) for p in (real_data / "nuscenes_sample").glob("*.pcd.bin"))
    assert len(nuscenes) == 34688 and nuscenes.intensity.max() == 255.0
    assert np.median(np.linalg.norm(nuscenes.points, axis=1)) < 30  # metres, not a misread
    assert (len(manual), len(auto)) == (78238, 85546)
    assert len(kitti) > 100_000 and kitti.intensity.max() <= 1.0
    assert auto.intensity.max() == pytest.approx(254.0)
