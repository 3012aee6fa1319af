// CPU rasteriser: tile-major loops (per 16x16 tile, triangles in depth order outside, the pixels of
// each triangle's span inside, per-tile pixel state in small arrays). This order keeps the tile's
// state in L1 and reads each triangle once per tile; it is ~2x faster than a per-pixel loop.
// Gradients are written per (tile, triangle) slot and summed per triangle in a fixed order, so
// results are deterministic without atomics.
#include <torch/extension.h>

#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include "bins.h"
#include "cpu_ops.h"
#include "pixel_io.h"
#include "triangle_math.h"

namespace {

using namespace lts;

// Runs fn(tile) for every tile; threads take tiles from a shared counter because tiles cost very
// different amounts. Each tile's result does not depend on the thread that computes it.
template <typename F>
void for_each_tile(int n_tiles, const F& fn) {
  std::atomic<int> next{0};
  const int n_threads = std::max(1, std::min<int>(at::get_num_threads(), n_tiles));
  at::parallel_for(0, n_threads, 1, [&](int64_t, int64_t) {
    for (int t = next++; t < n_tiles; t = next++) fn(t);
  });
}

// Pixel box of a triangle inside a tile; false if empty.
struct Box {
  int x0, y0, x1, y1;
};

inline bool pair_box(const Bins& b, int k, int tx0, int ty0, Box& box) {
  const int32_t* bd = b.bounds + 4 * static_cast<int64_t>(k);
  box.x0 = std::max<int>(bd[0], tx0);
  box.y0 = std::max<int>(bd[1], ty0);
  box.x1 = std::min<int>(bd[2], std::min(tx0 + kTile, b.width) - 1);
  box.y1 = std::min<int>(bd[3], std::min(ty0 + kTile, b.height) - 1);
  return box.x0 <= box.x1 && box.y0 <= box.y1;
}

// Narrows [x0, x1] to the pixels of row y where every edge function can reach the support
// threshold. The exact test is per pixel, so the span only has to be a superset: each bound is
// padded by 0.05 px plus a term for its rounding error, which grows with |b / a| (edges close to
// horizontal). False if the row is empty.
template <typename T>
bool row_span(const T* p, const T inv_a[3], T y, int& x0, int& x1) {
  T lo = T(x0), hi = T(x1);
  for (int j = 0; j < 3; ++j) {
    const T a = p[kLine + 3 * j], b = p[kLine + 3 * j + 1];
    const T bound = (p[kParams - 1] - (b * y + p[kLine + 3 * j + 2])) * inv_a[j];
    const T pad = T(0.05) + T(1e-4) * std::fabs(b * inv_a[j]);
    if (a > T(0)) {
      lo = std::max(lo, bound - pad);
    } else if (a < T(0)) {
      hi = std::min(hi, bound + pad);
    }
  }
  if (!(lo <= hi)) return false;
  x0 = static_cast<int>(std::ceil(lo));
  x1 = static_cast<int>(std::floor(hi));
  return x0 <= x1;
}

// Calls fn(x, y, pixel_index_in_tile, window) for every contributing pixel of a (tile, triangle)
// pair among the live ones (bit x of live[y] set for tile pixel (x, y)).
template <typename T, typename F>
void for_each_pixel(const T* p, const Box& box, int tx0, int ty0, const uint32_t* live,
                    const F& fn) {
  T inv_a[3];
  for (int j = 0; j < 3; ++j) inv_a[j] = T(1) / p[kLine + 3 * j];  // inf for 0: unused then
  for (int y = box.y0; y <= box.y1; ++y) {
    uint32_t bits = live[y - ty0];
    if (bits == 0) continue;
    int x0 = box.x0, x1 = box.x1;
    if (!row_span(p, inv_a, T(y), x0, x1)) continue;
    bits &= (2u << (x1 - tx0)) - (1u << (x0 - tx0));
    while (bits != 0) {
      const int lx = __builtin_ctz(bits);
      bits &= bits - 1;
      Window<T> w;
      if (eval_window(p, T(tx0 + lx), T(y), w)) fn(T(tx0 + lx), T(y), (y - ty0) * kTile + lx, w);
    }
  }
}

template <typename T>
void forward_tile(int tile, const Bins& b, const T* params, T* rgb, T* depth, T* alpha, T* normal,
                  T* median, T* distortion, int64_t* dominant, T* transmittance,
                  int32_t* last_entry, int32_t* median_entry, T* slot_max_weight) {
  const int tx0 = (tile % b.tiles_x) * kTile, ty0 = (tile / b.tiles_x) * kTile;
  const int tw = std::min(kTile, b.width - tx0), th = std::min(kTile, b.height - ty0);
  PixelState<T> px[kTilePixels];
  for (auto& s : px) s.reset();
  uint32_t live[kTile];
  for (int y = 0; y < kTile; ++y) live[y] = y < th ? (1u << tw) - 1 : 0u;
  int active = tw * th;
  for (int64_t e = b.tile_offsets[tile]; e < b.tile_offsets[tile + 1] && active > 0; ++e) {
    const int32_t slot = b.tile_slots[e];
    const int k = b.slot_tri[slot];
    Box box;
    if (!pair_box(b, k, tx0, ty0, box)) continue;
    // Local copies: the compiler cannot keep parameters and accumulators in registers when they
    // might alias the output arrays.
    T p[kParams];
    std::copy(params + static_cast<int64_t>(k) * kParams, params + (k + 1) * int64_t{kParams}, p);
    T max_weight = T(0);
    for_each_pixel(p, box, tx0, ty0, live, [&](T, T, int i, const Window<T>& w) {
      const T weight = px[i].blend(p, w, static_cast<int>(e), k);
      if (weight < T(0)) {
        live[i / kTile] &= ~(1u << (i % kTile));
        --active;
      } else {
        max_weight = std::max(max_weight, weight);
      }
    });
    slot_max_weight[slot] = max_weight;
  }
  for (int y = 0; y < th; ++y) {
    for (int x = 0; x < tw; ++x) {
      const int64_t o = static_cast<int64_t>(ty0 + y) * b.width + (tx0 + x);
      write_pixel(px[y * kTile + x], o, rgb, depth, alpha, normal, median, distortion, dominant,
                  transmittance, last_entry, median_entry);
    }
  }
}

template <typename T>
void backward_tile(int tile, const Bins& b, const T* params, const T* alpha, const T* depth,
                   const T* distortion, const T* transmittance, const int32_t* last_entry,
                   const int32_t* median_entry, const T* d_rgb, const T* d_depth,
                   const T* d_alpha, const T* d_normal, const T* d_median,
                   const T* d_distortion, T* slot_grads) {
  const int tx0 = (tile % b.tiles_x) * kTile, ty0 = (tile / b.tiles_x) * kTile;
  const int tw = std::min(kTile, b.width - tx0), th = std::min(kTile, b.height - ty0);
  PixelGrad<T> px[kTilePixels];
  for (int y = 0; y < kTile; ++y) {
    for (int x = 0; x < kTile; ++x) {
      PixelGrad<T>& g = px[y * kTile + x];
      if (y >= th || x >= tw) {
        g.last_entry = -1;
        continue;
      }
      const int64_t o = static_cast<int64_t>(ty0 + y) * b.width + (tx0 + x);
      read_pixel(g, o, alpha, depth, distortion, transmittance, last_entry, median_entry, d_rgb,
                 d_depth, d_alpha, d_normal, d_median, d_distortion);
    }
  }
  // Pixels join the back-to-front sweep at their last composited entry: visit them in that order.
  int order[kTilePixels];
  for (int i = 0; i < kTilePixels; ++i) order[i] = i;
  std::sort(order, order + kTilePixels,
            [&](int a, int c) { return px[a].last_entry > px[c].last_entry; });
  uint32_t live[kTile] = {};
  int joined = 0;
  for (int64_t e = b.tile_offsets[tile + 1] - 1; e >= b.tile_offsets[tile]; --e) {
    const int32_t slot = b.tile_slots[e];
    T g[kGrads] = {};
    for (; joined < kTilePixels && px[order[joined]].last_entry >= e; ++joined) {
      live[order[joined] / kTile] |= 1u << (order[joined] % kTile);
    }
    const int k = b.slot_tri[slot];
    Box box;
    if (joined > 0 && pair_box(b, k, tx0, ty0, box)) {
      T p[kParams];
      std::copy(params + static_cast<int64_t>(k) * kParams, params + (k + 1) * int64_t{kParams}, p);
      for_each_pixel(p, box, tx0, ty0, live, [&](T x, T y, int i, const Window<T>& w) {
        px[i].unblend(p, x, y, w, static_cast<int>(e), g);
      });
    }
    std::copy(g, g + kGrads, slot_grads + static_cast<int64_t>(slot) * kGrads);
  }
}

std::vector<torch::Tensor> forward(const torch::Tensor& params, const torch::Tensor& bounds,
                                   const torch::Tensor& tile_offsets,
                                   const torch::Tensor& tile_slots, const torch::Tensor& slot_tri,
                                   const torch::Tensor& tri_offsets, int64_t width,
                                   int64_t height) {
  TORCH_CHECK(params.device().is_cpu(), "params must be on the CPU");
  const Bins b =
      make_bins(params, bounds, tile_offsets, tile_slots, slot_tri, tri_offsets, width, height);
  const auto f = params.options();
  const auto i32 = f.dtype(torch::kInt32);
  auto rgb = torch::empty({height, width, 3}, f), normal = torch::empty({height, width, 3}, f);
  auto depth = torch::empty({height, width}, f), alpha = torch::empty({height, width}, f);
  auto median = torch::empty({height, width}, f), distortion = torch::empty({height, width}, f);
  auto transmittance = torch::empty({height, width}, f);
  auto dominant = torch::empty({height, width}, f.dtype(torch::kInt64));
  auto last_entry = torch::empty({height, width}, i32);
  auto median_entry = torch::empty({height, width}, i32);
  auto slot_max_weight = torch::zeros({tile_slots.numel()}, f);
  const int64_t n_tri = params.size(0);
  auto max_weight = torch::empty({n_tri}, f);
  AT_DISPATCH_FLOATING_TYPES(params.scalar_type(), "lts_raster_forward", [&] {
    const scalar_t* p = params.data_ptr<scalar_t>();
    for_each_tile(b.n_tiles, [&](int t) {
      forward_tile<scalar_t>(t, b, p, rgb.data_ptr<scalar_t>(), depth.data_ptr<scalar_t>(),
                             alpha.data_ptr<scalar_t>(), normal.data_ptr<scalar_t>(),
                             median.data_ptr<scalar_t>(), distortion.data_ptr<scalar_t>(),
                             dominant.data_ptr<int64_t>(), transmittance.data_ptr<scalar_t>(),
                             last_entry.data_ptr<int32_t>(), median_entry.data_ptr<int32_t>(),
                             slot_max_weight.data_ptr<scalar_t>());
    });
    const scalar_t* sw = slot_max_weight.data_ptr<scalar_t>();
    scalar_t* mw = max_weight.data_ptr<scalar_t>();
    at::parallel_for(0, n_tri, 1024, [&](int64_t k0, int64_t k1) {
      for (int64_t k = k0; k < k1; ++k) {
        scalar_t m = scalar_t(0);
        for (int64_t s = b.tri_offsets[k]; s < b.tri_offsets[k + 1]; ++s) m = std::max(m, sw[s]);
        mw[k] = m;
      }
    });
  });
  return {rgb,        depth,         alpha,      normal,      median,      distortion,
          dominant,   max_weight,    transmittance, last_entry, median_entry};
}

torch::Tensor backward(const torch::Tensor& params, const torch::Tensor& bounds,
                       const torch::Tensor& tile_offsets, const torch::Tensor& tile_slots,
                       const torch::Tensor& slot_tri, const torch::Tensor& tri_offsets,
                       int64_t width, int64_t height, const torch::Tensor& alpha,
                       const torch::Tensor& depth, const torch::Tensor& distortion,
                       const torch::Tensor& transmittance, const torch::Tensor& last_entry,
                       const torch::Tensor& median_entry, const torch::Tensor& d_rgb,
                       const torch::Tensor& d_depth, const torch::Tensor& d_alpha,
                       const torch::Tensor& d_normal, const torch::Tensor& d_median,
                       const torch::Tensor& d_distortion) {
  TORCH_CHECK(params.device().is_cpu(), "params must be on the CPU");
  for (const auto* t : {&d_rgb, &d_depth, &d_alpha, &d_normal, &d_median, &d_distortion}) {
    TORCH_CHECK(t->is_contiguous() && t->scalar_type() == params.scalar_type(),
                "upstream gradients must be contiguous and of the parameters' dtype");
  }
  const Bins b =
      make_bins(params, bounds, tile_offsets, tile_slots, slot_tri, tri_offsets, width, height);
  const int64_t n_tri = params.size(0);
  auto slot_grads = torch::empty({tile_slots.numel(), kGrads}, params.options());
  auto d_params = torch::zeros({n_tri, kParams}, params.options());
  AT_DISPATCH_FLOATING_TYPES(params.scalar_type(), "lts_raster_backward", [&] {
    const scalar_t* p = params.data_ptr<scalar_t>();
    scalar_t* sg = slot_grads.data_ptr<scalar_t>();
    for_each_tile(b.n_tiles, [&](int t) {
      backward_tile<scalar_t>(
          t, b, p, alpha.data_ptr<scalar_t>(), depth.data_ptr<scalar_t>(),
          distortion.data_ptr<scalar_t>(), transmittance.data_ptr<scalar_t>(),
          last_entry.data_ptr<int32_t>(), median_entry.data_ptr<int32_t>(),
          d_rgb.data_ptr<scalar_t>(), d_depth.data_ptr<scalar_t>(), d_alpha.data_ptr<scalar_t>(),
          d_normal.data_ptr<scalar_t>(), d_median.data_ptr<scalar_t>(),
          d_distortion.data_ptr<scalar_t>(), sg);
    });
    scalar_t* dp = d_params.data_ptr<scalar_t>();
    at::parallel_for(0, n_tri, 1024, [&](int64_t k0, int64_t k1) {
      for (int64_t k = k0; k < k1; ++k) {
        for (int64_t s = b.tri_offsets[k]; s < b.tri_offsets[k + 1]; ++s) {
          for (int i = 0; i < kGrads; ++i) dp[k * kParams + i] += sg[s * kGrads + i];
        }
      }
    });
  });
  return d_params;
}

// Tile binning (the CPU twin of splat/raster/binning.py): a counting sort by tile that visits
// triangles in depth order, so each tile's entries come out front to back. Serial: O(slots).
std::vector<torch::Tensor> bin_triangles(const torch::Tensor& bounds, int64_t width,
                                         int64_t height) {
  TORCH_CHECK(bounds.device().is_cpu() && bounds.scalar_type() == torch::kInt32 &&
                  bounds.is_contiguous() && bounds.dim() == 2 && bounds.size(1) == 4,
              "bounds must be a contiguous CPU (K, 4) int32 tensor");
  const int64_t n_tri = bounds.size(0);
  const int tiles_x = static_cast<int>((width + kTile - 1) / kTile);
  const int n_tiles = tiles_x * static_cast<int>((height + kTile - 1) / kTile);
  const int32_t* bd = bounds.data_ptr<int32_t>();
  auto i64 = torch::TensorOptions().dtype(torch::kInt64);
  auto tri_offsets = torch::empty({n_tri + 1}, i64);
  auto tile_offsets = torch::zeros({n_tiles + 1}, i64);
  int64_t* to = tri_offsets.data_ptr<int64_t>();
  int64_t* tile_count = tile_offsets.data_ptr<int64_t>() + 1;
  // Calls fn(tile) for the tiles of triangle k's box, in raster order.
  auto each_tile = [&](int64_t k, auto&& fn) {
    const int32_t* b = bd + 4 * k;
    if (b[2] < b[0] || b[3] < b[1]) return;
    for (int ty = b[1] / kTile; ty <= b[3] / kTile; ++ty) {
      for (int tx = b[0] / kTile; tx <= b[2] / kTile; ++tx) fn(ty * tiles_x + tx);
    }
  };
  to[0] = 0;
  for (int64_t k = 0; k < n_tri; ++k) {
    int64_t count = 0;
    each_tile(k, [&](int t) {
      ++count;
      ++tile_count[t];
    });
    to[k + 1] = to[k] + count;
  }
  int64_t* tile_off = tile_offsets.data_ptr<int64_t>();
  for (int t = 0; t < n_tiles; ++t) tile_off[t + 1] += tile_off[t];
  const int64_t n_slots = to[n_tri];
  auto i32 = torch::TensorOptions().dtype(torch::kInt32);
  auto tile_slots = torch::empty({n_slots}, i32), slot_tri = torch::empty({n_slots}, i32);
  int32_t* ts = tile_slots.data_ptr<int32_t>();
  int32_t* st = slot_tri.data_ptr<int32_t>();
  std::vector<int64_t> cursor(tile_off, tile_off + n_tiles);
  for (int64_t k = 0; k < n_tri; ++k) {
    int64_t slot = to[k];
    each_tile(k, [&](int t) {
      st[slot] = static_cast<int32_t>(k);
      ts[cursor[t]++] = static_cast<int32_t>(slot++);
    });
  }
  return {tile_offsets, tile_slots, slot_tri, tri_offsets};
}

}  // namespace

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("forward", &forward, "triangle rasteriser forward (CPU)");
  m.def("backward", &backward, "triangle rasteriser backward (CPU)");
  m.def("bin_triangles", &bin_triangles, "tile binning by counting sort (CPU)");
  m.def("setup_cull", &lts_cpu::setup_cull, "visibility and depth key per face (CPU)");
  m.def("setup_forward", &lts_cpu::setup_forward, "per-triangle kernel parameters (CPU)");
  m.def("setup_backward", &lts_cpu::setup_backward, "backward of setup_forward (CPU)");
}
