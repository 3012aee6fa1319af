"""Scoring a run on another scene's held-out views (``lts eval RUN --test-views OTHER``).

Two runs made from one recording with different keyframes (``--keyframe-interval``,
``--keyframe-distance``, ``--test-every``) hold out different views, so each one's own test PSNR
compares two samples of views, not two models. Scored on the same views, held out by both, they
compare. The other scene must come from the same recording and map: the frames both scenes hold
must have the same poses there.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.errors import InputError
from slam_bridge.scene import SCENE_FILE, Keyframe, Scene, load_scene
from splat import run_dir as layout

#: Most distance (m) between two scenes' camera positions at one frame for them to share a map.
SAME_MAP_M = 0.01


def views_scene(path: str | Path) -> Scene:
    """The scene ``path`` names: a scene folder (``lts prepare --out``), a training run (its scene)
    or an ``lts reconstruct`` folder (its ``scene/``)."""
    from eval.run_inputs import resolve_run_dir

    path = Path(path)
    if (path / SCENE_FILE).is_file():
        return load_scene(path)
    if not path.is_dir():
        raise InputError("no such scene or run folder", path=path, field="--test-views")
    try:
        run_dir = resolve_run_dir(path)
    except InputError:
        raise InputError(
            f"expected a scene folder ({SCENE_FILE}), a training run or an lts reconstruct folder",
            path=path,
            field="--test-views",
        ) from None
    return load_scene(layout.scene_of(run_dir))


def held_out_views(scene: Scene, other: Scene) -> list[Keyframe]:
    """The test keyframes of ``other`` that ``scene`` does not train on; an error naming ``other``
    when its camera differs from ``scene``'s, when the two share no frame, when their poses of a
    shared frame lie more than :data:`SAME_MAP_M` apart (another map), or when no view is left."""
    mine, theirs = scene.camera, other.camera
    if mine.size != theirs.size or not np.allclose(mine.K, theirs.K, rtol=1e-6):
        raise InputError(
            f"its camera ({theirs.width}x{theirs.height}, fx {theirs.K[0, 0]:.2f}) is not the run's "
            f"({mine.width}x{mine.height}, fx {mine.K[0, 0]:.2f}): prepare both at the same size",
            path=other.root,
            field="camera",
        )
    positions = {k.t_ns: k.T_world_cam[:3, 3] for k in scene.keyframes}
    shared = [k for k in other.keyframes if k.t_ns in positions]
    if not shared:
        raise InputError(
            "it shares no frame with the run's scene: not the same recording",
            path=other.root,
            field="keyframes",
        )
    apart = max(float(np.linalg.norm(k.T_world_cam[:3, 3] - positions[k.t_ns])) for k in shared)
    if apart > SAME_MAP_M:
        raise InputError(
            f"its poses of the frames both scenes hold lie up to {apart:.3f} m from the run's: not the same "
            "map (prepare both from one lts slam folder)",
            path=other.root,
            field="keyframes",
        )
    trained = {k.t_ns for k in scene.split("train")}
    views = [k for k in other.split("test") if k.t_ns not in trained]
    if not views:
        raise InputError(
            "every one of its test views is a training view of the run", path=other.root, field="keyframes"
        )
    return views
