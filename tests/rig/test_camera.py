import cv2
import numpy as np
import pytest

from rig import CameraModel, InputError

K = np.array([[310.0, 0.0, 161.3], [0.0, 305.0, 118.7], [0.0, 0.0, 1.0]])
CAMERAS = {
    "pinhole-none": CameraModel("pinhole", 320, 240, K, []),
    "pinhole-5": CameraModel("pinhole", 320, 240, K, [-0.28, 0.09, 0.0012, -0.0008, -0.012]),
    "pinhole-8": CameraModel("pinhole", 320, 240, K, [0.1, -0.05, 0.001, 0.0005, 0.002, 0.05, -0.02, 0.003]),
    "fisheye": CameraModel(
        "fisheye",
        320,
        240,
        [[186.0, 0.0, 161.3], [0.0, 183.0, 118.7], [0.0, 0.0, 1.0]],
        [0.05, -0.01, 0.004, -0.001],
    ),
}


def pixel_grid(camera: CameraModel, step: int = 7) -> np.ndarray:
    u, v = np.meshgrid(np.arange(0, camera.width, step), np.arange(0, camera.height, step))
    return np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64) + 0.25


@pytest.mark.parametrize("name", CAMERAS)
def test_project_of_unproject_is_identity_inside_image(name: str) -> None:
    camera = CAMERAS[name]
    pixels = pixel_grid(camera)
    depth = np.linspace(0.5, 30.0, len(pixels))
    points = camera.unproject(pixels, depth)
    np.testing.assert_allclose(points[:, 2], depth, rtol=0, atol=1e-12)
    reprojected = camera.project(points)
    assert np.abs(reprojected - pixels).max() < 1e-9


@pytest.mark.parametrize("name", CAMERAS)
def test_unproject_of_project_recovers_the_ray(name: str) -> None:
    camera = CAMERAS[name]
    rays = camera.unproject(pixel_grid(camera, 11))
    points = rays * np.linspace(1.0, 5.0, len(rays))[:, None]
    back = camera.unproject(camera.project(points), points[:, 2])
    assert np.abs(back - points).max() < 1e-9 * 5.0


def test_points_behind_camera_project_to_nan() -> None:
    pixels = CAMERAS["pinhole-5"].project(np.array([[0.1, 0.2, -1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 2.0]]))
    assert np.isnan(pixels[:2]).all()
    np.testing.assert_allclose(pixels[2], K[:2, 2])


@pytest.mark.parametrize("dist", [[], [0.0] * 5])
def test_undistorted_pinhole_projects_as_opencv_to_the_bit(dist: list[float]) -> None:
    camera = CameraModel("pinhole", 320, 240, K, dist)
    points = np.random.default_rng(0).normal(size=(5000, 3)) * [2.0, 2.0, 5.0]
    front = points[:, 2] > 0
    expected, _ = cv2.projectPoints(points[front].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, camera.dist)
    pixels = camera.project(points)
    assert np.array_equal(pixels[front], expected.reshape(-1, 2))
    assert np.isnan(pixels[~front]).all()


def test_in_image_uses_pixel_centres() -> None:
    camera = CAMERAS["pinhole-none"]
    mask = camera.in_image(np.array([[-0.5, 0], [-0.51, 0], [319.49, 239.49], [319.5, 0], [np.nan, 1]]))
    assert mask.tolist() == [True, False, True, False, False]


@pytest.mark.parametrize("name", ["pinhole-5", "fisheye"])
def test_undistort_image_samples_where_the_distorted_camera_sees_the_ray(name: str) -> None:
    camera = CAMERAS[name]
    target = camera.undistorted()
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (camera.height, camera.width), dtype=np.uint8)
    image = np.repeat(np.repeat(image[::8, ::8], 8, 0), 8, 1)  # blocky, so bilinear lookups are exact
    out = camera.undistort_image(image, target)
    pixels = pixel_grid(target, 13) - 0.25
    source = camera.project(target.unproject(pixels))
    inside = camera.in_image(source, margin=1.0)
    src = np.round(source[inside]).astype(int)
    dst = pixels[inside].astype(int)
    # Compare where the source pixel is well inside an 8×8 block so interpolation is exact.
    interior = (np.abs(source[inside] % 8 - 3.5) < 3.0).all(axis=1)
    assert interior.sum() > 50
    assert np.array_equal(out[dst[interior, 1], dst[interior, 0]], image[src[interior, 1], src[interior, 0]])


