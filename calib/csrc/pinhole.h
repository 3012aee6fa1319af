// The pinhole projection of calib/photo_consistency.py's _project, in NumPy's float32 arithmetic
// (Python floats become float32 operands; no fused multiply-adds: the build's -ffp-contract=off),
// so that the compiled kernels put every point where the NumPy specification does.
#pragma once

#include <cstdint>

struct Pinhole {
  float fx, fy, cx, cy, u_max, v_max;  // u_max, v_max: the last column and row

  Pinhole(double fx_, double fy_, double cx_, double cy_, int64_t width, int64_t height)
      : fx(float(fx_)), fy(float(fy_)), cx(float(cx_)), cy(float(cy_)),
        u_max(float(width - 1)), v_max(float(height - 1)) {}

  // The pixel (u, v) of camera point (x, y, z); whether it lies in the image (depth over 5 cm).
  // Branch-free (& not &&), so that loops over points vectorise.
  bool project(float x, float y, float z, float& u, float& v) const {
    const float safe = z > 0.05f ? z : 1.0f;
    u = fx * x / safe + cx;
    v = fy * y / safe + cy;
    return (z > 0.05f) & (u >= 0) & (u <= u_max) & (v >= 0) & (v <= v_max);
  }
};
