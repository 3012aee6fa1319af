// CPU rasteriser: tile-major loops (per 16x16 tile, triangles in depth order outside, the pixel
// blocks of each triangle's box inside, per-tile pixel state in one small array per quantity).
// This order keeps the tile's state in L1 and reads each triangle once per tile; it is ~2x faster
// than a per-pixel loop. A block's pixels are evaluated together in SIMD lanes (lane_math.h).
// Gradients are written per (tile, triangle) slot and summed per triangle in a fixed order, so
// results are deterministic without atomics.
#include "lane_math.h"  // first: it selects the vector instruction set of ATen/cpu/vec

#include <torch/csrc/utils/pybind.h>  // the module's Tensor arguments
#include <torch/types.h>  // not torch/extension.h: all of libtorch's C++ API doubles the compile time

#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>
#include <tuple>
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

// A vector's lanes cover a block of kBlockWidth x (lanes / kBlockWidth) pixels of a tile: a
// (tile, triangle) pair's box is a few pixels across (41 on average in the raster bench), and
// blocks cover the boxes with fewer vectors than rows of a tile do: 7-15 % fewer with 8 lanes
// (4x2), 18-31 % with 16 (4x4) on the demo room's views and the bench's scenes. A tile's pixel
// state is stored block after block, lane after lane (tile_index).
constexpr int kBlockWidth = 4;

template <typename T>
constexpr int block_height() {
  return lane_count<T>() / kBlockWidth;
}

template <typename T>
constexpr int tile_blocks() {
  return kTilePixels / lane_count<T>();
}

static_assert(kTile % kBlockWidth == 0 && kTile % block_height<float>() == 0 &&
                  kTile % block_height<double>() == 0 && block_height<double>() >= 1,
              "a tile must be a whole number of blocks");

// Index of tile pixel (x, y) in the tile's state arrays.
template <typename T>
inline int tile_index(int x, int y) {
  constexpr int height = block_height<T>();
  const int block = (y / height) * (kTile / kBlockWidth) + x / kBlockWidth;
  return block * lane_count<T>() + (y % height) * kBlockWidth + x % kBlockWidth;
}

// Sets the bit of tile pixel i (tile_index) in the tile's per-block masks of live pixels.
template <typename T>
inline void mark_live(uint32_t* live, int i) {
  live[i / lane_count<T>()] |= 1u << (i % lane_count<T>());
}

// Offset of each lane's pixel from its block's first pixel, along x (`rows` false) or y.
template <typename T>
inline Lanes<T> lane_offsets(bool rows) {
  alignas(64) T offset[lane_count<T>()];
  for (int i = 0; i < lane_count<T>(); ++i) offset[i] = T(rows ? i / kBlockWidth : i % kBlockWidth);
  return Lanes<T>::loadu(offset);
}

// Calls fn(i, x, y, in) for every block of the tile that holds a pixel of the pair's box among
// the live ones (bit b of live[block] set for the block's lane b): i is the block's first tile
// pixel index, x and y the lanes' pixel coordinates, `in` the mask of the live pixels of the box.
template <typename T, typename F>
void for_each_block(const Box& box, int tx0, int ty0, const uint32_t* live, const F& fn) {
  using V = Lanes<T>;
  constexpr int height = block_height<T>(), lanes = lane_count<T>();
  static const V columns = lane_offsets<T>(false), rows = lane_offsets<T>(true);
  const int x0 = box.x0 - tx0, x1 = box.x1 - tx0, y0 = box.y0 - ty0, y1 = box.y1 - ty0;
  for (int by = y0 / height; by <= y1 / height; ++by) {
    const int r0 = std::max(y0 - by * height, 0), r1 = std::min(y1 - by * height, height - 1);
    // Bit 0 of each of the box's rows r0..r1 in the block (a row is kBlockWidth lanes).
    const uint32_t row_starts =
        ((uint32_t(1) << (kBlockWidth * (r1 + 1))) - (uint32_t(1) << (kBlockWidth * r0))) /
        ((1u << kBlockWidth) - 1u);
    for (int bx = x0 / kBlockWidth; bx <= x1 / kBlockWidth; ++bx) {
      const int c0 = std::max(x0 - bx * kBlockWidth, 0);
      const int c1 = std::min(x1 - bx * kBlockWidth, kBlockWidth - 1);
      const int block = by * (kTile / kBlockWidth) + bx;
      const uint32_t bits = live[block] & (((2u << c1) - (1u << c0)) * row_starts);
      if (bits == 0) continue;
      const V x = V(T(tx0 + bx * kBlockWidth)) + columns;
      const V y = V(T(ty0 + by * height)) + rows;
      fn(block * lanes, x, y, lanes_of_bits<T>(bits));
    }
  }
}

