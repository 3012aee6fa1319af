"""The keyframe scene folder that ``lts prepare`` writes and training reads.

Layout of ``SCENE_DIR``::

    scene.json          camera (distortion-free pinhole), keyframes (name, t_ns, T_world_cam, split)
    images/NAME.png     undistorted colour image (8-bit)
    depth/NAME.npy      LiDAR depth (H, W) float32 metres along camera z, 0 = no return
    normals/NAME.npy    normal prior (H, W, 3) float32, camera frame, facing the camera, 0 = none
    mesh.ply            warm-start mesh (world frame), copied from the SLAM folder
    sparse_points.ply   COLMAP points triangulated from the keyframes (optional, ``--sparse-points``)

World = the SLAM map frame; ``T_world_cam`` maps camera points to the world.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError

SCENE_FILE = "scene.json"
SPARSE_POINTS_FILE = "sparse_points.ply"
Split = Literal["train", "test"]


@dataclass(frozen=True)
class Keyframe:
    """One keyframe: its files are ``images/NAME.png``, ``depth/NAME.npy``, ``normals/NAME.npy``."""

    name: str
    t_ns: int
    T_world_cam: np.ndarray
    split: Split


@dataclass(frozen=True)
class Scene:
    """A prepared scene: a pinhole camera, keyframes and the warm-start mesh path."""

    root: Path
    camera: CameraModel
    keyframes: list[Keyframe]
    mesh_path: Path
    sparse_points_path: Path | None = None

    def split(self, which: Split) -> list[Keyframe]:
        return [k for k in self.keyframes if k.split == which]

    def image(self, keyframe: Keyframe) -> np.ndarray:
        """``(H, W, 3)`` uint8 RGB image."""
        path = self.root / "images" / f"{keyframe.name}.png"
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise InputError("cannot read keyframe image", path=path)
        return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)

    def depth(self, keyframe: Keyframe) -> np.ndarray:
        """``(H, W)`` float32 LiDAR depth in metres, 0 where there is no return."""
        return _load_array(
            self.root / "depth" / f"{keyframe.name}.npy", (self.camera.height, self.camera.width)
        )

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


def _load_array(path: Path, shape: tuple[int, ...]) -> np.ndarray:
    try:
        array = np.load(path)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read array ({exc})", path=path) from None
    if array.shape != shape:
        raise InputError(f"expected shape {shape}, got {array.shape}", path=path)
    return array.astype(np.float32, copy=False)


def write_scene_index(
    root: Path, camera: CameraModel, keyframes: list[Keyframe], source: dict, sparse_points: str | None = None
) -> None:
    """Write ``scene.json`` (atomically) for the keyframes whose files are already written."""
    data = {
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
        "source": source,
    }
    tmp = root / (SCENE_FILE + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(root / SCENE_FILE)


def load_scene(root: str | Path) -> Scene:
    """Read a scene folder written by ``lts prepare``; errors name the file and field."""
    root = Path(root)
    index = root / SCENE_FILE
    try:
        data = json.loads(index.read_text())
    except OSError:
        raise InputError("no scene.json: not a scene folder (make one with lts prepare)", path=root) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc})", path=index) from None
    camera = CameraModel.from_dict(data.get("camera"), path=str(index))
    keyframes = []
    for i, entry in enumerate(data.get("keyframes") or []):
        try:
            T = np.asarray(entry["T_world_cam"], dtype=np.float64)
            keyframe = Keyframe(str(entry["name"]), int(entry["t_ns"]), T, entry["split"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"keyframe {i} is malformed ({exc})", path=index, field="keyframes") from None
        if T.shape != (4, 4) or keyframe.split not in ("train", "test"):
            raise InputError(f"keyframe {i}: bad pose shape or split", path=index, field="keyframes")
        keyframes.append(keyframe)
    if not keyframes:
        raise InputError("no keyframes", path=index, field="keyframes")
    sparse = data.get("sparse_points")
    return Scene(
        root, camera, keyframes, root / data.get("mesh", "mesh.ply"), root / sparse if sparse else None
    )
