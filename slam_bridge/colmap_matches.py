"""SIFT features of the keyframe images (COLMAP) matched between the keyframe pairs that see the
same surface, guided by the known poses (:mod:`slam_bridge.guided_matching`), into a COLMAP
database that triangulation and pose refinement read.

COLMAP puts pixel centres at +0.5 (its SIFT adds 0.5 to every keypoint) where the toolkit, like
OpenCV, puts them at integer coordinates: :data:`COLMAP_PIXEL_OFFSET` converts between the two,
for keypoints read here and for the principal point handed to COLMAP.

The same keyframes give the same database whatever the thread count: the images are entered in
name order before extraction (each is extracted on one thread, so the ids and keypoints do not
depend on which thread finished first), and matching is exact (see :mod:`~slam_bridge.guided_matching`)
and written in pair order.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.camera import CameraModel
from rig.mesh_rays import cast_camera_rays, pixel_rays
from rig.transforms import invert
from slam_bridge.guided_matching import TOLERANCE_DEG, KeyframeFeatures, essential_matrix, guided_matches
from slam_bridge.keyframe_pairs import keyframe_pairs

#: COLMAP pixel coordinate = OpenCV pixel coordinate + this.
COLMAP_PIXEL_OFFSET = 0.5
DATABASE_FILE = "database.db"
#: Images up to this many pixels are upsampled 2x before SIFT (COLMAP's default first octave -1):
#: small images need it for enough features. Larger ones are not: on real 1242x375 images it
#: took 0.69 s instead of 0.17 s per image for 3900-8000 features instead of 900-1700.
UPSAMPLE_MAX_PIXELS = 300_000
#: SIFT's contrast threshold on those small images (COLMAP's is 0.02 / 3 = 0.0067): guided matching
#: keeps only pose-consistent matches, so the virtual-rig room (320x240) kept 1681 sparse points
#: where the exhaustive matching had 1957, 36 % of whose verified matches were not consistent with
#: the true poses; at 0.0062 it keeps 2021 (1851 since the ratio test also runs in the other
#: direction), as close to the true mesh (72-73 % within 5 cm).
SMALL_IMAGE_PEAK_THRESHOLD = 0.0062
#: Images extracted per COLMAP call (the progress bar moves after each).
EXTRACTION_CHUNK = 8

#: ``progress(step, done, total)``: how far a named step has got (here ``"features"`` and
#: ``"matching"``; the scene builder adds ``"keyframes"``).
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class MatchingReport:
    """What matching did: keyframes, their mean keypoint count, the pairs matched and those that
    kept matches, the matches, and the seconds spent extracting features (once per database, however
    often it is matched), choosing the pairs and matching them (with the mesh depth at the
    keypoints)."""

    keyframes: int
    keypoints_mean: float
    pairs: int
    matched_pairs: int
    matches: int
    extraction_s: float
    pairing_s: float
    matching_s: float


def quiet_colmap_log() -> None:
    """Keep COLMAP's own progress lines (hundreds of INFO lines per run) out of the terminal;
    its warnings and errors still show."""
    import pycolmap

    pycolmap.logging.minloglevel = max(pycolmap.logging.minloglevel, int(pycolmap.logging.WARNING))


def colmap_camera_params(camera: CameraModel) -> list[float]:
    """``fx, fy, cx, cy`` of a distortion-free pinhole camera in COLMAP's pixel convention."""
    return [camera.fx, camera.fy, camera.cx + COLMAP_PIXEL_OFFSET, camera.cy + COLMAP_PIXEL_OFFSET]


@dataclass(frozen=True)
class KeyframeDatabase:
    """A COLMAP database at ``path`` holding the SIFT features of the keyframe images (in time
    order) under ``image_ids``, extracted in ``extraction_s`` seconds; matching writes into it
    (:func:`match_keyframes`), as often as the poses change."""

    path: Path
    image_ids: list[int]
    extraction_s: float


def extract_keyframe_features(
    images_dir: Path,
    workspace: Path,
    camera: CameraModel,
    names: list[str],
    progress: Progress | None = None,
    threads: int | None = None,
) -> KeyframeDatabase:
    """A new COLMAP database in ``workspace`` with the SIFT features of ``images_dir/NAME`` for
    each of ``names`` (keyframes in time order); ``camera`` is the distortion-free pinhole camera
    of the images, shared by all of them; ``threads``: how many to extract with (default: every
    core; the features are the same)."""
    quiet_colmap_log()
    threads = threads or os.cpu_count() or 1
    workspace.mkdir(parents=True, exist_ok=True)
    database = workspace / DATABASE_FILE
    database.unlink(missing_ok=True)
    started = time.perf_counter()
    image_ids = _new_database(database, camera, names)
    _extract_features(database, images_dir, camera, names, threads, progress)
    return KeyframeDatabase(database, image_ids, time.perf_counter() - started)