constexpr int kPrefetchAhead = 2;  // entries

// Starts loading the parameters of the tile's entry e (if any) into the cache: a tile reads its
// triangles in depth order, scattered over the parameter array, and waiting for each one's
// cache lines was the largest single cost of a pair.
template <typename T>
inline void prefetch_entry(const Bins& b, const T* params, int64_t e, int64_t end) {
  if (e < 0 || e >= end) return;
  const int64_t k = b.slot_tri[b.tile_slots[e]];
  const char* first = reinterpret_cast<const char*>(params + k * kParams);
  for (int byte = 0; byte < kParams * static_cast<int>(sizeof(T)); byte += 64) {
    __builtin_prefetch(first + byte);
  }
  __builtin_prefetch(first + kParams * sizeof(T) - 1);
}

// Calls fn(i) for every set bit i of mask, offset by base.
template <typename F>
inline void for_each_bit(uint32_t mask, int base, const F& fn) {
  for (; mask != 0; mask &= mask - 1) fn(base + __builtin_ctz(mask));
}

// Forward compositing state of a tile's pixels, one array per quantity (PixelState of
// triangle_math.h, laid out for lanes).
template <typename T>
struct TileState {
  alignas(64) T transmittance[kTilePixels];
  alignas(64) T rgb[3][kTilePixels];
  alignas(64) T normal[3][kTilePixels];
  alignas(64) T weight_sum[kTilePixels];
  alignas(64) T depth_sum[kTilePixels];
  alignas(64) T depth_shift[kTilePixels];
  alignas(64) T shifted_sum[kTilePixels];
  alignas(64) T shifted_sq[kTilePixels];
  alignas(64) T median[kTilePixels];
  alignas(64) T best_weight[kTilePixels];
  int32_t median_entry[kTilePixels], last_entry[kTilePixels];
  int64_t best[kTilePixels];

  // Every pixel in PixelState's starting state.
  void reset() {
    PixelState<T> fresh;
    fresh.reset();
    for (int i = 0; i < kTilePixels; ++i) store(i, fresh);
  }

  void store(int i, const PixelState<T>& p) {
    transmittance[i] = p.transmittance;
    for (int c = 0; c < 3; ++c) {
      rgb[c][i] = p.rgb[c];
      normal[c][i] = p.normal[c];
    }
    weight_sum[i] = p.weight_sum;
    depth_sum[i] = p.depth_sum;
    depth_shift[i] = p.depth_shift;
    shifted_sum[i] = p.shifted_sum;
    shifted_sq[i] = p.shifted_sq;
    median[i] = p.median;
    best_weight[i] = p.best_weight;
    median_entry[i] = p.median_entry;
    last_entry[i] = p.last_entry;
    best[i] = p.best;
  }

  // Tile pixel i as a PixelState, for write_pixel of pixel_io.h.
  PixelState<T> load(int i) const {
    PixelState<T> p;
    p.transmittance = transmittance[i];
    for (int c = 0; c < 3; ++c) {
      p.rgb[c] = rgb[c][i];
      p.normal[c] = normal[c][i];
    }
    p.weight_sum = weight_sum[i];
    p.depth_sum = depth_sum[i];
    p.depth_shift = depth_shift[i];
    p.shifted_sum = shifted_sum[i];
    p.shifted_sq = shifted_sq[i];
    p.median = median[i];
    p.best_weight = best_weight[i];
    p.median_entry = median_entry[i];
    p.last_entry = last_entry[i];
    p.best = best[i];
    p.done = false;
    return p;
  }

