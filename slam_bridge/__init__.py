"""slam_bridge: mesh-SLAM imports (ImMesh and others), the fallback mapper, the keyframe scene builder.

Every import and the mapper write the same SLAM folder (:mod:`slam_bridge.slam_dir`):
``mesh.ply`` (binary PLY, world frame) and ``trajectory.tum`` (``T_world_lidar``). The scene
builder turns a session + SLAM folder into the keyframe scene folder (:mod:`slam_bridge.scene`).

Names are imported on first use (PEP 562), so that ``lts --help``, which imports this package,
does not load trimesh and the mapper.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "lidar_depth_image": "slam_bridge.depth_image",
    "nearest_returns": "slam_bridge.depth_image",
    "remove_occluded": "slam_bridge.depth_image",
    "visible_returns": "slam_bridge.depth_image",
    "zbuffer_depth": "slam_bridge.depth_image",
    "MapperConfig": "slam_bridge.fallback_mapper",
    "MapperResult": "slam_bridge.fallback_mapper",
    "run_mapper": "slam_bridge.fallback_mapper",
    "import_fast_lio": "slam_bridge.fast_lio",
    "import_generic": "slam_bridge.generic",
    "ImmeshReport": "slam_bridge.immesh",
    "T_LC": "slam_bridge.immesh",
    "import_immesh": "slam_bridge.immesh",
    "read_immesh_log": "slam_bridge.immesh",
    "CleanupReport": "slam_bridge.mesh_cleanup",
    "clean_mesh": "slam_bridge.mesh_cleanup",
    "import_pin_slam": "slam_bridge.pin_slam",
    "mesh_from_points": "slam_bridge.point_map",
    "RefineConfig": "slam_bridge.pose_refinement",
    "RefinementReport": "slam_bridge.pose_refinement",
    "refine_keyframe_poses": "slam_bridge.pose_refinement",
    "PrepareConfig": "slam_bridge.prepare_config",
    "Keyframe": "slam_bridge.scene",
    "KeyframeLidar": "slam_bridge.scene",
    "Scene": "slam_bridge.scene",
    "load_scene": "slam_bridge.scene",
    "SceneBuild": "slam_bridge.scene_builder",
    "build_scene": "slam_bridge.scene_builder",
    "load_slam_dir": "slam_bridge.slam_dir",
    "write_slam_dir": "slam_bridge.slam_dir",
    "SparseResult": "slam_bridge.sparse_points",
    "triangulate_keyframes": "slam_bridge.sparse_points",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
