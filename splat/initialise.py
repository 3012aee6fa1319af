"""The initial triangles of each method: the decoupled SLAM mesh (ours), or a Delaunay
tetrahedralisation of SfM points (the TS+ baseline) or of LiDAR points (ablation)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import trimesh
from torch import Tensor

from rig.mesh_io import load_mesh
from rig.transforms import invert
from slam_bridge.scene import Keyframe, Scene
from splat.at_infinity import explained_at_infinity
from splat.background import background_sphere, constant_background
from splat.camera_only import camera_only_seeds
from splat.config import TrainConfig
from splat.init_mesh import NO_FLOOR, decouple_and_scale, ground_fill, simplify, up_direction
from splat.lidar_fill import lidar_fill
from splat.lidar_snap import snap_to_lidar
from splat.model import TriangleModel
from splat.plane_sweep import keyframe_sweeps, swept_cells
from splat.strategy.variance import lidar_returns
from splat.upward_extension import upward_extension
from splat.views import View

GREY = 0.5


@dataclass(frozen=True)
class Initialisation:
    """Triangles ``(F, 3, 3)``, their colours ``(F, 3, 3)`` in [0, 1] (None: to be projected from
    the views), and one line per decision taken."""

    triangles: np.ndarray
    colors: np.ndarray | None
    notes: list[str]


def _scaled(triangles: np.ndarray, scale: float) -> np.ndarray:
    """Independent triangles ``(F, 3, 3)`` scaled about their centroids."""
    corners = triangles.reshape(-1, 3)
    return decouple_and_scale(corners, np.arange(len(corners)).reshape(-1, 3), scale)


def _mesh_init(
    scene: Scene,
    train: list[Keyframe],
    config: TrainConfig,
    returns: list[np.ndarray],
    floor: np.ndarray | None,
) -> Initialisation:
    mesh = full_mesh = load_mesh(scene.mesh_path)
    notes = []
    if len(mesh.faces) > config.init_max_triangles:
        notes.append(
            f"warm-start mesh simplified from {len(mesh.faces)} to {config.init_max_triangles} faces"
        )
        mesh = simplify(mesh, config.init_max_triangles)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if config.init_noise_m > 0:
        rng = np.random.default_rng(config.seed)
        vertices = vertices + rng.normal(0.0, config.init_noise_m, vertices.shape)
        notes.append(f"Gaussian noise of {config.init_noise_m:g} m added to the warm-start vertices")
    if config.snap_to_lidar:
        snap = snap_to_lidar(vertices, scene, train)
        vertices = snap.vertices
        notes.append(snap.reason)
    mesh = trimesh.Trimesh(vertices, mesh.faces, process=False)
    triangles = decouple_and_scale(mesh.vertices, np.asarray(mesh.faces), config.init_scale)
    lidar = np.concatenate(returns)
    poses = np.stack([k.T_world_cam for k in train])
    up = up_direction(poses)
    if config.lidar_fill:
        fill_returns = lidar_fill(mesh, returns, poses[:, :3, 3])
        notes.append(fill_returns.reason)
        triangles = np.concatenate([triangles, fill_returns.triangles])
    if config.ground_fill and floor is None:
        notes.append(NO_FLOOR)
    elif config.ground_fill:
        fill = ground_fill(
            mesh, scene.camera, poses, lidar, config.ground_cell_m,
            complete_hidden=config.complete_hidden_floor, enclosing=full_mesh, plane=floor,
        )  # fmt: skip
        notes.append(fill.reason)
        # Seen cells are scaled like the mesh faces, to overlap while they train; hidden ones never
        # train, so they keep their size (scaled, they would reach past the walls).
        triangles = np.concatenate([triangles, _scaled(fill.triangles, config.init_scale), fill.hidden])
        up = up if fill.plane is None else fill.plane[:3]
    depths = [scene.depth(k) for k in train]
    images = [scene.image(k) for k in train]
    sweeps = None
    if config.plane_sweep:
        sweeps = keyframe_sweeps(scene.camera, images, poses, depths, [scene.moving_mask(k) for k in train])
    to_background = 0
    if config.upward_extension:
        lidars = [scene.lidar(k) for k in train]
        extension = upward_extension(scene.camera, poses, lidars, up, mesh, sweeps)
        notes.append(extension.reason)
        strips = extension.triangles
        if config.background != "none":
            explained = explained_at_infinity(strips.mean(axis=1), scene.camera, images, poses)
            strips, to_background = strips[~explained], to_background + int(explained.sum())
        triangles = np.concatenate([triangles, _scaled(strips, config.init_scale)])
    colors = None if config.init_color == "project" else np.full_like(triangles, GREY)
    if sweeps is not None:
        # Cells the extension made already explain what they cover.
        known = np.concatenate([lidar, strips.mean(axis=1)]) if config.upward_extension else lidar
        planes = extension.planes if config.upward_extension else None
        cells = swept_cells(scene.camera, images, poses, depths, sweeps, known, planes)
        notes.append(cells.reason)
        kept = np.ones(len(cells.triangles), dtype=bool)
        if config.background != "none":
            kept = ~explained_at_infinity(cells.triangles.mean(axis=1), scene.camera, images, poses)
            to_background += int((~kept).sum())
        triangles = np.concatenate([triangles, _scaled(cells.triangles[kept], config.init_scale)])
        colors = None if colors is None else np.concatenate([colors, cells.colors[kept]])
    if to_background:
        notes.append(
            f"{to_background} camera-only triangles left to the background: the images agree at least "
            "twice as well along their directions, as if they lay at infinity (sky, far structure; "
            "splat.at_infinity)"
        )
    if config.camera_only_seeds and scene.sparse_points_path is None:
        notes.append("no camera-only triangles: the scene has no sparse points (lts prepare --sparse-points)")
    elif config.camera_only_seeds:
        points, point_colors = scene.sparse_points()
        seeds = camera_only_seeds(points, point_colors, lidar, scene.camera, poses, depths)
        notes.append(seeds.reason)
        triangles = np.concatenate([triangles, seeds.triangles])
        colors = None if colors is None else np.concatenate([colors, seeds.colors])
    return Initialisation(triangles, colors, notes)


def initial_triangles(
    scene: Scene,
    train: list[Keyframe],
    config: TrainConfig,
    returns: list[np.ndarray],
    floor: np.ndarray | None,
) -> Initialisation:
    """The initial triangles of ``config.init`` for ``scene`` (``train``: the training keyframes,
    ``returns``: the world points ``(N_k, 3)`` of each one's LiDAR returns,
    :func:`~splat.lidar_points.keyframe_lidar_points`; ``floor``: the scene's floor plane ``(4,)``,
    :func:`~splat.init_mesh.fit_floor_plane`, or None)."""
    if config.init == "mesh":
        return _mesh_init(scene, train, config, returns, floor)
    from splat.init_delaunay import delaunay_triangles

    if config.init == "delaunay-sfm":
        points, colors = scene.sparse_points()
        triangles, tri_colors = delaunay_triangles(points, colors / 255.0, seed=config.seed)
        return Initialisation(triangles, tri_colors, [f"Delaunay of {len(points)} SfM points"])
    points = np.concatenate(returns)
    triangles, _ = delaunay_triangles(
        points, np.full_like(points, GREY), max_points=config.lidar_init_points, seed=config.seed
    )
    note = f"Delaunay of {min(len(points), config.lidar_init_points)} of {len(points)} LiDAR points"
    return Initialisation(triangles, None, [note])


@torch.no_grad()
def project_colors(model: TriangleModel, views: list[View], camera, backend: str = "auto") -> int:
    """Set each triangle's colour to the mean image colour over the pixels it dominates in
    ``views`` (first renders of the initial, grey model); returns how many triangles got one."""
    n = model.n_triangles
    total = torch.zeros(n, 3, dtype=torch.float64)
    count = torch.zeros(n, dtype=torch.float64)
    for view in views:
        out = model.render(camera, view.T_cam_world, backend=backend)
        owned = out.dominant >= 0
        ids = out.dominant[owned].cpu()
        count += torch.bincount(ids, minlength=n).double()
        pixels = view.image[owned].cpu().double()
        for c in range(3):
            total[:, c] += torch.bincount(ids, weights=pixels[:, c], minlength=n)
    seen = count > 0
    mean = torch.full((n, 3), GREY, dtype=torch.float64)
    mean[seen] = total[seen] / count[seen, None]
    colors = torch.logit(mean.clamp(0.02, 0.98)).to(model.params["colors"])
    model.params["colors"].data.copy_(colors[:, None, :].expand(n, 3, 3))
    return int(seen.sum())


def mean_image_color(views: list[View]) -> Tensor:
    """``(3,)`` mean RGB over every pixel of ``views`` (mid grey without views)."""
    if not views:
        return torch.full((3,), GREY)
    return torch.stack([view.image.mean(dim=(0, 1)) for view in views]).mean(dim=0).cpu()


def build_model(
    init: Initialisation, config: TrainConfig, views: list[View], camera, log: Callable[[str], None]
) -> TriangleModel:
    """The initial :class:`TriangleModel` on ``config.device`` (colours projected when asked; with
    a background, one of the views' mean colour)."""
    triangles = torch.as_tensor(init.triangles, dtype=torch.float32)
    colors = (
        torch.full_like(triangles, GREY)
        if init.colors is None
        else torch.as_tensor(init.colors).to(triangles)
    )
    model = TriangleModel.from_triangles(
        triangles.to(config.device), colors.to(config.device), config.init_opacity, config.sigma_start
    )
    if init.colors is None and config.init_color == "project":
        coloured = project_colors(model, views, camera)
        log(f"colours of {coloured} of {model.n_triangles} triangles projected from {len(views)} views")
    if config.background != "none":
        # The best constant before anything is known: pixels the triangles leave uncovered (or,
        # while they are translucent, partly covered) then start near the images' average.
        rgb = mean_image_color(views)
        with_map = config.background == "map"
        model.background = constant_background(
            rgb, config.background_sh_degree, with_map=with_map, dtype=triangles.dtype, device=config.device
        )
        sphere = views_background_sphere(views)
        if sphere is not None:
            model.background_sphere = torch.as_tensor(sphere, dtype=triangles.dtype, device=config.device)
        kind = " and a map down to 0.7°" if with_map else ""
        where = "at infinity" if sphere is None else f"on a sphere of {sphere[3]:.0f} m about the cameras"
        log(f"background: degree-{config.background_sh_degree} harmonics{kind} {where}, starting at the "
            f"training images' mean colour ({', '.join(f'{c:.2f}' for c in rgb.tolist())})")  # fmt: skip
    return model


#: Below this fraction of the training pixels showing the background, it stays at infinity.
MIN_SPHERE_BACKGROUND_FRACTION = 0.01


def views_background_sphere(views: list[View]) -> np.ndarray | None:
    """:func:`~splat.background.background_sphere` ``(4,)`` of ``views``' cameras and LiDAR depths,
    or None (at infinity): without depths, or where the background shows at fewer than
    :data:`MIN_SPHERE_BACKGROUND_FRACTION` of the views' pixels (their ``background_mask``).

    Indoors the LiDAR reaches nearly every surface the camera sees (the demo room shows the
    background at 0.015 % of its training pixels): there is no far structure for a sphere to place,
    and the demo room's PSNR was 0.04 dB lower with one (mean of five seeds).
    """
    pixels = [v.image.shape[0] * v.image.shape[1] for v in views]
    masks = [v.background_mask for v in views]
    shown = [n if m is None else int(m.sum()) for m, n in zip(masks, pixels, strict=True)]
    if sum(shown) < MIN_SPHERE_BACKGROUND_FRACTION * sum(pixels):
        return None
    poses = [view.T_cam_world.detach().cpu().numpy() for view in views]
    centres = invert(np.array(poses).reshape(-1, 4, 4))[:, :3, 3]
    depths = [v.depth[lidar_returns(v.depth)].detach().cpu().numpy() for v in views if v.depth is not None]
    return background_sphere(centres, np.concatenate(depths) if depths else np.zeros(0))
