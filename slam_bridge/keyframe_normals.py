"""Each keyframe's normal prior: the SLAM mesh's normals seen through its pixels, or a given normal
map (e.g. from a monocular normal network) undistorted into the scene's camera."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.image_io import read_image
from rig.mesh_rays import cast_camera_rays, pixel_rays
from slam_bridge.scene import Keyframe


def normal_prior(
    raycaster, T_world_cam: np.ndarray, rays_cam: np.ndarray, shape: tuple[int, int]
) -> np.ndarray:
    """Camera-frame normals ``(H, W, 3)`` of the mesh seen through each pixel ray (facing the camera)."""
    hits = cast_camera_rays(raycaster, T_world_cam, rays_cam)
    hit = np.isfinite(hits["t_hit"])
    normals = hits["primitive_normals"] @ T_world_cam[:3, :3]  # to the camera frame
    facing = np.einsum("ij,ij->i", normals, rays_cam) > 0
    normals[facing] *= -1
    normals[~hit] = 0
    return normals.reshape(*shape, 3).astype(np.float32)


def read_normal_map(folder: Path, frame_index: int, t_ns: int, camera: CameraModel) -> np.ndarray:
    """A precomputed normal map ``(H, W, 3)`` for one camera frame, in the original (distorted) image.

    Looked up as ``<t_ns>.npy|.png`` (the frame's host stamp) or ``<frame_index:06d>.npy|.png``
    (its position in the image topic). ``.npy``: float camera-frame normals (OpenCV axes); ``.png``:
    8-bit RGB encoding ``(n + 1) / 2``. Zero vectors mean "no normal".
    """
    for stem in (str(t_ns), f"{frame_index:06d}"):
        for suffix in (".npy", ".png"):
            path = folder / f"{stem}{suffix}"
            if not path.is_file():
                continue
            if suffix == ".npy":
                normals = np.load(path).astype(np.float32)
            else:
                encoded = read_image(path, what="the normal map")
                normals = cv2.cvtColor(encoded, cv2.COLOR_BGR2RGB).astype(np.float32) / 127.5 - 1.0
            if normals.shape != (camera.height, camera.width, 3):
                raise InputError(
                    f"normal map is {normals.shape}, expected ({camera.height}, {camera.width}, 3)", path=path
                )
            return normals
    raise InputError(
        f"no normal map for frame {frame_index} ({t_ns} ns): expected {t_ns}.npy or {frame_index:06d}.png",
        path=folder,
    )


def undistort_normals(normals: np.ndarray, camera: CameraModel, target: CameraModel) -> np.ndarray:
    """Resample a normal map ``(H, W, 3)`` into the undistorted camera ``target`` (of any size;
    nearest pixel, so normals are not blended across edges) and re-normalise; empty pixels stay
    zero."""
    resampled = camera.undistort_image(normals, target, interpolation=cv2.INTER_NEAREST)
    norms = np.linalg.norm(resampled, axis=-1, keepdims=True)
    return np.divide(resampled, norms, out=np.zeros_like(resampled), where=norms > 1e-6).astype(np.float32)


def write_keyframe_normals(
    out: Path,
    keyframes: list[Keyframe],
    frame_indices: np.ndarray,
    camera: CameraModel,
    target: CameraModel,
    raycaster,
    normals_dir: Path | None,
    done: Callable[[], None],
) -> None:
    """Save each keyframe's normal prior ``(H, W, 3)`` float32 in the image of the scene's camera
    ``target`` as ``out/normals/NAME.npy``: the maps in ``normals_dir`` (of the session's
    ``camera``, found by the keyframes' positions ``frame_indices`` ``(K,)`` on the image topic and
    their stamps) when given, else the SLAM mesh's normals through ``raycaster``; ``done()`` after
    each."""
    (out / "normals").mkdir(parents=True, exist_ok=True)
    rays_cam = pixel_rays(target)
    for index, keyframe in zip(frame_indices, keyframes, strict=True):
        if normals_dir is not None:
            given = read_normal_map(Path(normals_dir), int(index), keyframe.t_ns, camera)
            normals = undistort_normals(given, camera, target)
        else:
            normals = normal_prior(raycaster, keyframe.T_world_cam, rays_cam, (target.height, target.width))
        np.save(out / "normals" / f"{keyframe.name}.npy", normals)
        done()
