"""slam_bridge: mesh-SLAM imports (ImMesh and others), the fallback mapper, the keyframe scene builder."""
