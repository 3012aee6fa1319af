"""Camera simulation: ray-cast one image per pose through the (distorted) camera model.

Each pixel's ray is the camera model's back-projection of the pixel centre, so the image comes
out distorted exactly as the model says (pinhole with radial-tangential distortion, or fisheye)
without resampling. Texture lookups pick a mip level from the pixel's footprint on the surface.
"""

from __future__ import annotations

import numpy as np

from rig.camera import CameraModel
from rig.sim.raycast import Hits
from rig.sim.world import World, sky_colour

#: Footprint stretch is capped at this grazing angle's cosine (limits blur at grazing incidence).
MIN_COS_INCIDENCE = 0.25


def pixel_footprint(
    normals: np.ndarray, directions: np.ndarray, distance: np.ndarray, pixel_angle: float
) -> np.ndarray:
    """Size (m) ``(N,)`` of a pixel of angular size ``pixel_angle`` on surfaces with unit ``normals``
    ``(N, 3)``, seen along unit ``directions`` ``(N, 3)`` from ``distance`` ``(N,)`` away: what picks
    the texture's mip level."""
    cos = np.abs(np.einsum("ij,ij->i", normals, directions))
    return distance * pixel_angle / np.maximum(cos, MIN_COS_INCIDENCE)


class CameraSimulator:
    """Renders images and depth of a :class:`World` for one camera model.

    Args:
        camera: intrinsics and distortion (pixels the model cannot back-project stay black).
    """

    def __init__(self, camera: CameraModel) -> None:
        self.camera = camera
        u, v = np.meshgrid(
            np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64)
        )
        rays = camera.unproject(np.column_stack([u.ravel(), v.ravel()]))
        self.valid = np.all(np.isfinite(rays), axis=1)
        #: ``(H*W, 3)`` unit ray directions in the camera frame (valid pixels only).
        self.directions = rays[self.valid] / np.linalg.norm(rays[self.valid], axis=1, keepdims=True)
        self.pixel_angle = 1.0 / camera.fx

    def cast(self, world: World, T_world_cam: np.ndarray, t_s: float = 0.0) -> tuple[Hits, np.ndarray]:
        """What the rays of the valid pixels (row-major) of the view from pose ``T_world_cam``
        ``(4, 4)`` at time ``t_s`` hit, misses included, and the rays' unit world directions
        ``(P, 3)``."""
        directions = self.directions @ T_world_cam[:3, :3].T
        return world.raycaster.cast(T_world_cam[:3, 3], directions, t_s), directions

    def render(
        self, world: World, T_world_cam: np.ndarray, t_s: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Render the view from pose ``T_world_cam`` ``(4, 4)`` at time ``t_s`` (s; where the
        world's movers are).

        Returns:
            ``(H, W, 3)`` float32 RGB in [0, 1] (the sky, or black, where nothing was hit) and
            ``(H, W)`` float64 depth (camera-frame z, m; NaN where nothing was hit).
        """
        hits, directions = self.cast(world, T_world_cam, t_s)
        index = np.flatnonzero(self.valid)
        n_pix = self.camera.width * self.camera.height
        rgb = np.zeros((n_pix, 3), dtype=np.float32)
        if not hits.hit.all():  # closed scenes hit everywhere; skip the copies then
            ok = hits.hit
            if world.sky:
                rgb[index[~ok]] = sky_colour(directions[~ok])
            hits, directions, index = hits.subset(ok), directions[ok], index[ok]
        footprint = pixel_footprint(hits.normal, directions, hits.distance, self.pixel_angle)
        depth = np.full(n_pix, np.nan)
        rgb[index] = world.appearance.colour(hits, footprint)
        depth[index] = hits.distance * (directions @ T_world_cam[:3, 2])
        shape = (self.camera.height, self.camera.width)
        return rgb.reshape(*shape, 3), depth.reshape(shape)


def to_bgr8(
    rgb: np.ndarray, rng: np.random.Generator, noise_sigma: float = 0.0, exposure_jitter: float = 0.0
) -> np.ndarray:
    """8-bit BGR image ``(H, W, 3)`` from float RGB ``(H, W, 3)``, with optional exposure gain
    jitter (relative std) and pixel noise (std in grey levels)."""
    image = rgb[..., ::-1] * 255.0
    if exposure_jitter > 0:
        image = image * (1.0 + exposure_jitter * rng.standard_normal())
    if noise_sigma > 0:
        image = image + noise_sigma * rng.standard_normal(image.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)
