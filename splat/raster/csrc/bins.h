// Host-side views of the kernels' inputs: tile lists (built by splat/raster/binning.py) and camera.
#pragma once

#include <torch/types.h>

#include "triangle_setup.h"

namespace lts {

struct Bins {
  const int64_t* tile_offsets;  // (n_tiles + 1,) start of each tile's entries
  const int32_t* tile_slots;    // (n_slots,) slot of each entry, depth order inside a tile
  const int32_t* slot_tri;      // (n_slots,) sorted triangle of each slot
  const int64_t* tri_offsets;   // (n_triangles + 1,) slots of a triangle are contiguous
  const int32_t* bounds;        // (n_triangles, 4) inclusive pixel box x0, y0, x1, y1
  int width, height, tiles_x, n_tiles;
};

inline Bins make_bins(const torch::Tensor& params, const torch::Tensor& bounds,
                      const torch::Tensor& tile_offsets, const torch::Tensor& tile_slots,
                      const torch::Tensor& slot_tri, const torch::Tensor& tri_offsets,
                      int64_t width, int64_t height) {
  TORCH_CHECK(params.is_contiguous() && params.dim() == 2 && params.size(1) == kParams,
              "params must be a contiguous (K, ", kParams, ") tensor");
  TORCH_CHECK(bounds.scalar_type() == torch::kInt32 && bounds.is_contiguous(), "bounds: int32");
  TORCH_CHECK(tile_offsets.scalar_type() == torch::kInt64, "tile_offsets: int64");
  TORCH_CHECK(tri_offsets.scalar_type() == torch::kInt64, "tri_offsets: int64");
  TORCH_CHECK(tile_slots.scalar_type() == torch::kInt32 && slot_tri.scalar_type() == torch::kInt32,
              "tile_slots, slot_tri: int32");
  const int tiles_x = static_cast<int>((width + kTile - 1) / kTile);
  const int tiles_y = static_cast<int>((height + kTile - 1) / kTile);
  TORCH_CHECK(tile_offsets.numel() == tiles_x * tiles_y + 1, "tile_offsets has the wrong size");
  return {tile_offsets.data_ptr<int64_t>(), tile_slots.data_ptr<int32_t>(),
          slot_tri.data_ptr<int32_t>(),     tri_offsets.data_ptr<int64_t>(),
          bounds.data_ptr<int32_t>(),       static_cast<int>(width),
          static_cast<int>(height),         tiles_x,
          tiles_x * tiles_y};
}

// The 17 doubles of a view tensor: row-major R, t, fx, fy, cx, cy, near.
template <typename T>
View<T> make_view(const torch::Tensor& view, int64_t width, int64_t height) {
  const torch::Tensor host = view.to(torch::kCPU, torch::kFloat64).contiguous();
  TORCH_CHECK(host.numel() == 17, "view: 17 numbers");
  const double* c = host.data_ptr<double>();
  View<T> v;
  for (int i = 0; i < 9; ++i) v.R[i] = T(c[i]);
  for (int i = 0; i < 3; ++i) v.t[i] = T(c[9 + i]);
  v.fx = T(c[12]);
  v.fy = T(c[13]);
  v.cx = T(c[14]);
  v.cy = T(c[15]);
  v.near = T(c[16]);
  v.width = static_cast<int>(width);
  v.height = static_cast<int>(height);
  return v;
}

}  // namespace lts