  // PixelState::blend on the lanes from tile pixel i on: composites the pair where `w.hit`.
  // Returns the lanes that saturate (not composited) and raises max_weight to the lanes' weights.
  uint32_t blend(const T* p, const LaneWindow<T>& w, int i, int entry, int64_t triangle,
                 Lanes<T>& max_weight) {
    using V = Lanes<T>;
    const V zero(T(0));
    const V tr = V::loadu(transmittance + i);
    const V next = tr * (V(T(1)) - w.alpha);
    const V saturated = w.hit & (next < V(Thresholds<T>::transmittance_min));
    const V on = and_not(w.hit, saturated);
    const uint32_t on_bits = lane_bits<T>(on);
    if (on_bits != 0) {
      V colour[3], inv_depth;
      eval_attributes(p, w, colour, inv_depth);
      const V z = V(T(1)) / inv_depth;
      const V weight = w.alpha * tr;
      const auto add = [&](T* a, const V& v) {
        const V old = V::loadu(a + i);
        select(on, old + v, old).store(a + i);
      };
      for (int c = 0; c < 3; ++c) {
        add(rgb[c], weight * colour[c]);
        add(normal[c], weight * param(p, kNormal + c));
      }
      const V sum = V::loadu(weight_sum + i);
      const V shift = select(on & (sum == zero), z, V::loadu(depth_shift + i));  // first pair
      shift.store(depth_shift + i);
      const V dz = z - shift;
      add(shifted_sum, weight * dz);
      add(shifted_sq, weight * dz * dz);
      add(depth_sum, weight * z);
      select(on, sum + weight, sum).store(weight_sum + i);
      const V at_median = on & (tr > V(Thresholds<T>::median_transmittance));
      select(at_median, z, V::loadu(median + i)).store(median + i);
      for_each_bit(lane_bits<T>(at_median), i, [&](int k) { median_entry[k] = entry; });
      const V best_so_far = V::loadu(best_weight + i);
      const V better = on & (weight > best_so_far);
      select(better, weight, best_so_far).store(best_weight + i);
      for_each_bit(lane_bits<T>(better), i, [&](int k) { best[k] = triangle; });
      select(on, next, tr).store(transmittance + i);
      for_each_bit(on_bits, i, [&](int k) { last_entry[k] = entry; });
      max_weight = at::vec::maximum(max_weight, select(on, weight, zero));
    }
    return lane_bits<T>(saturated);
  }
};

template <typename T>
void forward_tile(int tile, const Bins& b, const T* params, T* rgb, T* depth, T* alpha, T* normal,
                  T* median, T* distortion, int64_t* dominant, T* transmittance,
                  int32_t* last_entry, int32_t* median_entry, T* slot_max_weight) {
  using V = Lanes<T>;
  const int tx0 = (tile % b.tiles_x) * kTile, ty0 = (tile / b.tiles_x) * kTile;
  const int tw = std::min(kTile, b.width - tx0), th = std::min(kTile, b.height - ty0);
  TileState<T> s;
  s.reset();
  uint32_t live[tile_blocks<T>()] = {};
  for (int y = 0; y < th; ++y) {
    for (int x = 0; x < tw; ++x) mark_live<T>(live, tile_index<T>(x, y));
  }
  int active = tw * th;
  for (int64_t e = b.tile_offsets[tile]; e < b.tile_offsets[tile + 1] && active > 0; ++e) {
    const int32_t slot = b.tile_slots[e];
    const int k = b.slot_tri[slot];
    prefetch_entry(b, params, e + kPrefetchAhead, b.tile_offsets[tile + 1]);
    Box box;
    if (!pair_box(b, k, tx0, ty0, box)) continue;
    const T* p = params + static_cast<int64_t>(k) * kParams;
    V max_weight(T(0));
    for_each_block<T>(box, tx0, ty0, live, [&](int i, const V& x, const V& y, const V& in) {
      const LaneWindow<T> w = eval_window(p, x, y, in);
      if (lane_bits<T>(w.hit) == 0) return;
      const uint32_t saturated = s.blend(p, w, i, static_cast<int>(e), k, max_weight);
      if (saturated != 0) {
        live[i / lane_count<T>()] &= ~saturated;
        active -= __builtin_popcount(saturated);
      }
    });
    slot_max_weight[slot] = at::vec::vec_reduce_all<T>(
        [](const V& a, const V& c) { return at::vec::maximum(a, c); }, max_weight);
  }
  for (int y = 0; y < th; ++y) {
    for (int x = 0; x < tw; ++x) {
      const int64_t o = static_cast<int64_t>(ty0 + y) * b.width + (tx0 + x);
      write_pixel(s.load(tile_index<T>(x, y)), o, rgb, depth, alpha, normal, median, distortion,
                  dominant, transmittance, last_entry, median_entry);
    }
  }
}