def match_keyframes(
    database: KeyframeDatabase,
    camera: CameraModel,
    poses: np.ndarray,
    raycaster: Any,
    progress: Progress | None = None,
    threads: int | None = None,
    tolerance_deg: float = TOLERANCE_DEG,
) -> MatchingReport:
    """Match the keyframes of ``database`` at ``poses`` ``(N, 4, 4)`` ``T_world_cam``: the pairs
    that see the same surface of the mesh in ``raycaster``
    (:func:`~slam_bridge.keyframe_pairs.keyframe_pairs`), each keypoint within ``tolerance_deg`` of
    where the poses put it. The matches replace any the database held; returns the report (its
    ``extraction_s`` is the database's).

    ``camera``: the images' camera; ``threads``: how many to match with (default: every core; the
    matches are the same)."""
    threads = threads or os.cpu_count() or 1
    started = time.perf_counter()
    pairs = keyframe_pairs(raycaster, camera, poses)
    paired = time.perf_counter()
    features = _read_features(database.path, database.image_ids, poses, camera, raycaster)
    with ThreadPoolExecutor(max_workers=threads) as pool:
        found = pool.map(
            lambda pair: guided_matches(features[pair[0]], features[pair[1]], camera, tolerance_deg), pairs
        )
        matches = []
        for done, pair_matches in enumerate(found, start=1):
            matches.append(pair_matches)
            if progress is not None:
                progress("matching", done, len(pairs))
    _write_matches(database.path, camera, database.image_ids, features, pairs, matches)
    return MatchingReport(
        keyframes=len(database.image_ids),
        keypoints_mean=float(np.mean([len(f.uv) for f in features])) if features else 0.0,
        pairs=len(pairs),
        matched_pairs=sum(len(m) > 0 for m in matches),
        matches=sum(len(m) for m in matches),
        extraction_s=database.extraction_s,
        pairing_s=paired - started,
        matching_s=time.perf_counter() - paired,
    )


def _new_database(database: Path, camera: CameraModel, names: list[str]) -> list[int]:
    """A COLMAP database holding ``camera`` (one rig) and an image with its frame for each of
    ``names``, entered in that order; returns their image ids."""
    import pycolmap

    db = pycolmap.Database.open(database)
    try:
        camera_id = db.write_camera(
            pycolmap.Camera(
                model="PINHOLE", width=camera.width, height=camera.height, params=colmap_camera_params(camera)
            )
        )
        rig = pycolmap.Rig()
        rig.add_ref_sensor(pycolmap.sensor_t(type=pycolmap.SensorType.CAMERA, id=camera_id))
        rig_id = db.write_rig(rig)
        image_ids = []
        for name in names:
            image_id = db.write_image(pycolmap.Image(name=name, camera_id=camera_id))
            frame = pycolmap.Frame()
            frame.rig_id = rig_id
            frame.add_data_id(db.read_image(image_id).data_id)
            db.write_frame(frame)
            image_ids.append(image_id)
    finally:
        db.close()
    return image_ids


def sift_options(camera: CameraModel, threads: int) -> Any:
    """COLMAP's SIFT extraction options for images of ``camera`` on ``threads`` threads: small ones
    (:data:`UPSAMPLE_MAX_PIXELS`) upsampled first and searched with a lower contrast threshold
    (:data:`SMALL_IMAGE_PEAK_THRESHOLD`), larger ones as they are."""
    import pycolmap

    options = pycolmap.FeatureExtractionOptions()
    options.num_threads = threads
    if camera.width * camera.height <= UPSAMPLE_MAX_PIXELS:
        options.sift.first_octave = -1
        options.sift.peak_threshold = SMALL_IMAGE_PEAK_THRESHOLD
    else:
        options.sift.first_octave = 0
    return options


def _extract_features(
    database: Path,
    images_dir: Path,
    camera: CameraModel,
    names: list[str],
    threads: int,
    progress: Progress | None,
) -> None:
    import pycolmap

    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.camera_params = ",".join(str(v) for v in colmap_camera_params(camera))
    options = sift_options(camera, threads)
    for start in range(0, len(names), EXTRACTION_CHUNK):
        pycolmap.extract_features(
            database,
            images_dir,
            image_names=names[start : start + EXTRACTION_CHUNK],
            camera_mode=pycolmap.CameraMode.SINGLE,
            reader_options=reader,
            extraction_options=options,
            device=pycolmap.Device.cpu,
        )
        if progress is not None:
            progress("features", min(start + EXTRACTION_CHUNK, len(names)), len(names))


