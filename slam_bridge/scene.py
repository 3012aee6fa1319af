"""The keyframe scene folder that ``lts prepare`` writes and training reads.

Layout of ``SCENE_DIR``::

    scene.json          format_version, camera (distortion-free pinhole), keyframes (name, t_ns,
                        T_world_cam, split), options (every PrepareConfig field), source
    images/NAME.png     undistorted colour image (8-bit)
    lidar/NAME.npy      LiDAR points (N, 3) float32 in the camera frame, deskewed, those that
                        project into the image (the scans between the neighbouring keyframes)
    normals/NAME.npy    normal prior (H, W, 3) float32, camera frame, facing the camera, 0 = none
    moving/NAME.npy     points of moving objects (N, 3) float32 in the camera frame, from the
                        sweeps taken with the image (only keyframes that have some)
    mesh.ply            warm-start mesh (world frame), copied from the SLAM folder
    sparse_points.ply   COLMAP points triangulated from the keyframes (optional, ``--sparse-points``)

World = the SLAM map frame; ``T_world_cam`` maps camera points to the world. A keyframe's LiDAR
depth image is made from its points when read: z-buffered, less the returns the camera cannot see
(:func:`~slam_bridge.depth_image.visible_returns`, window ``options.occlusion_window_px``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from rig.atomic_file import write_atomic
from rig.camera import CameraModel
from rig.data_file import load_data_file
from rig.errors import InputError
from rig.image_io import read_image
from rig.transforms import check_rigid
from slam_bridge.depth_image import moving_pixel_mask, visible_returns
from slam_bridge.prepare_config import PrepareConfig

SCENE_FILE = "scene.json"
SPARSE_POINTS_FILE = "sparse_points.ply"
LIDAR_DIR = "lidar"
MOVING_DIR = "moving"
#: Of those, the points at the top of the LiDAR's field (``slam_bridge.keyframe_lidar.at_field_top``).
MOVING_TOP_DIR = "moving_top"
#: Version of the folder layout; 1 kept depth images instead of LiDAR points and no options.
FORMAT_VERSION = 2
Split = Literal["train", "test"]


@dataclass(frozen=True)
class Keyframe:
    """One keyframe: its files are ``images/NAME.png``, ``lidar/NAME.npy``, ``normals/NAME.npy``."""

    name: str
    t_ns: int
    T_world_cam: np.ndarray
    split: Split


@dataclass(frozen=True)
class KeyframeLidar:
    """The LiDAR returns a keyframe's camera sees, one per pixel: flat pixel indices ``pixels``
    ``(M,)`` (``row * W + col``, increasing) and the camera-frame points there ``points`` ``(M, 3)``
    float32, for an image of ``shape`` ``(H, W)``."""

    pixels: np.ndarray
    points: np.ndarray
    shape: tuple[int, int]

    def depth(self) -> np.ndarray:
        """``(H, W)`` float32 depth (z in metres), 0 where there is no return."""
        depth = np.zeros(self.shape[0] * self.shape[1], dtype=np.float32)
        depth[self.pixels] = self.points[:, 2]
        return depth.reshape(self.shape)

    def point_index(self) -> np.ndarray:
        """``(H, W)`` int64 index into :attr:`points` of each pixel's return, -1 where there is none."""
        index = np.full(self.shape[0] * self.shape[1], -1, dtype=np.int64)
        index[self.pixels] = np.arange(len(self.pixels))
        return index.reshape(self.shape)


@dataclass(frozen=True)
class Scene:
    """A prepared scene: a pinhole camera, keyframes, the warm-start mesh path and the options that
    made it. Each keyframe's LiDAR file is read once (on first use) and kept."""

    root: Path
    camera: CameraModel
    keyframes: list[Keyframe]
    mesh_path: Path
    options: PrepareConfig
    sparse_points_path: Path | None = None
    _lidar: dict[str, KeyframeLidar] = field(default_factory=dict, init=False, repr=False, compare=False)

    def split(self, which: Split) -> list[Keyframe]:
        return [k for k in self.keyframes if k.split == which]

    def image(self, keyframe: Keyframe) -> np.ndarray:
        """``(H, W, 3)`` uint8 RGB image."""
        path = self.root / "images" / f"{keyframe.name}.png"
        image = read_image(path, what="the keyframe image")
        want = (self.camera.height, self.camera.width)
        if image.shape[:2] != want:  # it would be trained against the wrong pixels
            raise InputError(
                f"image is {image.shape[1]}x{image.shape[0]}, the scene's camera {want[1]}x{want[0]}",
                path=path,
                field="size",
            )
        return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)

    def lidar(self, keyframe: Keyframe) -> KeyframeLidar:
        """The LiDAR returns ``keyframe``'s camera sees (read from ``lidar/NAME.npy`` once)."""
        if keyframe.name not in self._lidar:
            points = _load_array(self.root / LIDAR_DIR / f"{keyframe.name}.npy", (None, 3))
            pixels, seen = visible_returns(points, self.camera, self.options.occlusion_window_px)
            shape = (self.camera.height, self.camera.width)
            self._lidar[keyframe.name] = KeyframeLidar(pixels, points[seen], shape)
        return self._lidar[keyframe.name]

    def depth(self, keyframe: Keyframe) -> np.ndarray:
        """``(H, W)`` float32 LiDAR depth in metres, 0 where there is no return."""
        return self.lidar(keyframe).depth()

    def moving_mask(self, keyframe: Keyframe) -> np.ndarray | None:
        """``(H, W)`` bool: the pixels near a moving object's point (``moving/NAME.npy``), and above
        those at the top of the LiDAR's field (``moving_top/NAME.npy``;
        :func:`~slam_bridge.depth_image.moving_pixel_mask`), or None when the keyframe has none."""
        path = self.root / MOVING_DIR / f"{keyframe.name}.npy"
        if not path.is_file():
            return None
        top = self.root / MOVING_TOP_DIR / f"{keyframe.name}.npy"
        at_top = _load_array(top, (None, 3)) if top.is_file() else None
        return moving_pixel_mask(_load_array(path, (None, 3)), self.camera, at_top)

    def normals(self, keyframe: Keyframe) -> np.ndarray:
        """``(H, W, 3)`` float32 camera-frame normal prior, zeros where there is none."""
        return _load_array(
            self.root / "normals" / f"{keyframe.name}.npy", (self.camera.height, self.camera.width, 3)
        )

    def sparse_points(self) -> tuple[np.ndarray, np.ndarray]:
        """COLMAP sparse points ``(N, 3)`` and colours ``(N, 3)`` uint8 RGB; an error naming the fix
        when the scene was prepared without them."""
        if self.sparse_points_path is None:
            raise InputError(
                "this scene has no sparse points; prepare it with lts prepare --sparse-points",
                path=self.root / SCENE_FILE,
                field="sparse_points",
            )
        import trimesh

        cloud = trimesh.load(self.sparse_points_path, process=False)
        colors = np.asarray(cloud.colors)[:, :3] if len(getattr(cloud, "colors", [])) else np.zeros((0, 3))
        return np.asarray(cloud.vertices, dtype=np.float64), colors.astype(np.uint8)