// Backward state of a tile's pixels, one array per quantity (PixelGrad of triangle_math.h, laid
// out for lanes).
template <typename T>
struct TileGrads {
  alignas(64) T d_rgb[3][kTilePixels];
  alignas(64) T d_normal[3][kTilePixels];
  alignas(64) T d_depth[kTilePixels];
  alignas(64) T d_alpha[kTilePixels];
  alignas(64) T d_distortion[kTilePixels];
  alignas(64) T d_median_here[kTilePixels];  // d_median at the pixel's median entry, else 0
  alignas(64) T weight_sum[kTilePixels];
  alignas(64) T depth_mean[kTilePixels];
  alignas(64) T depth_m2[kTilePixels];
  alignas(64) T transmittance[kTilePixels];
  alignas(64) T suffix[kTilePixels];
  T d_median[kTilePixels];
  int32_t median_entry[kTilePixels], last_entry[kTilePixels];

  // Stores a pixel's state (read_pixel of pixel_io.h) as tile pixel i.
  void store(int i, const PixelGrad<T>& g) {
    for (int c = 0; c < 3; ++c) {
      d_rgb[c][i] = g.d_rgb[c];
      d_normal[c][i] = g.d_normal[c];
    }
    d_depth[i] = g.d_depth;
    d_alpha[i] = g.d_alpha;
    d_median[i] = g.d_median;
    d_median_here[i] = T(0);
    d_distortion[i] = g.d_distortion;
    weight_sum[i] = g.weight_sum;
    depth_mean[i] = g.depth_mean;
    depth_m2[i] = g.depth_m2;
    transmittance[i] = g.transmittance;
    suffix[i] = g.suffix;
    median_entry[i] = g.median_entry;
    last_entry[i] = g.last_entry;
  }

  // PixelGrad::unblend on the lanes from tile pixel i on, where `w.hit`.
  void unblend(const T* p, const Lanes<T>& x, const Lanes<T>& y, const LaneWindow<T>& w, int i,
               LaneGrads<T>& acc) {
    using V = Lanes<T>;
    const V zero(T(0));
    const auto at = [&](const T* a) { return V::loadu(a + i); };
    const V alpha = select(w.hit, w.alpha, zero);
    const V keep = V(T(1)) / (V(T(1)) - alpha);
    const V tr = at(transmittance) * keep;  // unchanged (x 1) outside the hit lanes
    tr.store(transmittance + i);
    V colour[3], inv_depth;
    eval_attributes(p, w, colour, inv_depth);
    const V z = select(w.hit, V(T(1)) / inv_depth, zero);
    const V weight = alpha * tr;
    const V sum = at(weight_sum), d_dist = at(d_distortion);
    const V dz_mean = z - at(depth_mean);
    V d_weight = at(d_depth) * z + at(d_alpha) + d_dist * (at(depth_m2) + sum * dz_mean * dz_mean);
    V d_colour[3], d_normal_pair[3];
    for (int c = 0; c < 3; ++c) {
      const V dr = at(d_rgb[c]), dn = at(d_normal[c]);
      d_weight = d_weight + (dr * colour[c] + dn * param(p, kNormal + c));
      d_colour[c] = weight * dr;
      d_normal_pair[c] = weight * dn;
    }
    const V old_suffix = at(suffix);
    const V d_alpha_pair = select(w.hit, tr * d_weight - old_suffix * keep, zero);
    (old_suffix + weight * d_weight).store(suffix + i);
    const V d_z = weight * at(d_depth) + d_dist * V(T(2)) * weight * sum * dz_mean +
                  at(d_median_here);
    pair_backward(p, x, y, w, z, d_alpha_pair, d_colour, d_z, d_normal_pair, acc);
  }
};

