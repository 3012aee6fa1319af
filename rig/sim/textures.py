"""Procedural, seamlessly tiling material textures with detail at several scales.

Each material is a colour image that tiles a square of ``period_m`` metres, built from spectrally
shaped (1/f) noise, which has structure at every scale, plus a material-specific pattern (tiles,
planks, bricks, weave), or from a photograph that scikit-image ships in its wheel (brick, gravel,
grass and a few pictures), so that scenes also have the texture statistics of real surfaces.
Lookups use a mip pyramid chosen by the pixel footprint so distant surfaces do not alias.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: Texture size in texels (a power of two, for the mip pyramid).
TEXTURE_SIZE = 512


@dataclass(frozen=True)
class Material:
    """Appearance and LiDAR reflectivity of one surface kind.

    Attributes:
        name: material name (``plaster``, ``tiles``, ...).
        colour: ``(3,)`` base RGB in [0, 1].
        pattern: ``noise``, ``tiles``, ``planks``, ``bricks``, ``weave``, or ``photo`` (a picture
            from ``skimage.data``; :data:`PHOTOS` says which and how it is laid).
        period_m: side of the square the texture tiles, in metres.
        contrast: amplitude of the multi-scale noise (a grey photo's: of its brightness) around
            the base colour.
        reflectivity: LiDAR reflectivity in [0, 1] (drives intensity).
    """

    name: str
    colour: tuple[float, float, float]
    pattern: str
    period_m: float
    contrast: float
    reflectivity: float


#: The materials procedural scenes are made of; a face's material is an index into this tuple.
MATERIALS: tuple[Material, ...] = (
    Material("plaster", (0.80, 0.76, 0.68), "noise", 2.0, 0.55, 0.70),
    Material("tiles", (0.55, 0.52, 0.48), "tiles", 2.0, 0.30, 0.45),
    Material("ceiling", (0.88, 0.88, 0.86), "noise", 2.0, 0.30, 0.80),
    Material("wood", (0.55, 0.36, 0.20), "planks", 1.0, 0.35, 0.35),
    Material("fabric", (0.25, 0.35, 0.55), "weave", 0.5, 0.40, 0.25),
    Material("cardboard", (0.65, 0.50, 0.32), "noise", 1.0, 0.45, 0.50),
    Material("metal", (0.45, 0.46, 0.50), "noise", 0.5, 0.20, 0.90),
    Material("bricks", (0.62, 0.30, 0.22), "bricks", 2.0, 0.30, 0.40),
    Material("concrete", (0.58, 0.58, 0.56), "noise", 2.0, 0.55, 0.55),
    # Matte print of a calibration board (appended: earlier materials keep their textures).
    Material("board_black", (0.06, 0.06, 0.06), "noise", 1.0, 0.0, 0.10),
    Material("board_white", (0.90, 0.90, 0.88), "noise", 1.0, 0.0, 0.85),
    # The street (appended for the same reason). Vehicle paints are near uniform: textures are
    # mapped in world coordinates, so a moving vehicle's would slide over it.
    Material("asphalt", (0.30, 0.30, 0.32), "noise", 2.0, 0.40, 0.15),
    Material("foliage", (0.24, 0.42, 0.16), "noise", 1.0, 0.65, 0.50),
    Material("glass", (0.16, 0.19, 0.23), "noise", 2.0, 0.10, 0.08),
    Material("paint_red", (0.70, 0.13, 0.10), "noise", 8.0, 0.04, 0.60),
    Material("paint_white", (0.86, 0.86, 0.84), "noise", 8.0, 0.04, 0.80),
    Material("paint_blue", (0.14, 0.24, 0.58), "noise", 8.0, 0.04, 0.50),
    # The office (appended): photographs. A grey one is tinted with the colour; a colour one
    # (a poster, a monitor's picture) is shown as it is.
    Material("brick_photo", (0.66, 0.40, 0.32), "photo", 1.2, 1.0, 0.40),
    Material("carpet", (0.40, 0.42, 0.48), "photo", 0.8, 1.0, 0.30),
    Material("leaves", (0.24, 0.48, 0.16), "photo", 0.3, 1.2, 0.50),
    Material("poster_astronaut", (1.0, 1.0, 1.0), "photo", 0.8, 1.0, 0.60),
    Material("poster_coffee", (1.0, 1.0, 1.0), "photo", 0.8, 1.0, 0.60),
    Material("poster_chelsea", (1.0, 1.0, 1.0), "photo", 0.8, 1.0, 0.60),
    Material("screen", (1.0, 1.0, 1.0), "photo", 0.5, 1.0, 0.10),
)
MATERIAL_IDS = {m.name: i for i, m in enumerate(MATERIALS)}
#: The picture of each ``photo`` material (a ``skimage.data`` function) and whether it is laid
#: mirrored 2 × 2, which makes a texture photograph tile without seams (a picture is laid once).
PHOTOS = {
    "brick_photo": ("brick", True),
    "carpet": ("gravel", True),
    "leaves": ("grass", True),
    "poster_astronaut": ("astronaut", False),
    "poster_coffee": ("coffee", False),
    "poster_chelsea": ("chelsea", False),
    "screen": ("rocket", False),
}


def fractal_noise(rng: np.random.Generator, size: int, beta: float = 1.6) -> np.ndarray:
    """Seamlessly tiling noise ``(size, size)`` in [-1, 1] with power spectrum ∝ 1/f^beta.

    Filtering white noise in the Fourier domain makes it periodic, so the texture tiles without
    seams, and the 1/f spectrum gives detail at every scale.
    """
    white = rng.standard_normal((size, size))
    radius = np.hypot(np.fft.fftfreq(size)[:, None], np.fft.rfftfreq(size)[None, :])
    radius[0, 0] = 1.0
    spectrum = np.fft.rfft2(white) / radius ** (beta / 2)  # power ∝ amplitude²
    spectrum[0, 0] = 0.0
    noise = np.fft.irfft2(spectrum, s=(size, size))
    return noise / np.abs(noise).max()


def _grid_lines(size: int, cells: int, width: float) -> np.ndarray:
    """``(size,)`` profile that is 1 on grid lines (``cells`` per period) and 0 between them."""
    x = (np.arange(size) + 0.5) / size * cells
    distance = np.abs(x - np.round(x))
    return (distance < width / 2).astype(np.float64)


def _pattern(material: Material, rng: np.random.Generator, size: int) -> np.ndarray:
    """Material-specific brightness pattern ``(size, size)`` around 0."""
    v, u = np.mgrid[0:size, 0:size] / size
    if material.pattern == "tiles":
        cells = 4
        lines = np.maximum(_grid_lines(size, cells, 0.04)[None, :], _grid_lines(size, cells, 0.04)[:, None])
        tile_shade = rng.uniform(-0.25, 0.25, (cells, cells))
        shade = tile_shade[(v * cells).astype(int) % cells, (u * cells).astype(int) % cells]
        return shade - 0.8 * lines
    if material.pattern == "planks":
        planks = 8
        index = (v * planks).astype(int) % planks
        grain = np.sin(2 * np.pi * (u * 6 + 0.4 * fractal_noise(rng, size, 2.2)) * 3)
        return (
            0.3 * grain
            + rng.uniform(-0.3, 0.3, planks)[index]
            - 0.7 * _grid_lines(size, planks, 0.03)[:, None]
        )
    if material.pattern == "bricks":
        rows = 16
        row = (v * rows).astype(int)
        shifted = (u * 8 + 0.5 * (row % 2)) % 1.0 * 8
        mortar = np.maximum(
            _grid_lines(size, rows, 0.12)[:, None], (np.abs(shifted - np.round(shifted)) < 0.05)
        )
        brick_id = (row * 16 + (u * 8 + 0.5 * (row % 2)).astype(int)) % 256
        return rng.uniform(-0.3, 0.3, 256)[brick_id] + 0.9 * mortar
    if material.pattern == "weave":
        return 0.5 * np.sin(2 * np.pi * u * 64) * np.sin(2 * np.pi * v * 64)
    return np.zeros((size, size))


def photo_texture(material: Material, size: int = TEXTURE_SIZE) -> np.ndarray:
    """RGB texture ``(size, size, 3)`` float32 in [0, 1] of a ``photo`` material: the centre square
    of its picture, upright on walls (texture rows run up), a grey one tinted by the colour."""
    import skimage.data  # here: most importers of this module build no texture

    name, mirrored = PHOTOS[material.name]
    picture = np.asarray(getattr(skimage.data, name)(), dtype=np.float32) / 255.0
    h, w = picture.shape[:2]
    side = min(h, w)
    square = picture[(h - side) // 2 : (h - side) // 2 + side, (w - side) // 2 : (w - side) // 2 + side]
    tile = size // 2 if mirrored else size
    square = cv2.resize(square, (tile, tile), interpolation=cv2.INTER_AREA)
    if mirrored:
        row = np.concatenate([square, square[:, ::-1]], axis=1)
        square = np.concatenate([row, row[::-1]], axis=0)
    square = square[::-1]
    if square.ndim == 2:
        brightness = 1.0 + material.contrast * (square / square.mean() - 1.0)
        square = np.asarray(material.colour) * brightness[..., None]
    return np.ascontiguousarray(np.clip(square, 0.0, 1.0), dtype=np.float32)


def material_texture(material: Material, rng: np.random.Generator, size: int = TEXTURE_SIZE) -> np.ndarray:
    """RGB texture ``(size, size, 3)`` float32 in [0, 1] for one material."""
    if material.pattern == "photo":
        return photo_texture(material, size)
    coarse = fractal_noise(rng, size, 2.4)  # large stains and shading variations
    fine = fractal_noise(rng, size, 1.2)  # grain
    brightness = 0.6 * coarse + 0.4 * fine + _pattern(material, rng, size)
    tint = 1.0 + 0.15 * fractal_noise(rng, size, 2.0)[..., None] * rng.uniform(-1, 1, 3)
    colour = np.asarray(material.colour) * (1.0 + material.contrast * brightness)[..., None] * tint
    return np.clip(colour, 0.0, 1.0).astype(np.float32)


def mip_pyramid(texture: np.ndarray) -> list[np.ndarray]:
    """Box-filtered mip levels of a ``(S, S, 3)`` texture, down to 4×4 texels."""
    levels = [texture]
    while levels[-1].shape[0] > 4:
        levels.append(cv2.resize(levels[-1], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA))
    return levels


class TextureBank:
    """Mip-mapped textures of :data:`MATERIALS`, looked up by world-space planar mapping.

    All mip levels of all materials live in one flat texel array, so a lookup is one gather.

    Args:
        seed: seeds the noise, so a scene's appearance is reproducible.
    """

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(seed)
        pyramids = [mip_pyramid(material_texture(m, rng)) for m in MATERIALS]
        self.n_levels = len(pyramids[0])
        #: ``(L,)`` side of each mip level in texels.
        self.level_size = np.array([level.shape[0] for level in pyramids[0]], dtype=np.int32)
        #: ``(L, M)`` offset of each (level, material) image in :attr:`texels`.
        self.offset = np.zeros((self.n_levels, len(MATERIALS)), dtype=np.int64)
        flat, start = [], 0
        for lv in range(self.n_levels):
            for m, pyramid in enumerate(pyramids):
                self.offset[lv, m] = start
                flat.append(pyramid[lv].reshape(-1, 3))
                start += len(flat[-1])
        #: ``(T, 3)`` float32 texels of every level of every material.
        self.texels = np.concatenate(flat)
        self.periods = np.array([m.period_m for m in MATERIALS])
        self.reflectivity = np.array([m.reflectivity for m in MATERIALS], dtype=np.float32)

    def sample(
        self, material: np.ndarray, points: np.ndarray, normals: np.ndarray, footprint_m: np.ndarray | float
    ) -> np.ndarray:
        """Colours ``(N, 3)`` RGB in [0, 1] of surface points.

        Args:
            material: ``(N,)`` int material indices.
            points: ``(N, 3)`` world points; the two coordinates across the dominant axis of the
                normal are the texture coordinates (planar mapping, exact for axis-aligned scenes).
            normals: ``(N, 3)`` surface normals.
            footprint_m: size of the area one sample stands for (a pixel's footprint), scalar or
                ``(N,)``; picks the mip level.
        """
        axis = np.argmax(np.abs(normals), axis=1)
        x, y, z = points[:, 0], points[:, 1], points[:, 2]
        period = self.periods[material]
        u = np.where(axis == 0, y, x) / period
        v = np.where(axis == 2, y, z) / period
        level = np.log2(np.maximum(np.asarray(footprint_m) * (TEXTURE_SIZE / period), 1.0))
        level = np.minimum(np.rint(level).astype(np.int32), self.n_levels - 1)
        size = self.level_size[level]
        mask = size - 1  # sizes are powers of two: wrapping is a bitwise and (also for negatives)
        col = np.floor(u * size).astype(np.int32) & mask
        row = np.floor(v * size).astype(np.int32) & mask
        return self.texels[self.offset[level, material] + row * size + col]