def _read_features(
    database: Path, image_ids: list[int], poses: np.ndarray, camera: CameraModel, raycaster: Any
) -> list[KeyframeFeatures]:
    """Each image's keypoints (toolkit pixels), descriptors and the mesh depth at its keypoints."""
    import pycolmap

    db = pycolmap.Database.open(database)
    try:
        read = [
            (
                db.read_keypoints(image_id)[:, :2].astype(np.float64) - COLMAP_PIXEL_OFFSET,
                np.asarray(db.read_descriptors(image_id).data, dtype=np.float32),
            )
            for image_id in image_ids
        ]
    finally:
        db.close()
    features = []
    for (uv, descriptors), pose in zip(read, poses, strict=True):
        rays = pixel_rays(camera, uv)
        distance = cast_camera_rays(raycaster, pose, rays)["t_hit"] if len(uv) else np.zeros(0)
        depth = np.where(np.isfinite(distance), distance * rays[:, 2], np.nan)
        features.append(KeyframeFeatures(uv, descriptors, depth, pose))
    return features


def _write_matches(
    database: Path,
    camera: CameraModel,
    image_ids: list[int],
    features: list[KeyframeFeatures],
    pairs: list[tuple[int, int]],
    matches: list[np.ndarray],
) -> None:
    """Write each pair's matches as both its raw and its verified (inlier) matches, with the
    two-view geometry the poses give, in place of any matches the database held."""
    import pycolmap

    fx, fy, cx, cy = colmap_camera_params(camera)
    K_inv = np.linalg.inv(np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]]))
    db = pycolmap.Database.open(database)
    try:
        db.clear_matches()
        db.clear_two_view_geometries()
        for (i, j), pair_matches in zip(pairs, matches, strict=True):
            if len(pair_matches) == 0:
                continue
            T_j_i = invert(features[j].T_world_cam) @ features[i].T_world_cam
            E = essential_matrix(T_j_i)
            geometry = pycolmap.TwoViewGeometry()
            geometry.config = pycolmap.TwoViewGeometryConfiguration.CALIBRATED
            geometry.E, geometry.F = E, K_inv.T @ E @ K_inv
            geometry.cam2_from_cam1 = pycolmap.Rigid3d(pycolmap.Rotation3d(T_j_i[:3, :3]), T_j_i[:3, 3])
            geometry.inlier_matches = pair_matches.astype(np.uint32)
            db.write_matches(image_ids[i], image_ids[j], pair_matches.astype(np.uint32))
            db.write_two_view_geometry(image_ids[i], image_ids[j], geometry)
    finally:
        db.close()


@dataclass(frozen=True)
class Correspondences:
    """Verified matches as directed observations: keyframe ``observer[m]`` sees at pixel
    ``uv_observer[m]`` the scene point that keyframe ``source[m]`` sees at ``uv_source[m]``.

    Every match appears in both directions, with the same number ``match[m]``. Indices refer to
    the ``names`` the matches were read for; pixels ``(M, 2)`` are in the toolkit's convention
    (pixel centres at integers).
    """

    observer: np.ndarray
    source: np.ndarray
    uv_observer: np.ndarray
    uv_source: np.ndarray
    match: np.ndarray

    def __len__(self) -> int:
        return len(self.observer)


def read_correspondences(database: Path, names: list[str]) -> Correspondences:
    """The inlier matches of every verified image pair in a COLMAP database, for images ``names``."""
    import pycolmap

    index = {name: i for i, name in enumerate(names)}
    db = pycolmap.Database.open(database)
    try:
        image_index = {
            image.image_id: index[image.name] for image in db.read_all_images() if image.name in index
        }
        keypoints = {
            i: db.read_keypoints(i)[:, :2].astype(np.float64) - COLMAP_PIXEL_OFFSET for i in image_index
        }
        pair_ids, geometries = db.read_two_view_geometries()
    finally:
        db.close()
    observer, source, uv_observer, uv_source, match = [], [], [], [], []
    count = 0
    for pair_id, geometry in zip(pair_ids, geometries, strict=True):
        a, b = pycolmap.pair_id_to_image_pair(pair_id)
        matches = geometry.inlier_matches
        if a not in image_index or b not in image_index or len(matches) == 0:
            continue
        for (seer, seen), (k_seer, k_seen) in (((a, b), (0, 1)), ((b, a), (1, 0))):
            observer.append(np.full(len(matches), image_index[seer]))
            source.append(np.full(len(matches), image_index[seen]))
            uv_observer.append(keypoints[seer][matches[:, k_seer]])
            uv_source.append(keypoints[seen][matches[:, k_seen]])
            match.append(count + np.arange(len(matches)))
        count += len(matches)
    if not observer:
        empty = np.zeros(0, dtype=np.int64)
        return Correspondences(empty, empty, np.zeros((0, 2)), np.zeros((0, 2)), empty)
    return Correspondences(
        *(np.concatenate(parts) for parts in (observer, source, uv_observer, uv_source, match))
    )
