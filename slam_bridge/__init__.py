"""slam_bridge: mesh-SLAM imports (ImMesh and others), the fallback mapper, the keyframe scene builder.

Every import and the mapper write the same SLAM folder (:mod:`slam_bridge.slam_dir`):
``mesh.ply`` (binary PLY, world frame) and ``trajectory.tum`` (``T_world_lidar``). The scene
builder turns a session + SLAM folder into the keyframe scene folder (:mod:`slam_bridge.scene`).
"""

from slam_bridge.depth_image import (
    lidar_depth_image,
    nearest_returns,
    remove_occluded,
    visible_returns,
    zbuffer_depth,
)
from slam_bridge.fallback_mapper import MapperConfig, MapperResult, run_mapper
from slam_bridge.fast_lio import import_fast_lio
from slam_bridge.generic import import_generic
from slam_bridge.immesh import T_LC, ImmeshReport, import_immesh, read_immesh_log
from slam_bridge.mesh_cleanup import CleanupReport, clean_mesh
from slam_bridge.pin_slam import import_pin_slam
from slam_bridge.point_map import mesh_from_points
from slam_bridge.pose_refinement import RefineConfig, RefinementReport, refine_keyframe_poses
from slam_bridge.prepare_config import PrepareConfig
from slam_bridge.scene import Keyframe, KeyframeLidar, Scene, load_scene
from slam_bridge.scene_builder import SceneBuild, build_scene
from slam_bridge.slam_dir import load_slam_dir, write_slam_dir
from slam_bridge.sparse_points import SparseResult, triangulate_keyframes

__all__ = [
    "T_LC",
    "CleanupReport",
    "ImmeshReport",
    "Keyframe",
    "KeyframeLidar",
    "MapperConfig",
    "MapperResult",
    "PrepareConfig",
    "RefineConfig",
    "RefinementReport",
    "Scene",
    "SceneBuild",
    "SparseResult",
    "build_scene",
    "clean_mesh",
    "import_fast_lio",
    "import_generic",
    "import_immesh",
    "import_pin_slam",
    "lidar_depth_image",
    "load_scene",
    "load_slam_dir",
    "mesh_from_points",
    "nearest_returns",
    "read_immesh_log",
    "refine_keyframe_poses",
    "remove_occluded",
    "run_mapper",
    "triangulate_keyframes",
    "visible_returns",
    "write_slam_dir",
    "zbuffer_depth",
]
