"""Reading what others' bags hold: image encodings, compressed formats, per-point time conventions,
organised clouds and Livox CustomMsg, and the one-line errors on what cannot be read."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from bag_layouts import (
    cloud_msg,
    compressed_image_msg,
    livox_custom_msg,
    raw_image_msg,
    ros1_typestore,
    to_ros1,
    xyz_columns,
)
from rosbags.typesys import Stores, get_typestore

from rig.errors import InputError
from rig.messages import Scan
from rig.session import ros_messages as rm
from rig.session.livox_messages import CUSTOM_MSG_TYPES, register_livox_types

CAMERA = "/cam/image_raw"
LIDAR = "/lidar/points"
STAMP = 1_700_000_000_123_456_789  # a wall-clock stamp, as real drivers write
HEADER = rm.make_header(STAMP, "sensor")
RNG = np.random.default_rng(7)
BGR = RNG.integers(0, 256, (6, 10, 3), dtype=np.uint8)
# JPEG keeps smooth images, not noise.
SMOOTH = np.dstack([*np.meshgrid(np.arange(16) * 8, np.arange(16) * 4), np.full((16, 16), 90)]).astype(
    np.uint8
)


def frame_of(msg: Any) -> np.ndarray:
    msgtype = rm.IMAGE if hasattr(msg, "encoding") else rm.COMPRESSED_IMAGE
    frame = rm.msg_to_frame(msg, msgtype, 1, None, CAMERA)
    assert frame.encoding == ("mono8" if frame.image.ndim == 2 else "bgr8")
    return frame.image


@pytest.mark.parametrize(
    ("encoding", "pixels"),
    [
        ("bgr8", BGR),
        ("8UC3", BGR),
        ("rgb8", BGR[:, :, ::-1]),
        ("bgra8", np.dstack([BGR, np.full(BGR.shape[:2], 9, np.uint8)])),
        ("rgba8", np.dstack([BGR[:, :, ::-1], np.full(BGR.shape[:2], 9, np.uint8)])),
        ("rgb16", BGR[:, :, ::-1].astype(np.uint16) * 257),
        ("bgra16", np.dstack([BGR, np.zeros(BGR.shape[:2], np.uint8)]).astype(np.uint16) * 257),
    ],
)
def test_raw_colour_encodings_give_the_bgr_image(encoding: str, pixels: np.ndarray) -> None:
    np.testing.assert_array_equal(
        frame_of(raw_image_msg(np.ascontiguousarray(pixels), encoding, HEADER)), BGR
    )


@pytest.mark.parametrize("encoding", ["mono8", "8UC1"])
def test_grey_images_stay_grey(encoding: str) -> None:
    grey = BGR[:, :, 1].copy()
    np.testing.assert_array_equal(frame_of(raw_image_msg(grey, encoding, HEADER)), grey)


@pytest.mark.parametrize("bigendian", [False, True])
def test_mono16_keeps_the_high_byte_in_either_byte_order(bigendian: bool) -> None:
    grey = BGR[:, :, 0].copy()
    widened = grey.astype(np.uint16) * 257  # full-scale 8 → 16 bits comes back exactly
    np.testing.assert_array_equal(
        frame_of(raw_image_msg(widened, "mono16", HEADER, bigendian=bigendian)), grey
    )
    one = raw_image_msg(np.full((2, 2), 0x12FF, np.uint16), "mono16", HEADER, bigendian=bigendian)
    assert (frame_of(one) == 0x12).all()


def test_row_padding_is_skipped() -> None:
    msg = raw_image_msg(BGR, "bgr8", HEADER, row_align=64)
    assert msg.step == 64 > BGR.shape[1] * 3
    np.testing.assert_array_equal(frame_of(msg), BGR)


def mosaic(bgr: np.ndarray, pattern: str) -> np.ndarray:
    """The Bayer mosaic ``(H, W)`` of ``bgr`` ``(H, W, 3)`` for a pattern such as ``rggb`` (the
    colours of the top-left 2x2 cell, row by row)."""
    channel = {"b": 0, "g": 1, "r": 2}
    out = np.empty(bgr.shape[:2], dtype=bgr.dtype)
    for k, colour in enumerate(pattern):
        row, col = divmod(k, 2)
        out[row::2, col::2] = bgr[row::2, col::2, channel[colour]]
    return out


@pytest.mark.parametrize("bits", [8, 16])
@pytest.mark.parametrize("pattern", ["rggb", "bggr", "gbrg", "grbg"])
def test_bayer_images_are_demosaiced(pattern: str, bits: int) -> None:
    colour = np.array([30, 120, 220], dtype=np.uint8)  # B G R
    flat = np.broadcast_to(colour, (8, 12, 3))
    raw = mosaic(flat.astype(np.uint16) * 257 if bits == 16 else flat, pattern)
    image = frame_of(raw_image_msg(raw, f"bayer_{pattern}{bits}", HEADER))
    np.testing.assert_array_equal(image[2:-2, 2:-2], np.broadcast_to(colour, (4, 8, 3)))


def test_unknown_encoding_names_the_topic_and_the_encodings_read() -> None:
    with pytest.raises(InputError) as error:
        frame_of(raw_image_msg(BGR, "yuv422", HEADER))
    message = str(error.value)
    assert "\n" not in message
    assert CAMERA in message and "'yuv422'" in message
    assert all(name in message for name in ("rgb8", "bgra8", "mono16", "bayer_grbg8", "bayer_rggb16"))


def test_image_data_shorter_than_its_rows_is_refused() -> None:
    msg = raw_image_msg(BGR, "bgr8", HEADER)
    msg.data = msg.data[:-1]
    with pytest.raises(InputError, match=f"{CAMERA}: .*got step 30 and 179 bytes"):
        frame_of(msg)


@pytest.mark.parametrize(
    ("fmt", "encoded", "expected", "lossless"),
    [
        ("jpeg", SMOOTH, SMOOTH, False),
        ("png", BGR, BGR, True),
        ("rgb8; jpeg compressed bgr8", SMOOTH, SMOOTH, False),
        ("bgr8; png compressed bgr8", BGR, BGR, True),
        ("rgb8; png compressed rgb8", BGR[:, :, ::-1], BGR, True),  # RGB pixels compressed as they were
        ("mono8; png compressed mono8", BGR[:, :, 0], BGR[:, :, 0], True),
        ("mono16; png compressed mono16", BGR[:, :, 0].astype(np.uint16) * 257, BGR[:, :, 0], True),
        ("bgra8; png compressed bgra8", np.dstack([BGR, BGR[:, :, 0]]), BGR, True),
        ("", BGR, BGR, True),  # some recorders leave the format empty: png data still decodes
    ],
)
def test_compressed_images(fmt: str, encoded: np.ndarray, expected: np.ndarray, lossless: bool) -> None:
    image = frame_of(compressed_image_msg(np.ascontiguousarray(encoded), HEADER, fmt))
    difference = np.abs(image.astype(int) - expected.astype(int))
    assert difference.max() == 0 if lossless else difference.mean() < 2


@pytest.mark.parametrize(
    ("fmt", "reason"),
    [
        ("16UC1; compressedDepth png", "compressed depth image"),
        ("32FC1; compressedDepth", "compressed depth image"),
        ("theora", "unsupported CompressedImage format 'theora'; expected jpeg or png"),
    ],
)
def test_compressed_formats_that_are_not_camera_images_are_refused(fmt: str, reason: str) -> None:
    msg = compressed_image_msg(BGR, HEADER, "png")
    msg.format = fmt
    with pytest.raises(InputError, match=f"^{CAMERA}: .*{reason}"):
        frame_of(msg)


def test_undecodable_compressed_data_is_refused() -> None:
    msg = compressed_image_msg(BGR, HEADER, "jpeg")
    msg.data = np.zeros(10, np.uint8)
    with pytest.raises(InputError, match=f"^{CAMERA}: cannot decode 'jpeg' image data"):
        frame_of(msg)


# --- point clouds --------------------------------------------------------------------------------

POINTS = RNG.uniform(-5, 5, (50, 3)).astype(np.float32)
OFFSETS_S = np.linspace(0.0, 0.099, len(POINTS))


def scan_of(msg: Any) -> Scan:
    return rm.msg_to_scan(msg, 1, rm.stamp_ns(msg), LIDAR)


def times_column(name: str, values: np.ndarray, dtype: str) -> dict[str, tuple[np.ndarray, int, str]]:
    return xyz_columns(POINTS) | {"intensity": (np.arange(len(POINTS)), 12, "f4"), name: (values, 16, dtype)}


@pytest.mark.parametrize(
    ("name", "values", "dtype", "expected", "atol"),
    [
        ("t", np.round(OFFSETS_S * 1e9), "u4", OFFSETS_S, 1e-8),  # Ouster: uint32 ns after the stamp
        ("offset_time", np.round(OFFSETS_S * 1e9), "u4", OFFSETS_S, 1e-8),  # Livox PointCloud2
        ("time", OFFSETS_S, "f4", OFFSETS_S, 1e-8),  # Velodyne: float32 s after the stamp
        ("time", OFFSETS_S - 0.1, "f4", OFFSETS_S - 0.1, 1e-8),  # stamped at the sweep's end
        ("timestamp", STAMP * 1e-9 + OFFSETS_S, "f8", OFFSETS_S, 1e-6),  # Hesai / RoboSense: absolute s
        ("timestamp", STAMP + OFFSETS_S * 1e9, "f8", OFFSETS_S, 1e-6),  # livox_ros_driver2: absolute ns
    ],
)
def test_point_time_conventions(
    name: str, values: np.ndarray, dtype: str, expected: np.ndarray, atol: float
) -> None:
    scan = scan_of(cloud_msg(HEADER, times_column(name, values, dtype), 24))
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_array_equal(scan.intensity, np.arange(len(POINTS)))
    np.testing.assert_allclose(scan.point_time_s, expected, rtol=0, atol=atol)
    # Negative times stay right on the absolute clock that de-skewing uses.
    np.testing.assert_allclose(scan.point_times_ns() - STAMP, expected * 1e9, rtol=0, atol=atol * 1e9)


@pytest.mark.parametrize("unit", [1.0, 1e9])
def test_absolute_times_on_a_small_clock_are_still_absolute(unit: float) -> None:
    """A bag stamped by a monotonic clock (seconds since boot) has small absolute times."""
    stamp = 6_804_248_884_054
    header = rm.make_header(stamp, "sensor")
    absolute = (stamp * 1e-9 + OFFSETS_S) * unit
    scan = scan_of(cloud_msg(header, times_column("timestamp", absolute, "f8"), 24))
    np.testing.assert_allclose(scan.point_time_s, OFFSETS_S, rtol=0, atol=1e-6)


def test_organised_cloud_drops_nan_and_zero_points_and_row_padding() -> None:
    points = POINTS.copy()
    points[[3, 17, 40]] = np.nan  # missing returns of an organised cloud
    points[[5, 22]] = 0.0  # Ouster's "no return"
    columns = xyz_columns(points) | {"t": (np.round(OFFSETS_S * 1e9), 16, "u4")}
    msg = cloud_msg(HEADER, columns, 20, rows=7, row_padding=5)
    assert (msg.height, msg.width, msg.row_step) == (7, 8, 165)
    scan = scan_of(msg)
    keep = np.ones(len(POINTS), bool)
    keep[[3, 17, 40, 5, 22]] = False
    np.testing.assert_array_equal(scan.points, POINTS[keep])
    np.testing.assert_allclose(scan.point_time_s, OFFSETS_S[keep], atol=1e-8)


def test_big_endian_cloud_with_reflectivity_and_no_time() -> None:
    columns = xyz_columns(POINTS) | {"reflectivity": (np.arange(len(POINTS)), 12, "u2")}
    scan = scan_of(cloud_msg(HEADER, columns, 16, bigendian=True))
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_array_equal(scan.intensity, np.arange(len(POINTS)))
    assert not scan.point_time_s.any()


def test_clouds_that_cannot_be_read_are_refused_naming_the_topic() -> None:
    no_z = {k: v for k, v in xyz_columns(POINTS).items() if k != "z"}
    with pytest.raises(InputError, match=f"^{LIDAR}: PointCloud2 lacks field\\(s\\) z$"):
        scan_of(cloud_msg(HEADER, no_z, 12))
    outside = xyz_columns(POINTS) | {"t": (np.zeros(len(POINTS)), 12, "u4")}
    msg = cloud_msg(HEADER, outside, 16)
    msg.point_step = 14
    with pytest.raises(
        InputError, match=f"^{LIDAR}: field 't' at offset 12 does not fit a point of 14 bytes"
    ):
        scan_of(msg)
    short = cloud_msg(HEADER, xyz_columns(POINTS), 12)
    short.data = short.data[:-12]
    with pytest.raises(InputError, match=f"^{LIDAR}: 1 rows of 50 points of 12 bytes need"):
        scan_of(short)


# --- Livox CustomMsg -----------------------------------------------------------------------------

SWEEP = Scan(
    POINTS, OFFSETS_S.astype(np.float32), np.arange(len(POINTS), dtype=np.float32), 5, STAMP, "livox"
)


def test_typestore_and_point_cloud_types_know_every_livox_package() -> None:
    assert set(CUSTOM_MSG_TYPES) <= set(rm.typestore().types)
    assert (rm.POINT_CLOUD, *CUSTOM_MSG_TYPES) == rm.POINT_CLOUD_TYPES
    store = get_typestore(Stores.ROS2_HUMBLE)
    register_livox_types(store)
    register_livox_types(store)  # idempotent
    assert {t.replace("CustomMsg", "CustomPoint") for t in CUSTOM_MSG_TYPES} <= set(store.types)


@pytest.mark.parametrize("msgtype", CUSTOM_MSG_TYPES)
def test_custom_msg_round_trip_through_cdr(msgtype: str) -> None:
    msg = rm.deserialize(rm.serialize(livox_custom_msg(SWEEP, HEADER, msgtype)), msgtype)
    scan = rm.msg_to_scan(msg, 5, STAMP, "livox")
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_allclose(scan.point_time_s, OFFSETS_S, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(scan.intensity, np.arange(len(POINTS)))
    assert (scan.t_host, scan.t_device, scan.lidar_id) == (5, STAMP, "livox")


def test_ros1_custom_msg_round_trip() -> None:
    """livox_ros_driver's ROS 1 message (its Header has seq), as FAST-LIO users record it."""
    store = ros1_typestore()
    register_livox_types(store)
    msgtype = "livox_ros_driver/msg/CustomMsg"
    ros1 = to_ros1(livox_custom_msg(SWEEP, HEADER, msgtype), store)
    msg = store.deserialize_ros1(bytes(store.serialize_ros1(ros1, msgtype)), msgtype)
    scan = rm.msg_to_scan(msg, 5, rm.stamp_ns(msg), "livox")
    np.testing.assert_array_equal(scan.points, POINTS)
    np.testing.assert_allclose(scan.point_time_s, OFFSETS_S, rtol=0, atol=1e-8)


def test_custom_msg_drops_missing_points() -> None:
    points = POINTS.copy()
    points[[1, 2]] = [[0, 0, 0], [np.nan, 1, 1]]
    sweep = Scan(points, SWEEP.point_time_s, SWEEP.intensity, 5, STAMP, "livox")
    scan = rm.msg_to_scan(livox_custom_msg(sweep, HEADER), 5, STAMP, "livox")
    np.testing.assert_array_equal(scan.points, np.delete(POINTS, [1, 2], axis=0))


def test_custom_msg_with_a_wrong_point_count_is_refused_in_one_line() -> None:
    msg = livox_custom_msg(SWEEP, HEADER)
    msg.point_num = 96
    with pytest.raises(InputError) as error:
        rm.msg_to_scan(msg, 5, STAMP, "/livox/lidar")
    assert str(error.value) == (
        "/livox/lidar: CustomMsg says point_num=96 but holds 50 points (expected them to agree)"
    )
