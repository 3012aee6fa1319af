"""A surface mesh from a mapper's point map (FAST-LIO's ``scans.pcd``, ImMesh's registered clouds).

Mappers that keep no mesh keep points; a mesh is made here by screened Poisson reconstruction
(open3d), with normals oriented towards the trajectory and the surface trimmed to where points are.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.errors import InputError


def mesh_from_points(
    points: np.ndarray, viewpoints: np.ndarray, voxel_m: float = 0.03, depth: int = 9
) -> trimesh.Trimesh:
    """Surface mesh of a point map ``(N, 3)`` seen from ``viewpoints`` ``(P, 3)``.

    Normals are estimated from neighbours and flipped to face the nearest viewpoint; Poisson's
    surface is kept only within ``3 * voxel_m`` of a map point (it closes holes elsewhere).
    """
    from rig.open3d_lite import o3d

    if len(points) < 100:
        raise InputError(f"the point map holds only {len(points)} points", field="points")
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    cloud = cloud.voxel_down_sample(voxel_m)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * voxel_m, max_nn=30))
    positions = np.asarray(cloud.points)
    normals = np.asarray(cloud.normals)
    _, nearest = cKDTree(viewpoints).query(positions)
    flip = np.einsum("ij,ij->i", normals, viewpoints[nearest] - positions) < 0
    normals[flip] *= -1
    cloud.normals = o3d.utility.Vector3dVector(normals)
    surface, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(cloud, depth=depth)
    vertices = np.asarray(surface.vertices)
    distance, _ = cKDTree(positions).query(vertices)
    surface.remove_vertices_by_mask(distance > 3 * voxel_m)
    return trimesh.Trimesh(np.asarray(surface.vertices), np.asarray(surface.triangles), process=False)