def test_dict_round_trip() -> None:
    camera = CAMERAS["fisheye"]
    again = CameraModel.from_dict(camera.to_dict())
    assert (
        again.model == "fisheye"
        and np.array_equal(again.K, camera.K)
        and np.array_equal(again.dist, camera.dist)
    )


@pytest.mark.parametrize(
    ("block", "field"),
    [
        (
            {"model": "orthographic", "width": 4, "height": 4, "K": np.eye(3).tolist()},
            "camera.model",
        ),
        ({"model": "pinhole", "width": 4, "height": 4, "K": [[1, 0], [0, 1]]}, "camera.K"),
        (
            {"model": "fisheye", "width": 4, "height": 4, "K": np.eye(3).tolist(), "dist": [0.1]},
            "camera.dist",
        ),
        (
            {"model": "pinhole", "width": 0, "height": 4, "K": np.eye(3).tolist()},
            "camera.width/height",
        ),
        ({"model": "pinhole", "height": 4, "K": np.eye(3).tolist()}, "camera"),
    ],
)
def test_bad_camera_block_names_file_and_field(block: dict, field: str) -> None:
    with pytest.raises(InputError) as info:
        CameraModel.from_dict(block, path="calib.yaml")
    assert info.value.field == field
    assert str(info.value).startswith("calib.yaml: ")


@pytest.mark.parametrize("name", CAMERAS)
@pytest.mark.parametrize("size", [(80, 60), (107, 80), (320, 240), (640, 480)])
def test_scaled_camera_sees_a_point_at_the_same_place_in_the_image(name: str, size: tuple[int, int]) -> None:
    """A point lands at the same fraction of the image's width and height (measured from the image's
    edge, half a pixel before the first pixel centre) before and after the resize."""
    camera = CAMERAS[name]
    scaled = camera.scaled(*size)
    points = camera.unproject(pixel_grid(camera, 9), np.linspace(0.5, 20.0, len(pixel_grid(camera, 9))))
    before = (camera.project(points) + 0.5) / camera.size
    after = (scaled.project(points) + 0.5) / scaled.size
    np.testing.assert_allclose(after, before, atol=1e-9)
    assert scaled.model == camera.model and np.array_equal(scaled.dist, camera.dist)


def test_area_undistortion_of_a_distortion_free_camera_is_an_area_resize() -> None:
    camera = CAMERAS["pinhole-none"]
    image = np.random.default_rng(1).integers(0, 255, (camera.height, camera.width, 3), dtype=np.uint8)
    for size in [(80, 60), (160, 120)]:
        out = camera.undistort_image(image, camera.scaled(*size), interpolation=cv2.INTER_AREA)
        expected = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
        assert np.abs(out.astype(int) - expected).max() <= 1


@pytest.mark.parametrize("name", ["pinhole-5", "fisheye"])
def test_area_undistortion_into_a_smaller_camera_puts_a_spot_where_it_projects(name: str) -> None:
    """A bright spot drawn where a point projects in the distorted image is centred, after one
    undistortion into a camera a third the size, where that camera projects the point."""
    camera = CAMERAS[name]
    target = camera.undistorted().scaled(107, 80)
    point = camera.unproject(np.array([[200.3, 90.6]]), 3.0)
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    spot = camera.project(point)[0]
    image = 250 * np.exp(-((u - spot[0]) ** 2 + (v - spot[1]) ** 2) / (2 * 4.0**2))
    out = camera.undistort_image(image.astype(np.float32), target, interpolation=cv2.INTER_AREA)
    tu, tv = np.meshgrid(np.arange(target.width), np.arange(target.height))
    centroid = np.array([(out * tu).sum(), (out * tv).sum()]) / out.sum()
    np.testing.assert_allclose(centroid, target.project(point)[0], atol=0.05)