def _load_array(path: Path, shape: tuple[int | None, ...]) -> np.ndarray:
    """A numeric ``.npy`` of ``shape`` (None: any length) as float32, finite everywhere."""
    try:
        array = np.load(path)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot read array ({exc})", path=path) from None
    if array.ndim != len(shape) or any(w not in (None, n) for n, w in zip(array.shape, shape, strict=True)):
        expected = ", ".join("N" if w is None else str(w) for w in shape)
        raise InputError(f"expected shape ({expected}), got {array.shape}", path=path, field="shape")
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise InputError(f"expected numbers, got dtype {array.dtype}", path=path, field="dtype")
    array = array.astype(np.float32, copy=False)
    if not np.all(np.isfinite(array)):
        raise InputError("holds NaN or Inf (0 marks no data)", path=path, field="values")
    return array


def write_scene_index(
    root: Path,
    camera: CameraModel,
    keyframes: list[Keyframe],
    options: PrepareConfig,
    source: dict,
    sparse_points: str | None = None,
) -> None:
    """Write ``scene.json`` (atomically) for the keyframes whose files are already written, with the
    ``options`` that made them."""
    data = {
        "format_version": FORMAT_VERSION,
        "camera": camera.to_dict(),
        "mesh": "mesh.ply",
        "sparse_points": sparse_points,
        "keyframes": [
            {
                "name": k.name,
                "t_ns": int(k.t_ns),
                "T_world_cam": np.asarray(k.T_world_cam).tolist(),
                "split": k.split,
            }
            for k in keyframes
        ],
        "options": options.to_json(),
        "source": source,
    }
    write_atomic(root / SCENE_FILE, json.dumps(data, indent=1))


def load_scene(root: str | Path) -> Scene:
    """Read a scene folder written by ``lts prepare``; errors name the file and field."""
    root = Path(root)
    index = root / SCENE_FILE
    if not index.is_file():
        raise InputError("no scene.json: not a scene folder (make one with lts prepare)", path=root)
    data = load_data_file(index, "JSON", "scene index")
    if not isinstance(data, dict):
        raise InputError("expected a JSON object with camera and keyframes", path=index)
    version = data.get("format_version", 1)
    if version != FORMAT_VERSION:
        raise InputError(
            f"scene format version {version}, this lts reads version {FORMAT_VERSION}: re-run lts prepare",
            path=index,
            field="format_version",
        )
    camera = CameraModel.from_dict(data.get("camera"), path=str(index))
    if camera.model != "pinhole" or np.any(camera.dist):
        raise InputError(
            "a scene's images are undistorted: expected a pinhole camera without distortion",
            path=index,
            field="camera",
        )
    entries = data.get("keyframes") or []
    if not isinstance(entries, list):
        raise InputError(f"expected a list, got {type(entries).__name__}", path=index, field="keyframes")
    keyframes = []
    for i, entry in enumerate(entries):
        try:
            t_ns = entry["t_ns"]
            if isinstance(t_ns, float) and not t_ns.is_integer():
                raise ValueError(f"t_ns {t_ns} is not whole nanoseconds")
            keyframe = Keyframe(str(entry["name"]), int(t_ns), entry["T_world_cam"], entry["split"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"keyframe {i} is malformed ({exc})", path=index, field="keyframes") from None
        if keyframe.split not in ("train", "test"):
            raise InputError(
                f"keyframe {i}: split {keyframe.split!r}; expected train or test",
                path=index,
                field="keyframes",
            )
        name = keyframe.name
        if not name or name in (".", "..") or "/" in name or "\\" in name:
            raise InputError(
                f"keyframe {i}: name {name!r} is not a plain file name", path=index, field="keyframes"
            )
        T = check_rigid(keyframe.T_world_cam, field=f"keyframes[{i}].T_world_cam", path=str(index))
        keyframes.append(Keyframe(name, keyframe.t_ns, T, keyframe.split))
    if not keyframes:
        raise InputError("no keyframes", path=index, field="keyframes")
    options = PrepareConfig.from_json(data.get("options"), index)
    sparse = data.get("sparse_points")
    mesh = root / data.get("mesh", "mesh.ply")
    return Scene(root, camera, keyframes, mesh, options, root / sparse if sparse else None)
