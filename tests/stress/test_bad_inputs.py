"""Bad input across the readers: truncated and corrupted files, wrong counts, NaN, out-of-order
and duplicate stamps, wrong image sizes, non-orthonormal rotations. Each gives an InputError
naming the file (and field), never a library traceback or a hang — in the API and the CLI."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import assert_one_line_error, examples
from console_script import run_console_script as run_cli
from hypothesis import given
from hypothesis import strategies as st

from lts.stress.guards import time_limit
from lts.stress.readers import MUTATIONS, check_reader
from lts.stress.samples import READER_KINDS
from rig.calibration import load_calibration
from rig.camera import CameraModel
from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.pointcloud_io import read_point_cloud
from rig.session import SessionReader, recover, session_info
from rig.trajectory_io import read_trajectory
from slam_bridge.prepare_config import PrepareConfig
from slam_bridge.scene import Keyframe, load_scene, write_scene_index


@examples(150)
@given(
    st.sampled_from(READER_KINDS),
    st.sampled_from(MUTATIONS),
    st.floats(0.0, 1.0),
    st.binary(min_size=1, max_size=8),
)
def test_every_reader_survives_truncation_corruption_and_nan(
    tmp_path, kind, mutation, position, payload
) -> None:
    problems, _ = check_reader(kind, mutation, position, payload, tmp_path)
    assert problems == []


def _raises(fn: Callable[[], object], path: Path, *needles: str, field: str | None = None) -> InputError:
    with time_limit(20), pytest.raises(InputError) as err:
        fn()
    assert err.value.path is not None and Path(err.value.path).name == path.name, str(err.value)
    for needle in needles:
        assert needle in str(err.value), str(err.value)
    if field is not None:
        assert err.value.field == field, str(err.value)
    return err.value


# Meshes ---------------------------------------------------------------------------------------

PLY = (
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
)
OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


@pytest.mark.parametrize(
    ("name", "text", "needle", "field"),
    [
        # Bug: a face count larger than the faces present loaded silently (a cut-short file).
        ("faces.ply", PLY.replace("element face 1", "element face 4"), "4 face", "element"),
        ("vertices.ply", PLY.replace("element vertex 3", "element vertex 5"), "5 vertex", "element"),
        ("fewer.ply", PLY.replace("element vertex 3", "element vertex 2"), "the file holds 4", "element"),
        ("nan.ply", PLY.replace("1 0 0\n", "nan 0 0\n"), "NaN", "vertices"),
        ("index.ply", PLY.replace("3 0 1 2", "3 0 1 7"), "vertex 7", "faces"),
        # Bug: a negative index was reported as "faces index vertex 2" (the largest one).
        ("negative.ply", PLY.replace("3 0 1 2", "3 0 -1 2"), "vertex -1", "faces"),
        ("header.ply", "ply\nformat ascii 1.0\n", "end_header", "header"),
        # Bug: OBJ index 0 (OBJ counts from 1) was silently rewired into a different mesh.
        ("zero.obj", OBJ.replace("f 1 2 3", "f 0 1 2"), "index 0", "f"),
        ("far.obj", OBJ.replace("f 1 2 3", "f 1 2 9"), "index 9", "f"),
        # Bug: a 2-coordinate vertex gave a mesh of 2-D vertices.
        ("flat.obj", OBJ.replace("v 1 0 0", "v 1 0"), "2 coordinates", "v"),
        ("nan.obj", OBJ.replace("v 1 0 0", "v nan 0 0"), "NaN", "vertices"),
    ],
)
def test_bad_meshes(tmp_path: Path, name: str, text: str, needle: str, field: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    _raises(lambda: load_mesh(path), path, needle, field=field)


def test_truncated_binary_ply(samples, tmp_path: Path) -> None:
    data = samples("ply_binary").read_bytes()
    for cut in (len(data) // 2, len(data) - 3):
        path = tmp_path / "cut.ply"
        path.write_bytes(data[:cut])
        _raises(lambda: load_mesh(path), path, "unexpected length")  # noqa: B023


# Point clouds ---------------------------------------------------------------------------------


def _pcd(n: int, encoding: str, **over: str) -> str:
    head = {"FIELDS": "x y z intensity", "SIZE": "4 4 4 4", "TYPE": "F F F F", "COUNT": "1 1 1 1"}
    head |= {"WIDTH": str(n), "HEIGHT": "1", "POINTS": str(n)} | over
    lines = [
        "VERSION 0.7",
        *(f"{k} {v}" for k, v in head.items()),
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"DATA {encoding}",
    ]
    return "\n".join(lines) + "\n"


ROWS = "\n".join(f"{i}.5 {i}.25 -{i}.75 {i}" for i in range(10)) + "\n"


@pytest.mark.parametrize(
    ("text", "needle", "field"),
    [
        # Bug: Open3D padded missing points with zeros (12 points, 2 at the origin).
        (_pcd(12, "ascii", WIDTH="12") + ROWS, "12 points, the file holds 10", "POINTS"),
        # Bug: extra lines were silently dropped.
        (_pcd(8, "ascii", WIDTH="8") + ROWS, "8 points, the file holds 10", "POINTS"),
        # Bug: a word that is not a number was read as 0.
        (_pcd(10, "ascii") + ROWS.replace("3.5", "abc"), "point 3", "DATA"),
        (_pcd(10, "ascii", WIDTH="7") + ROWS, "WIDTH x HEIGHT", "POINTS"),
        # Bug: an unknown TYPE raised Open3D's RuntimeError (a C++ traceback line).
        (_pcd(10, "ascii", TYPE="Q F F F") + ROWS, "unknown type 'Q'", "TYPE"),
        (_pcd(10, "ascii", SIZE="4 4 4") + ROWS, "3 entries for 4 fields", "SIZE"),
        (_pcd(10, "ascii", COUNT="1 1") + ROWS, "2 entries", "COUNT"),
        (_pcd(10, "ascii", SIZE="3 4 4 4") + ROWS, "cannot be 3 bytes", "SIZE"),
        (_pcd(-5, "ascii", WIDTH="-5") + ROWS, "negative count", "POINTS"),
        (_pcd(10, "lzma") + ROWS, "unknown encoding", "DATA"),
    ],
)
def test_bad_pcd_headers_and_ascii_payloads(tmp_path: Path, text: str, needle: str, field: str) -> None:
    path = tmp_path / "cloud.pcd"
    path.write_text(text)
    _raises(lambda: read_point_cloud(path), path, needle, field=field)


@pytest.mark.parametrize("kind", ["pcd_binary", "pcd_compressed"])
def test_truncated_binary_pcd(samples, tmp_path: Path, kind: str) -> None:
    data = samples(kind).read_bytes()
    payload = data.index(b"DATA") + data[data.index(b"DATA") :].index(b"\n") + 1
    for cut in (payload, payload + 5, len(data) - 7):
        path = tmp_path / "cut.pcd"
        path.write_bytes(data[:cut])
        _raises(lambda: read_point_cloud(path), path, "truncated", field="DATA")  # noqa: B023


def test_nan_points_are_dropped_from_pcd_and_kitti_alike(tmp_path: Path) -> None:
    """Bug: read_pcd dropped points with a NaN coordinate (no return), read_kitti_bin kept them."""
    pcd = tmp_path / "nan.pcd"
    pcd.write_text(_pcd(10, "ascii") + ROWS.replace("3.5", "nan"))
    kitti = tmp_path / "nan.bin"
    rows = np.array([[np.nan, 0, 0, 1], [1, 2, 3, 4], [0, np.inf, 0, 1]], dtype="<f4")
    rows.tofile(kitti)
    assert len(read_point_cloud(pcd)) == 9
    cloud = read_point_cloud(kitti)
    assert len(cloud) == 1 and np.all(np.isfinite(cloud.points)) and cloud.intensity.tolist() == [4.0]


# Trajectories ---------------------------------------------------------------------------------

TUM = "1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n3.0 2 0 0 0 0 0 1\n"
KITTI = "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n"


@pytest.mark.parametrize(
    ("name", "text", "kwargs", "needle", "field"),
    [
        ("order.tum", TUM.replace("2.0 1", "4.0 1"), {}, "out-of-order", "t"),
        ("nan.tum", TUM.replace("2.0 1", "2.0 nan"), {}, "not finite", "tx"),
        ("quat.tum", TUM.replace("0 0 0 1\n3.0", "0 0 0 0\n3.0"), {}, "unit quaternion", "q"),
        # Bug: a stamp beyond int64 nanoseconds (1e10 s and up) raised a bare OverflowError.
        ("overflow.tum", TUM.replace("3.0", "1e10"), {}, "int64", "t"),
        ("overflow.csv", "99999999999999999999,0,0,0,1,0,0,0\n", {}, "int64", "timestamp_ns"),
        # Bug: --rate nan was accepted (with a numpy warning), --rate inf stamped every pose 0, a
        # tiny rate overflowed into a negative stamp reported as "out of order".
        ("rate.txt", KITTI, {"rate_hz": float("nan")}, "positive", "rate"),
        ("rate.txt", KITTI, {"rate_hz": float("inf")}, "positive", "rate"),
        ("rate.txt", KITTI, {"rate_hz": 1e-12}, "do not fit", "rate"),
        # Bug: a sheared "rotation" with determinant 1 was accepted and turned into a quaternion.
        ("shear.txt", "1 0.5 0 0 0 1 0 0 0 0 1 0\n", {"rate_hz": 10.0}, "R Rᵀ", "pose"),
        # Bug: a 4x4 line's last row was ignored.
        ("row.txt", "1 0 0 0 0 1 0 0 0 0 1 0 5 5 5 5\n", {"rate_hz": 10.0}, "last row", "pose"),
    ],
)
def test_bad_trajectories(
    tmp_path: Path, name: str, text: str, kwargs: dict, needle: str, field: str
) -> None:
    path = tmp_path / name
    path.write_text(text)
    _raises(lambda: read_trajectory(path, **kwargs), path, needle, field=field)


def test_duplicate_stamps_are_kept_with_a_warning_naming_the_line(tmp_path: Path, caplog) -> None:
    path = tmp_path / "dup.tum"
    path.write_text(TUM.replace("3.0", "2.0"))
    trajectory = read_trajectory(path)
    assert len(trajectory) == 3 and f"{path}:3" in caplog.text
    assert np.allclose(trajectory.interpolate(2_000_000_000)[:3, 3], [2, 0, 0])  # last pose of the stamp


# Calibration ----------------------------------------------------------------------------------

CAMERA = (
    "camera: {model: pinhole, width: 320, height: 240, "
    "K: [[200, 0, 160], [0, 200, 120], [0, 0, 1]], dist: []}\n"
)


@pytest.mark.parametrize(
    ("text", "needle", "field"),
    [
        (
            CAMERA + "T_cam_lidar: [[1,0.1,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n",
            "not orthonormal",
            "T_cam_lidar",
        ),
        (CAMERA + "T_cam_lidar: [[-1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n", "det +1", "T_cam_lidar"),
        (CAMERA + "T_cam_lidar: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,2]]\n", "last row", "T_cam_lidar"),
        (CAMERA + "T_cam_lidar: [[.nan,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n", "NaN", "T_cam_lidar"),
        # Bug: a fractional image size was truncated by int() (320.5 became 320).
        (CAMERA.replace("320", "320.5", 1), "whole pixels", "camera.width/height"),
        (CAMERA + "time_offset_s: .inf\n", "finite", "time_offset_s"),
    ],
)
def test_bad_calibrations(tmp_path: Path, text: str, needle: str, field: str) -> None:
    path = tmp_path / "calib.yaml"
    path.write_text(text)
    _raises(lambda: load_calibration(path), path, needle, field=field)


def test_binary_calibration_file(tmp_path: Path) -> None:
    """Bug: a calib.yaml that is not UTF-8 text raised UnicodeDecodeError."""
    path = tmp_path / "calib.yaml"
    path.write_bytes(b"\xff\xfe\x00\x01garbage")
    _raises(lambda: load_calibration(path), path, "not a text file")


# Scene folders --------------------------------------------------------------------------------

SCENE_CAMERA = CameraModel("pinhole", 32, 24, [[30, 0, 16], [0, 30, 12], [0, 0, 1]], [])


def _scene(root: Path) -> Path:
    (root / "images").mkdir(parents=True)
    (root / "lidar").mkdir()
    (root / "normals").mkdir()
    write_scene_index(root, SCENE_CAMERA, [Keyframe("a", 1, np.eye(4), "train")], PrepareConfig(), {})
    cv2.imwrite(str(root / "images" / "a.png"), np.zeros((24, 32, 3), np.uint8))
    np.save(root / "lidar" / "a.npy", np.ones((5, 3), np.float32))
    np.save(root / "normals" / "a.npy", np.zeros((24, 32, 3), np.float32))
    return root


def test_scene_image_of_the_wrong_size(tmp_path: Path) -> None:
    """Bug: Scene.image returned an image of any size; training would have compared it with
    renders of the camera's size."""
    scene = load_scene(_scene(tmp_path))
    path = tmp_path / "images" / "a.png"
    cv2.imwrite(str(path), np.zeros((20, 32, 3), np.uint8))
    _raises(lambda: scene.image(scene.keyframes[0]), path, "32x20", field="size")


