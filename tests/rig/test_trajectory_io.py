from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rig import (
    InputError,
    Trajectory,
    detect_format,
    read_euroc,
    read_kitti,
    read_trajectory,
    read_tum,
    write_euroc,
    write_kitti,
    write_trajectory,
    write_tum,
)
from rig.trajectory_io import ns_to_seconds_text, seconds_text_to_ns


def assert_same(a: Trajectory, b: Trajectory) -> None:
    assert np.array_equal(a.t_ns, b.t_ns)
    assert np.array_equal(a.translations, b.translations)
    assert np.array_equal(a.quaternions, b.quaternions)
    assert np.array_equal(a.rotations, b.rotations)


def data_rows(path: Path, delimiter: str | None = None) -> np.ndarray:
    """An independent parse of a numeric table (numpy's loadtxt)."""
    return np.loadtxt(path, comments="#", delimiter=delimiter)


def test_tum_ground_truth_loads_with_right_count_and_end_poses(real_data: Path) -> None:
    path = real_data / "trajectories_evo" / "fr2_desk_groundtruth.txt"
    rows = data_rows(path)
    trajectory = read_tum(path)
    assert len(trajectory) == len(rows) == 20957
    for index in (0, -1):
        assert trajectory.t_ns[index] == round(rows[index, 0] * 1e4) * 100_000  # stamps have 4 decimals
        np.testing.assert_array_equal(trajectory.translations[index], rows[index, 1:4])
        np.testing.assert_array_equal(trajectory.quaternions[index], rows[index, 4:8])
    expected_R = Rotation.from_quat(rows[-1, 4:8]).as_matrix()
    np.testing.assert_allclose(trajectory.poses[-1, :3, :3], expected_R, atol=1e-12)


def test_kitti_ground_truth_loads_with_times(real_data: Path) -> None:
    folder = real_data / "trajectories_evo"
    rows = data_rows(folder / "KITTI_00_gt.txt")
    times = data_rows(folder / "KITTI_00_gt_times.txt")
    trajectory = read_kitti(folder / "KITTI_00_gt.txt", folder / "KITTI_00_gt_times.txt")
    assert len(trajectory) == len(rows) == len(times) == 4541
    for index in (0, -1):
        np.testing.assert_array_equal(trajectory.poses[index, :3, :], rows[index].reshape(3, 4))
        assert trajectory.t_ns[index] == round(times[index] * 1e9)
    assert trajectory.duration_s == pytest.approx(times[-1])


def test_euroc_ground_truth_loads(real_data: Path) -> None:
    path = real_data / "trajectories_evo" / "V102_groundtruth.csv"
    rows = data_rows(path, delimiter=",")
    trajectory = read_euroc(path)
    assert len(trajectory) == len(rows)
    with path.open() as f:
        first_stamp = int(next(line for line in f if not line.startswith("#")).split(",")[0])
    assert trajectory.t_ns[0] == first_stamp  # exact: 19-digit stamps do not fit a float64
    np.testing.assert_array_equal(trajectory.quaternions[-1], rows[-1, [5, 6, 7, 4]])


@pytest.mark.parametrize(
    ("name", "fmt"),
    [
        ("fr2_desk_groundtruth.txt", "tum"),
        ("fr2_desk_ORB.txt", "tum"),
        ("KITTI_00_gt.txt", "kitti"),
        ("KITTI_00_ORB.txt", "kitti"),
        ("V102_groundtruth.csv", "euroc"),
    ],
)
def test_parse_write_parse_round_trip_is_exact(real_data: Path, tmp_path: Path, name: str, fmt: str) -> None:
    path = real_data / "trajectories_evo" / name
    times = real_data / "trajectories_evo" / "KITTI_00_gt_times.txt" if name == "KITTI_00_gt.txt" else None
    first = read_trajectory(path, times_path=times, rate_hz=10.0)
    assert detect_format(path) == fmt
    out = tmp_path / f"again.{fmt}"
    write_trajectory(first, out, fmt)
    again = read_trajectory(out, fmt, times_path=tmp_path / "again_times.txt" if fmt == "kitti" else None)
    assert_same(first, again)


def test_conversion_between_formats_keeps_poses(real_data: Path, tmp_path: Path) -> None:
    tum = read_tum(real_data / "trajectories_evo" / "fr2_desk_ORB.txt")
    write_kitti(tum, tmp_path / "k.txt", tmp_path / "k_times.txt")
    kitti = read_kitti(tmp_path / "k.txt", tmp_path / "k_times.txt")
    assert np.array_equal(kitti.t_ns, tum.t_ns)
    np.testing.assert_allclose(kitti.poses, tum.poses, atol=1e-12)
    write_euroc(kitti, tmp_path / "e.csv")
    write_tum(read_euroc(tmp_path / "e.csv"), tmp_path / "t.txt")
    np.testing.assert_allclose(read_tum(tmp_path / "t.txt").poses, tum.poses, atol=1e-12)


@pytest.mark.parametrize("text", ["0", "1305031102.1758", "-0.5", "1.037359e-01", "1311868229.576000001"])
def test_seconds_text_round_trips_through_nanoseconds(text: str) -> None:
    ns = seconds_text_to_ns(text)
    assert seconds_text_to_ns(ns_to_seconds_text(ns)) == ns


@pytest.mark.parametrize(
    ("content", "line", "needle"),
    [
        ("# header\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", 3, "expected 8 numbers"),
        ("1.0 0 0 0 0 0 0 1\n\n2.0 0 0 zero 0 0 0 1\n", 3, "tz: 'zero' is not a number"),
        ("1.0 0 0 0 0 0 0 1\n2.0 0 0 nan 0 0 0 1\n", 2, "tz: 'nan' is not finite"),
        ("1.0 0 0 0 0 0 0 1\n0.5 0 0 0 0 0 0 1\n", 2, "out-of-order timestamp"),
        ("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 3\n", 2, "unit quaternion"),
    ],
)
def test_malformed_tum_line_names_file_and_line(tmp_path: Path, content: str, line: int, needle: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(content)
    with pytest.raises(InputError) as info:
        read_tum(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert needle in message


def test_unreadable_and_empty_files_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot read trajectory"):
        read_tum(tmp_path / "missing.txt")
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(InputError, match="no poses"):
        read_trajectory(tmp_path / "empty.txt")
    (tmp_path / "five.txt").write_text("1 2 3 4 5\n")
    with pytest.raises(InputError, match="cannot tell the trajectory format"):
        read_trajectory(tmp_path / "five.txt")


def test_kitti_without_times_needs_times_or_rate(real_data: Path, tmp_path: Path) -> None:
    path = real_data / "trajectories_evo" / "KITTI_00_ORB.txt"
    with pytest.raises(InputError, match="give a times file or a positive rate"):
        read_kitti(path)
    assert read_kitti(path, rate_hz=10.0).t_ns[1] == 100_000_000
    (tmp_path / "times.txt").write_text("0.0\n0.1\n")
    with pytest.raises(InputError, match="2 times for 4541 poses"):
        read_kitti(path, tmp_path / "times.txt")