template <typename T>
void backward_tile(int tile, const Bins& b, const T* params, const T* alpha, const T* depth,
                   const T* distortion, const T* transmittance, const int32_t* last_entry,
                   const int32_t* median_entry, const T* d_rgb, const T* d_depth,
                   const T* d_alpha, const T* d_normal, const T* d_median,
                   const T* d_distortion, T* slot_grads) {
  using V = Lanes<T>;
  const int tx0 = (tile % b.tiles_x) * kTile, ty0 = (tile / b.tiles_x) * kTile;
  const int tw = std::min(kTile, b.width - tx0), th = std::min(kTile, b.height - ty0);
  TileGrads<T> px;
  for (int y = 0; y < kTile; ++y) {
    for (int x = 0; x < kTile; ++x) {
      // Pixels outside the image never join the sweep, but their lanes are computed with the
      // others' (and masked): zeros keep them finite.
      PixelGrad<T> g{};
      g.transmittance = T(1);
      g.median_entry = g.last_entry = -1;
      if (y < th && x < tw) {
        const int64_t o = static_cast<int64_t>(ty0 + y) * b.width + (tx0 + x);
        read_pixel(g, o, alpha, depth, distortion, transmittance, last_entry, median_entry, d_rgb,
                   d_depth, d_alpha, d_normal, d_median, d_distortion);
      }
      px.store(tile_index<T>(x, y), g);
    }
  }
  // Pixels join the back-to-front sweep at their last composited entry, and take d_median at
  // their median entry: visit them in those orders.
  int joins[kTilePixels], medians[kTilePixels];
  for (int i = 0; i < kTilePixels; ++i) joins[i] = medians[i] = i;
  std::sort(joins, joins + kTilePixels,
            [&](int a, int c) { return px.last_entry[a] > px.last_entry[c]; });
  std::sort(medians, medians + kTilePixels,
            [&](int a, int c) { return px.median_entry[a] > px.median_entry[c]; });
  uint32_t live[tile_blocks<T>()] = {};
  int joined = 0, median_next = 0;
  LaneGrads<T> acc;
  for (int64_t e = b.tile_offsets[tile + 1] - 1; e >= b.tile_offsets[tile]; --e) {
    const int32_t slot = b.tile_slots[e];
    T g[kGrads] = {};
    for (; joined < kTilePixels && px.last_entry[joins[joined]] >= e; ++joined) {
      mark_live<T>(live, joins[joined]);
    }
    const int median_first = median_next;
    for (; median_next < kTilePixels && px.median_entry[medians[median_next]] == e; ++median_next) {
      px.d_median_here[medians[median_next]] = px.d_median[medians[median_next]];
    }
    const int k = b.slot_tri[slot];
    prefetch_entry(b, params, e - kPrefetchAhead, b.tile_offsets[tile + 1]);
    Box box;
    if (joined > 0 && pair_box(b, k, tx0, ty0, box)) {
      const T* p = params + static_cast<int64_t>(k) * kParams;
      acc.reset();
      for_each_block<T>(box, tx0, ty0, live, [&](int i, const V& x, const V& y, const V& in) {
        const LaneWindow<T> w = eval_window(p, x, y, in);
        if (lane_bits<T>(w.hit) != 0) px.unblend(p, x, y, w, i, acc);
      });
      acc.sum_into(g);
    }
    for (int m = median_first; m < median_next; ++m) px.d_median_here[medians[m]] = T(0);
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
  m.def(
      "simd", [] { return std::make_tuple(std::string(lane_instruction_set()), lane_count<float>()); },
      "vector instruction set of the kernel and its float lanes per vector");
  m.def("bin_triangles", &bin_triangles, "tile binning by counting sort (CPU)");
  m.def("setup_cull", &lts_cpu::setup_cull, "visibility and depth key per face (CPU)");
  m.def("setup_forward", &lts_cpu::setup_forward, "per-triangle kernel parameters (CPU)");
  m.def("setup_backward", &lts_cpu::setup_backward, "backward of setup_forward (CPU)");
  m.def("ssim_forward", &lts_cpu::ssim_forward, "SSIM map and its partials (CPU)");
  m.def("ssim_backward", &lts_cpu::ssim_backward, "gradient of the SSIM map (CPU)");
  m.def("normal_loss_forward", &lts_cpu::normal_loss_forward, "normal loss, its pixels (CPU)");
  m.def("normal_loss_backward", &lts_cpu::normal_loss_backward, "its gradient (CPU)");
  m.def("error_sums", &lts_cpu::error_sums, "the densification's error sums (CPU)");
}