@pytest.mark.parametrize(
    ("array", "needle", "field"),
    [
        (np.full((5, 3), np.inf, np.float32), "NaN or Inf", "values"),
        (np.full((5, 3), "x"), "dtype", "dtype"),  # Bug: numpy's ValueError from astype
        (np.ones((5, 2), np.float32), "shape", "shape"),
        (np.ones((24, 32), np.float32), "shape", "shape"),  # a depth image of format version 1
    ],
)
def test_scene_lidar_arrays(tmp_path: Path, array: np.ndarray, needle: str, field: str) -> None:
    scene = load_scene(_scene(tmp_path))
    path = tmp_path / "lidar" / "a.npy"
    np.save(path, array)
    _raises(lambda: scene.depth(scene.keyframes[0]), path, needle, field=field)


@pytest.mark.parametrize(
    ("edit", "needle", "field"),
    [
        # Bugs: a JSON list, a non-list keyframes, a NaN or sheared pose, a path as a name, a
        # fractional stamp and a distorted camera were accepted or raised raw errors.
        (lambda d: [d], "JSON object", None),
        (lambda d: {**d, "keyframes": 5}, "expected a list", "keyframes"),
        (lambda d: _pose(d, [[float("nan")] * 4] * 4), "NaN", "keyframes[0].T_world_cam"),
        (lambda d: _pose(d, [[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), "orthonormal", None),
        (lambda d: _entry(d, name="../../outside"), "plain file name", "keyframes"),
        (lambda d: _entry(d, t_ns=1.5), "whole nanoseconds", "keyframes"),
        (lambda d: {**d, "camera": {**d["camera"], "dist": [0.1, 0, 0, 0, 0]}}, "distortion", "camera"),
        # A scene folder of an older lts prepare (depth images, no options) or of a newer one.
        (lambda d: _without(d, "format_version"), "re-run lts prepare", "format_version"),
        (lambda d: {**d, "format_version": 3}, "re-run lts prepare", "format_version"),
        (lambda d: {**d, "options": {"keyframe_interval_s": 0.5}}, "expected the fields", "options"),
    ],
)
def test_bad_scene_index(tmp_path: Path, edit, needle: str, field: str | None) -> None:
    root = _scene(tmp_path)
    index = root / "scene.json"
    index.write_text(json.dumps(edit(json.loads(index.read_text()))))
    _raises(lambda: load_scene(root), index, needle, field=field)


def _without(data: dict, key: str) -> dict:
    return {k: v for k, v in data.items() if k != key}


def _entry(data: dict, **changes) -> dict:
    return {**data, "keyframes": [{**data["keyframes"][0], **changes}]}


def _pose(data: dict, T) -> dict:
    return _entry(data, T_world_cam=T)


def test_binary_scene_index(tmp_path: Path) -> None:
    root = _scene(tmp_path)
    (root / "scene.json").write_bytes(b"\xff\xfe\x00")
    _raises(lambda: load_scene(root), root / "scene.json", "not a text file")


# Sessions (MCAP) ------------------------------------------------------------------------------


def test_corrupted_chunk_is_reported_as_truncation_not_a_zstd_traceback(samples, tmp_path: Path) -> None:
    """Bug: a damaged zstd chunk raised zstandard.ZstdError out of rig info / rig recover / the
    readers, a flipped byte that still decompressed went unnoticed (garbled messages), and a
    corrupted length field raised OverflowError or tried to allocate terabytes. Fix: chunk CRCs
    checked, reads clamped to the file size, these errors reported as truncation."""
    data = bytearray(samples("mcap").read_bytes())
    whole = session_info(samples("mcap"))["messages"]
    middle = len(data) // 2
    data[middle : middle + 6] = b"\x00\xff\x13\x37\x00\xff"
    path = tmp_path / "flipped.mcap"
    path.write_bytes(bytes(data))
    with time_limit(20):
        info = session_info(path)
        salvage = recover(path, tmp_path / "fixed.mcap")
    assert info["truncated"] and 0 < info["messages"] < whole
    assert salvage["messages"] == info["messages"] and not session_info(tmp_path / "fixed.mcap")["truncated"]


def test_huge_length_field_is_truncation(samples, tmp_path: Path) -> None:
    data = bytearray(samples("mcap").read_bytes())
    # The first record after the magic is the header: opcode (1 byte) then its length (8 bytes).
    data[9:17] = (2**62).to_bytes(8, "little")
    path = tmp_path / "length.mcap"
    path.write_bytes(bytes(data))
    with time_limit(20):
        info = session_info(path)
    assert info["truncated"] and info["messages"] == 0


def test_every_truncation_point_reads_a_prefix(samples, tmp_path: Path) -> None:
    data = samples("mcap").read_bytes()
    counts = []
    for cut in range(8, len(data), max(1, len(data) // 40)):
        path = tmp_path / "cut.mcap"
        path.write_bytes(data[:cut])
        info = session_info(path)
        assert info["truncated"]
        assert sum(1 for _ in SessionReader(path).messages()) == info["messages"]
        counts.append(info["messages"])
    assert counts == sorted(counts) and counts[-1] > 0  # more file, more messages


def test_not_an_mcap_file(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"ROSBAG V2.0\n" + bytes(100))
    _raises(lambda: session_info(path), path, "bad magic")


def test_a_packet_capture_is_told_how_to_become_a_recording(real_data: Path) -> None:
    path = real_data / "ouster" / "OS-0-32-U1_v2.2.0_1024x10.pcap"
    _raises(lambda: session_info(path), path, "rig record replays an Ouster pcap")


# Through the command line ---------------------------------------------------------------------


@pytest.fixture
def rig_main():
    from rig.cli import main

    return main


@pytest.fixture
def lts_main():
    from lts.cli import main

    return main


def test_rig_info_and_recover_on_damaged_files(rig_main, samples, tmp_path, monkeypatch, capsys) -> None:
    bogus = tmp_path / "bogus.mcap"
    bogus.write_bytes(b"not an mcap file at all")
    code, _, err = run_cli(rig_main, ["info", bogus], monkeypatch, capsys)
    assert_one_line_error(code, err, str(bogus), "bad magic")
    code, _, err = run_cli(rig_main, ["recover", bogus, "--out", tmp_path / "f.mcap"], monkeypatch, capsys)
    assert_one_line_error(code, err, str(bogus))
    data = samples("mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    code, out, err = run_cli(rig_main, ["info", cut, "--json"], monkeypatch, capsys)
    assert code == 0 and json.loads(out)["truncated"], err
    fixed = tmp_path / "fixed.mcap"
    code, out, err = run_cli(rig_main, ["recover", cut, "--out", fixed, "--json"], monkeypatch, capsys)
    assert code == 0 and json.loads(out)["truncated"], err
    assert not session_info(fixed)["truncated"]


@pytest.mark.parametrize(
    ("name", "text", "needles"),
    [
        ("order.tum", TUM.replace("2.0 1", "4.0 1"), [":3", "t:", "out-of-order"]),
        ("overflow.tum", TUM.replace("3.0", "1e10"), [":3", "t:", "int64"]),
        ("shear.tum", "not used", []),
    ],
)
def test_lts_trajectory_info_bad_files(lts_main, tmp_path, monkeypatch, capsys, name, text, needles) -> None:
    path = tmp_path / name
    args = ["trajectory", "info", path]
    if name == "shear.tum":
        path = tmp_path / "shear.txt"
        path.write_text("1 0.5 0 0 0 1 0 0 0 0 1 0\n")
        args, needles = ["trajectory", "info", path, "--format", "kitti", "--rate", "10"], ["pose", "R Rᵀ"]
    else:
        path.write_text(text)
    code, out, err = run_cli(lts_main, args, monkeypatch, capsys)
    assert_one_line_error(code, err, str(path), *needles)
    assert out == ""


def test_lts_eval_mesh_bad_input(lts_main, samples, tmp_path, monkeypatch, capsys) -> None:
    """Bug: `lts eval --threshold -1` ended in a ValueError traceback."""
    good = samples("ply_binary")
    bad = tmp_path / "bad.ply"
    bad.write_text(PLY.replace("element face 1", "element face 4"))
    code, _, err = run_cli(lts_main, ["eval", "--mesh", bad, "--gt", good, "--json"], monkeypatch, capsys)
    assert_one_line_error(code, err, str(bad), "element")
    for option in (["--threshold", "-1"], ["--threshold", "nan"], ["--samples", "0"]):
        args = ["eval", "--mesh", good, "--gt", good, "--json", *option]
        code, _, err = run_cli(lts_main, args, monkeypatch, capsys)
        assert_one_line_error(code, err, "threshold" if option[0] == "--threshold" else "samples")
