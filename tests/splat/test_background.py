"""The trained background: spherical harmonics and the map, compositing, training, files, and the
trainer."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import trimesh
from training_scene import write_training_scene

from rig.camera import CameraModel
from rig.errors import InputError
from rig.transforms import make_transform
from splat.background import (
    MAP_LEVELS,
    MAP_TEXELS,
    REACH_MULTIPLE,
    REACH_PERCENTILE,
    background_image,
    background_rgb,
    background_sphere,
    camera_rays,
    constant_background,
    map_values,
    sh_basis,
    sphere_directions,
)
from splat.background_mask import above_lidar, beyond_range, scored_background_mask
from splat.config import make_config
from splat.export import export_mesh
from splat.initialise import views_background_sphere
from splat.lidar_points import lidar_points
from splat.model import TriangleModel, load_model, save_model
from splat.param_rows import make_optimizer, replace_rows
from splat.raster.scenes import pinhole
from splat.trainer import Trainer, camera_only_triangles
from splat.views import View

CAMERA = pinhole(64, 48, fov_deg=80.0)
# Looking along world +y from 1 m up (world z up): image rows above the centre see the sky.
T_WORLD_CAM = make_transform(np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]), np.array([0.0, 0.0, 1.0]))
T_CAM_WORLD = torch.as_tensor(np.linalg.inv(T_WORLD_CAM), dtype=torch.float32)
TRIANGLE_RGB = (0.3, 0.6, 0.2)


def lower_half_model() -> TriangleModel:
    """Three stacked triangles of opacity 0.9 covering the image rows below the centre (alpha =
    1 - 0.1³ there, 0 above), seen from ``T_WORLD_CAM``. (A pixel stops compositing before its
    transmittance falls below 1e-4, so alpha never quite reaches 1.)"""
    corners = torch.tensor([[-100.0, 0.0, 3.0], [100.0, 0.0, 3.0], [0.0, 100.0, 3.0]])
    layers = torch.stack([corners + torch.tensor([0.0, 0.0, 0.5 * i]) for i in range(3)]).double()
    world = layers @ torch.as_tensor(T_WORLD_CAM[:3, :3]).T + torch.as_tensor(T_WORLD_CAM[:3, 3])
    colors = torch.tensor(TRIANGLE_RGB).expand(3, 3, 3)
    return TriangleModel.from_triangles(world.float(), colors, 0.9, sigma=1e-3)


def psnr(a: torch.Tensor, b: torch.Tensor) -> float:
    return -10 * math.log10(float(((a - b) ** 2).mean()))


def test_harmonics_match_their_closed_forms_and_are_differentiable():
    # The closed forms (with the Condon-Shortley signs of the 3DGS basis) at a unit direction.
    x, y, z = 0.6, 0.0, 0.8
    c1, c2 = math.sqrt(3 / (4 * math.pi)), 0.5 * math.sqrt(15 / math.pi)
    expected = [
        0.5 / math.sqrt(math.pi), -c1 * y, c1 * z, -c1 * x,
        c2 * x * y, -c2 * y * z, 0.25 * math.sqrt(5 / math.pi) * (3 * z * z - 1), -c2 * x * z,
        0.5 * c2 * (x * x - y * y),
    ]  # fmt: skip
    direction = torch.tensor([[x, y, z]], dtype=torch.float64)
    torch.testing.assert_close(sh_basis(direction, 2)[0], torch.tensor(expected, dtype=torch.float64))
    assert sh_basis(direction, 0).shape == (1, 1) and sh_basis(direction, 3).shape == (1, 16)
    coefficients = torch.linspace(-1, 1, 27, dtype=torch.float64).view(9, 3)
    rgb = background_rgb(coefficients, direction)[0]
    torch.testing.assert_close(rgb, torch.sigmoid(torch.tensor(expected, dtype=torch.float64) @ coefficients))

    coefficients.requires_grad_(True)
    directions = torch.nn.functional.normalize(torch.randn(5, 3, dtype=torch.float64), dim=1)
    assert torch.autograd.gradcheck(background_rgb, (coefficients, directions.requires_grad_(True)))


def test_a_constant_background_has_its_colour_everywhere_and_world_directions_follow_the_pose():
    constant = constant_background([0.2, 0.5, 0.9], 2)
    assert constant.shape == (9, 3) and constant.is_leaf and constant.requires_grad
    image = background_image(constant, CAMERA, T_CAM_WORLD)
    torch.testing.assert_close(image, torch.tensor([0.2, 0.5, 0.9]).expand(48, 64, 3))

    coefficients = torch.randn(9, 3)
    rays, valid = camera_rays(CAMERA, torch.device("cpu"), torch.float32)
    assert bool(valid.all()) and torch.allclose(rays.norm(dim=1), torch.ones(len(rays)))
    image = background_image(coefficients, CAMERA, T_CAM_WORLD)
    # The optical axis (the pixel at (cx, cy) lies between four pixels: average their rays) sees +y.
    centre = image[23:25, 31:33].reshape(4, 3)
    axis = torch.nn.functional.normalize(rays.view(48, 64, 3)[23:25, 31:33].reshape(4, 3), dim=1)
    world = axis @ T_CAM_WORLD[:3, :3]
    torch.testing.assert_close(world.mean(0), torch.tensor([0.0, 1.0, 0.0]), atol=0.02, rtol=0)
    torch.testing.assert_close(centre, background_rgb(coefficients, world))


def test_a_background_on_a_sphere_shows_the_parallax_of_the_cameras_that_move_inside_it():
    sphere = torch.tensor([1.0, 2.0, 0.0, 50.0])
    directions = torch.nn.functional.normalize(torch.randn(100, 3, dtype=torch.float64), dim=1)
    # From the centre, the sphere's directions are the rays'; at infinity (None), always the rays'.
    torch.testing.assert_close(
        sphere_directions(directions, sphere[:3].double(), sphere.double()), directions
    )
    assert sphere_directions(directions, torch.zeros(3), None) is directions
    # A point on the sphere seen from two places inside it: the same sphere direction from both.
    point = sphere[:3].double() + 50.0 * directions[:1]
    for origin in (torch.tensor([10.0, -5.0, 3.0]), torch.tensor([-20.0, 7.0, 1.0])):
        ray = torch.nn.functional.normalize(point - origin.double(), dim=1)
        torch.testing.assert_close(sphere_directions(ray, origin.double(), sphere.double()), directions[:1])

    # A camera 20 m from the centre sees a sphere background displaced against one at infinity,
    # and the pixels of its optical axis (world +y) look along the direction to (20 + 45.8, ...).
    coefficients = torch.randn(9, 3)  # smooth: four pixels' mean is the mean ray's colour
    T_world_cam = T_WORLD_CAM.copy()
    T_world_cam[:3, 3] = [20.0, 0.0, 0.0]
    T_cam_world = torch.as_tensor(np.linalg.inv(T_world_cam), dtype=torch.float32)
    at_infinity = background_image(coefficients, CAMERA, T_cam_world)
    on_sphere = background_image(coefficients, CAMERA, T_cam_world, torch.tensor([0.0, 0.0, 0.0, 50.0]))
    assert float((on_sphere - at_infinity).abs().max()) > 0.05
    axis = torch.tensor([[20.0, math.sqrt(50.0**2 - 20.0**2), 0.0]]) / 50.0
    expected = background_rgb(coefficients, axis)[0]
    torch.testing.assert_close(on_sphere[23:25, 31:33].mean(dim=(0, 1)), expected, atol=0.03, rtol=0)


def test_the_sphere_lies_twice_the_lidars_reach_beyond_the_farthest_camera():
    centres = np.array([[0.0, 0, 0], [10.0, 0, 0], [20.0, 0, 2]])
    depths = np.random.default_rng(0).uniform(1.0, 60.0, 10_000)
    sphere = background_sphere(centres, depths)
    np.testing.assert_allclose(sphere[:3], [10.0, 0.0, 2 / 3])
    spread = np.hypot(10.0, 4 / 3)
    np.testing.assert_allclose(sphere[3], spread + REACH_MULTIPLE * np.percentile(depths, REACH_PERCENTILE))
    assert (
        background_sphere(centres, np.zeros(0)) is None
        and background_sphere(np.zeros((0, 3)), depths) is None
    )


def test_the_background_stays_at_infinity_where_it_shows_at_under_one_percent_of_the_pixels():
    def view(x: float, shown_rows: int) -> View:
        T_world_cam = T_WORLD_CAM.copy()
        T_world_cam[:3, 3] = [x, 0.0, 1.0]
        mask = torch.zeros(48, 64, dtype=torch.bool)
        mask[:shown_rows] = True
        depth = torch.full((48, 64), 20.0)
        T = torch.as_tensor(np.linalg.inv(T_world_cam), dtype=torch.float32)
        return View("v", T, torch.zeros(48, 64, 3), depth, None, background_mask=mask)

    outdoors = views_background_sphere([view(0.0, 12), view(10.0, 12)])  # a quarter of the pixels
    np.testing.assert_allclose(outdoors, [5.0, 0.0, 1.0, 5.0 + REACH_MULTIPLE * 20.0], rtol=1e-6)
    assert views_background_sphere([view(0.0, 0), view(10.0, 0)]) is None  # indoors: nowhere
    unmasked = [view(0.0, 0), view(10.0, 0)]
    for v in unmasked:
        v.background_mask = None  # composited everywhere
    assert views_background_sphere(unmasked) is not None
    no_depth = [view(0.0, 12)]
    no_depth[0].depth = None
    assert views_background_sphere(no_depth) is None


def _azimuth_elevation(azimuth_deg: torch.Tensor, elevation_deg: torch.Tensor) -> torch.Tensor:
    a, e = torch.deg2rad(azimuth_deg.double()), torch.deg2rad(elevation_deg.double())
    return torch.stack([torch.cos(e) * torch.cos(a), torch.cos(e) * torch.sin(a), torch.sin(e)], dim=-1)


def test_the_map_adds_to_the_harmonics_and_closes_at_azimuth_180():
    directions = torch.nn.functional.normalize(torch.randn(50, 3, dtype=torch.float64), dim=1)
    harmonics = constant_background([0.2, 0.5, 0.9], 2).detach().double()
    plain = background_rgb(harmonics, directions)
    with_map = constant_background([0.2, 0.5, 0.9], 2, with_map=True).detach().double()
    assert with_map.shape == (9 + MAP_TEXELS, 3)
    torch.testing.assert_close(background_rgb(with_map, directions), plain)  # an empty map adds nothing

    texels = torch.randn(MAP_TEXELS, 3, dtype=torch.float64)
    # Either side of azimuth ±180° (the grids' left and right edges) lies the same colour.
    elevation = torch.linspace(-60, 60, 7)
    west = map_values(texels, _azimuth_elevation(torch.full((7,), 180.0), elevation))
    east = map_values(texels, _azimuth_elevation(torch.full((7,), -180.0), elevation))
    torch.testing.assert_close(west, east)
    # A texel's centre shows its value plus the coarser levels' (bilinear: the finest level's
    # texel centre, here one where the coarse grids are zero).
    rows, columns = MAP_LEVELS[-1]
    texels = torch.zeros(MAP_TEXELS, 3, dtype=torch.float64, requires_grad=True)
    row, column = 100, 300
    centre = _azimuth_elevation(
        torch.tensor([-180 + (column + 0.5) * 360 / columns]), torch.tensor([90 - (row + 0.5) * 180 / rows])
    )
    start = MAP_TEXELS - rows * columns
    with torch.no_grad():
        texels[start + row * columns + column] = torch.tensor([1.0, -2.0, 3.0])
    value = map_values(texels, centre)
    torch.testing.assert_close(value[0], torch.tensor([1.0, -2.0, 3.0], dtype=torch.float64))
    value.sum().backward()
    assert float(texels.grad[start + row * columns + column].sum()) == pytest.approx(3.0)


def test_few_directions_read_only_their_texels_and_sample_as_the_whole_grids_do(monkeypatch):
    import splat.background as background

    generator = torch.Generator().manual_seed(0)
    directions = torch.nn.functional.normalize(
        torch.randn(300, 3, dtype=torch.float64, generator=generator), dim=1
    )
    # The seam at azimuth ±180° and the clamped rows next to the poles (at a pole itself the
    # elevation's derivative is infinite either way).
    seam = _azimuth_elevation(
        torch.tensor([180.0, -180.0, 179.9, 0.0, 0.0]), torch.tensor([0.0, 30.0, -89.9, 89.95, -89.95])
    )
    directions = torch.cat([directions, seam.double()]).requires_grad_(True)
    texels = torch.randn(MAP_TEXELS, 3, dtype=torch.float64, generator=generator, requires_grad=True)
    results = []
    for below in (len(directions) + 1, 0):  # gathered, then the whole grids sampled
        monkeypatch.setattr(background, "GATHER_BELOW", below)
        value = map_values(texels, directions)
        gradients = torch.autograd.grad(
            (value * torch.arange(3.0, dtype=torch.float64)).sum(), (texels, directions)
        )
        results.append((value, *gradients))
    for gathered, sampled in zip(*results, strict=True):
        torch.testing.assert_close(gathered, sampled)


def test_the_map_learns_a_roofline_the_harmonics_blur():
    # Sky above a skyline that steps from 10° to 30° high at azimuth 90°: a sharp edge.
    grid = torch.meshgrid(torch.linspace(60, 120, 120), torch.linspace(0, 50, 100), indexing="ij")
    azimuth, elevation = (angle.reshape(-1) for angle in grid)
    directions = _azimuth_elevation(azimuth, elevation).float()
    sky, brick = torch.tensor([0.6, 0.75, 0.95]), torch.tensor([0.6, 0.3, 0.2])
    target = torch.where((elevation > torch.where(azimuth < 90, 10.0, 30.0))[:, None], sky, brick)
    errors = {}
    for with_map in (False, True):
        background = constant_background([0.5, 0.5, 0.5], 2, with_map=with_map)
        optimizer = torch.optim.Adam([background], lr=make_config().lr_background, eps=1e-15)
        for _ in range(150):
            loss = (background_rgb(background, directions) - target).abs().mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        errors[with_map] = float((background_rgb(background.detach(), directions) - target).abs().mean())
    assert errors[True] < 0.3 * errors[False], errors


def test_pixels_the_camera_cannot_back_project_get_no_background():
    fisheye = CameraModel("fisheye", 64, 48, np.array([[8.0, 0, 31.5], [0, 8, 23.5], [0, 0, 1]]), np.zeros(4))
    _, valid = camera_rays(fisheye, torch.device("cpu"), torch.float32)
    assert 0 < int(valid.sum()) < len(valid)  # the corners lie beyond 180°
    image = background_image(constant_background([0.5, 0.5, 0.5], 2), fisheye, torch.eye(4))
    assert not image.view(-1, 3)[~valid].any()
    torch.testing.assert_close(image.view(-1, 3)[valid], torch.full((int(valid.sum()), 3), 0.5))


def test_the_background_shows_where_no_triangle_is_and_not_where_they_are_opaque():
    model = lower_half_model()
    plain = model.render(CAMERA, T_CAM_WORLD)
    model.background = constant_background([0.1, 0.2, 0.9], 2)
    out = model.render(CAMERA, T_CAM_WORLD)
    sky, ground = out.alpha == 0, out.alpha > 0.998
    assert bool(sky[:23].all()) and bool(ground[25:].all())
    torch.testing.assert_close(out.rgb[sky], torch.tensor([0.1, 0.2, 0.9]).expand(int(sky.sum()), 3))
    torch.testing.assert_close(out.rgb[ground], torch.tensor(TRIANGLE_RGB).expand(int(ground.sum()), 3),
                               atol=2e-3, rtol=0)  # fmt: skip
    bg = background_image(model.background, CAMERA, T_CAM_WORLD)
    torch.testing.assert_close(out.rgb, plain.rgb + bg * (1 - plain.alpha)[..., None])
    for name in ("alpha", "accumulated_depth", "normal", "dominant", "max_weight"):
        assert torch.equal(getattr(out, name), getattr(plain, name)), name
    mask = torch.zeros(48, 64, dtype=torch.bool)
    mask[:, :32] = True
    masked = model.render(CAMERA, T_CAM_WORLD, background_mask=mask)
    torch.testing.assert_close(masked.rgb[:, :32], out.rgb[:, :32])
    torch.testing.assert_close(masked.rgb[:, 32:], plain.rgb[:, 32:])


def test_training_shows_the_background_only_above_the_topmost_lidar_returns():
    depth = torch.zeros(10, 40)
    depth[6, :20] = 2.0  # a low wall on the left, a return in every other column
    depth[3, 21::2] = 5.0  # a higher building on the right
    above = above_lidar(depth)
    assert bool(above[:6, :19].all()) and not above[6:, :19].any()  # gaps between returns bridged
    assert bool(above[:3, 23:].all()) and not above[3:, 23:].any()
    assert bool(above_lidar(torch.zeros(10, 40)).all())  # no return: all beyond the LiDAR


def test_the_background_also_shows_where_the_lidar_reached_nothing_between_its_returns():
    # Rings 4 px apart over 80 columns: an overpass (rows 8-20), sky beyond the LiDAR's range under
    # it (rows 21-59), the road (rows 60-100); below row 100 the camera sees beyond the LiDAR's field.
    depth = torch.zeros(120, 80)
    for row in [8, 12, 16, 20, *range(60, 101, 4)]:
        depth[row, ::2] = 10.0
    focal = 8 / math.tan(math.radians(2.0))  # the 2° empty window is 9 px wide
    beyond = beyond_range(depth, focal)
    assert bool(beyond[30:50, 10:70].all())  # the sky under the overpass
    assert not beyond[:21].any() and not beyond[60:].any()  # the overpass, the road and below it
    mask = scored_background_mask(depth, focal)
    assert not mask[8:21].any() and bool(mask[:8].all()) and bool(mask[30:50].all())
    # The gaps between rings stay black (a hole there is a hole), and so does a moving object's.
    depth[21:60, ::2] = torch.where(torch.arange(21, 60)[:, None] % 4 == 0, 10.0, 0.0)
    assert not beyond_range(depth, focal).any()
    depth[21:60, 30:50] = 0.0
    assert bool(beyond_range(depth, focal)[30:50, 36:44].all())
    moving = torch.zeros(120, 80, dtype=torch.bool)
    moving[21:60, 30:50] = True
    assert not beyond_range(depth, focal, moving).any()


@pytest.mark.parametrize("k", [3, 9, 11])
def test_the_masks_dilate_by_a_whole_square(k):
    from scipy.ndimage import binary_dilation

    from splat.background_mask import _dilate

    mask = torch.rand(37, 53, generator=torch.Generator().manual_seed(k)) > 0.97
    mask[0, 0] = mask[-1, 25] = True  # at the border too
    square = binary_dilation(mask.numpy(), structure=np.ones((k, k), dtype=bool))
    assert np.array_equal(_dilate(mask, k).numpy(), square)


def test_a_few_adam_steps_learn_a_sky_gradient():
    model = lower_half_model()
    rays, _ = camera_rays(CAMERA, torch.device("cpu"), torch.float32)
    up = (rays @ T_CAM_WORLD[:3, :3])[:, 2].clamp(min=0).view(48, 64, 1)
    horizon, zenith = torch.tensor([0.95, 0.95, 0.97]), torch.tensor([0.5, 0.7, 0.97])  # haze to blue
    sky = horizon + (zenith - horizon) * (up / 0.5).clamp(max=1)
    model.background = constant_background([0.5, 0.5, 0.5], 2)
    with torch.no_grad():
        out = model.render(CAMERA, T_CAM_WORLD)
    target = torch.where(out.alpha[..., None] > 0.5, out.rgb, sky)
    before = psnr(out.rgb[:24], target[:24])
    optimizer = torch.optim.Adam([model.background], lr=make_config().lr_background, eps=1e-15)
    for _ in range(60):
        loss = (model.render(CAMERA, T_CAM_WORLD).rgb - target).abs().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    with torch.no_grad():
        after = psnr(model.render(CAMERA, T_CAM_WORLD).rgb[:24], target[:24])
    assert before < 10 and after > 20, (before, after)


def test_models_round_trip_with_and_without_a_background(tmp_path):
    model = lower_half_model()
    save_model(model, tmp_path / "plain.pt")
    assert load_model(tmp_path / "plain.pt").background is None  # also what older files hold
    model.background = constant_background([0.4, 0.5, 0.6], 3)
    save_model(model, tmp_path / "sky.pt")
    loaded = load_model(tmp_path / "sky.pt")
    assert torch.equal(loaded.background, model.background.detach())
    assert loaded.background.is_leaf and loaded.background.requires_grad
    torch.testing.assert_close(loaded.render(CAMERA, T_CAM_WORLD).rgb, model.render(CAMERA, T_CAM_WORLD).rgb)

    model.background = constant_background([0.4, 0.5, 0.6], 2, with_map=True)
    save_model(model, tmp_path / "map.pt")
    torch.testing.assert_close(
        load_model(tmp_path / "map.pt").render(CAMERA, T_CAM_WORLD).rgb, model.render(CAMERA, T_CAM_WORLD).rgb
    )

    model.background_sphere = torch.tensor([1.0, 2.0, 3.0, 80.0])
    save_model(model, tmp_path / "sphere.pt")
    loaded = load_model(tmp_path / "sphere.pt")
    assert torch.equal(loaded.background_sphere, model.background_sphere)
    torch.testing.assert_close(loaded.render(CAMERA, T_CAM_WORLD).rgb, model.render(CAMERA, T_CAM_WORLD).rgb)
    assert load_model(tmp_path / "map.pt").background_sphere is None  # older files: at infinity

    state = model.to_state()
    for bad, message in ((torch.zeros(3), "shape"), (torch.tensor([0.0, 0, 0, -1]), "radius > 0"),
                         (torch.tensor([math.inf, 0, 0, 1]), "finite")):  # fmt: skip
        with pytest.raises(InputError, match=message) as error:
            TriangleModel.from_state({**state, "background_sphere": bad}, path=tmp_path / "m.pt")
        assert error.value.field == "background_sphere"
    for bad, message in ((torch.zeros(5, 3), "coefficients per channel"), (torch.zeros(9), "shape"),
                         ("sky", "tensor"), (torch.full((4, 3), math.nan), "NaN")):  # fmt: skip
        with pytest.raises(InputError, match=message) as error:
            TriangleModel.from_state({**state, "background": bad}, path=tmp_path / "m.pt")
        assert error.value.field == "background"


def test_row_surgery_leaves_the_background_and_its_adam_state_alone():
    model = lower_half_model()
    model.background = constant_background([0.5, 0.5, 0.5], 2)
    optimizer = make_optimizer(model, {"vertices": 0.01, "colors": 0.01, "opacity": 0.01, "background": 0.01})
    for p in model.trainable():
        p.grad = torch.ones_like(p)
    optimizer.step()
    background, moment = model.background, optimizer.state[model.background]["exp_avg"].clone()
    keep = torch.tensor([True, False, True])
    replace_rows(model, optimizer, keep, {k: v[:0].detach() for k, v in model.params.items()})
    assert model.n_triangles == 2 and model.background is background
    assert torch.equal(optimizer.state[background]["exp_avg"], moment)
    assert next(g for g in optimizer.param_groups if g["name"] == "background")["params"][0] is background


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return write_training_scene(tmp_path_factory.mktemp("scene"))


@pytest.mark.parametrize("background", ["map", "sh", "none"])
def test_training_with_and_without_a_background_exports_only_the_triangles(scene_dir, tmp_path, background):
    config = make_config(
        iterations=30, densify_every=10, densify_until=0.5, eval_every=10, checkpoint_every=10,
        init_max_triangles=500, ground_fill=False, drop_redundant_keyframes=False, background=background,
    )  # fmt: skip
    trainer = Trainer(scene_dir, tmp_path / "run", config, log=lambda *_: None)
    trainer.prepare(resume=False)
    masks = [view.background_mask for view in trainer.train_views]
    result = trainer.run(progress=False)
    model = load_model(tmp_path / "run" / "model.pt")
    if background != "none":
        rows = 9 + (MAP_TEXELS if background == "map" else 0)
        assert model.background.shape == (rows, 3) and bool(torch.isfinite(model.background).all())
        # The scene's LiDAR reaches a few metres: the sphere lies within tens of metres, not at infinity.
        assert 2.0 < float(model.background_sphere[3]) < 50.0
        # Beyond the corner's walls (the black top right of the views) is above every return.
        assert all(0 < int(mask.sum()) < mask.numel() for mask in masks)
    else:
        assert model.background is None and masks == [None] * len(masks)
    assert np.isfinite(result.test["test_psnr"])
    mesh = trimesh.load(tmp_path / "run" / "mesh.ply", force="mesh", process=False)
    assert len(mesh.faces) == model.n_triangles == result.n_triangles
    model.background = None
    export_mesh(
        model,
        tmp_path / "without",
        camera_only=camera_only_triangles(
            model.params["vertices"],
            lidar_points(trainer.scene, trainer.train_keyframes),
            trainer.train_keyframes,
        ),
    )
    assert (tmp_path / "without" / "mesh.ply").read_bytes() == (tmp_path / "run" / "mesh.ply").read_bytes()
