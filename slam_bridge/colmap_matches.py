"""SIFT features and geometrically verified matches between keyframe images, with pycolmap.

COLMAP puts pixel centres at +0.5 (its SIFT adds 0.5 to every keypoint) where the toolkit, like
OpenCV, puts them at integer coordinates: :data:`COLMAP_PIXEL_OFFSET` converts between the two,
for keypoints read here and for the principal point handed to COLMAP.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.camera import CameraModel

#: COLMAP pixel coordinate = OpenCV pixel coordinate + this.
COLMAP_PIXEL_OFFSET = 0.5
#: Above this many keyframes, match each only with its neighbours in time (sequential matching).
EXHAUSTIVE_MATCHING_LIMIT = 100
DATABASE_FILE = "database.db"
#: Seed of the two-view geometric verification's RANSAC (reproducible matches).
RANSAC_SEED = 0


def colmap_camera_params(camera: CameraModel) -> list[float]:
    """``fx, fy, cx, cy`` of a distortion-free pinhole camera in COLMAP's pixel convention."""
    return [camera.fx, camera.fy, camera.cx + COLMAP_PIXEL_OFFSET, camera.cy + COLMAP_PIXEL_OFFSET]


def match_keyframes(images_dir: Path, workspace: Path, camera: CameraModel, names: list[str]) -> Path:
    """Extract SIFT features of ``images_dir/NAME`` for each of ``names`` and match them (exhaustively,
    or sequentially above :data:`EXHAUSTIVE_MATCHING_LIMIT` images); returns the COLMAP database.

    ``camera`` is the distortion-free pinhole camera of the images, shared by all of them.
    """
    import pycolmap

    workspace.mkdir(parents=True, exist_ok=True)
    database = workspace / DATABASE_FILE
    database.unlink(missing_ok=True)
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.camera_params = ",".join(str(v) for v in colmap_camera_params(camera))
    # One extraction thread: COLMAP numbers the images in the order their features are written,
    # and with several threads that order (hence each pair's direction and the verification's
    # random draws) changed from run to run.
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = 1
    pycolmap.extract_features(
        database,
        images_dir,
        image_names=names,
        camera_mode=pycolmap.CameraMode.SINGLE,
        reader_options=reader,
        extraction_options=extraction,
        device=pycolmap.Device.cpu,
    )
    # Reproducible matches (the refined poses and sparse points differed from run to run): exact
    # nearest neighbours on one thread instead of FLANN's randomised trees, and COLMAP's random
    # generator and each pair's RANSAC seeded instead of from the clock (its -1).
    matching = pycolmap.FeatureMatchingOptions()
    matching.sift.cpu_brute_force_matcher = True
    matching.num_threads = 1
    verification = pycolmap.TwoViewGeometryOptions()
    verification.ransac.random_seed = RANSAC_SEED
    pycolmap.set_random_seed(RANSAC_SEED)
    exhaustive = len(names) <= EXHAUSTIVE_MATCHING_LIMIT
    match = pycolmap.match_exhaustive if exhaustive else pycolmap.match_sequential
    match(database, matching_options=matching, verification_options=verification, device=pycolmap.Device.cpu)
    return database


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
