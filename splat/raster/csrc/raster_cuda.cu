// CUDA rasteriser with the CPU extension's interface. GPU loop structure (3DGS-style): one block
// per 16x16 tile, one thread per pixel, the tile's triangles streamed through shared memory in
// batches. The per-pair and per-triangle maths are the CPU kernel's (triangle_math.h,
// triangle_setup.h). Pair gradients are reduced in a fixed order per (tile, triangle) slot, then
// per triangle, so the rasteriser's backward uses no floating-point atomics.
#include <torch/csrc/utils/pybind.h>  // the module's Tensor arguments
#include <torch/types.h>  // not torch/extension.h: all of libtorch's C++ API doubles the compile time

#include <c10/cuda/CUDAException.h>
#include <c10/cuda/CUDAGuard.h>
#include <c10/cuda/CUDAStream.h>

#include <vector>

#include "bins.h"
#include "pixel_io.h"
#include "triangle_math.h"
#include "triangle_setup.h"

namespace {

using namespace lts;

constexpr int kBatch = 128;  // triangles per shared-memory batch (27 doubles each fit in 48 KB)
constexpr int kWarps = kTilePixels / 32;

inline int blocks_for(int64_t n, int threads) { return static_cast<int>((n + threads - 1) / threads); }

// Max for non-negative values: their bit patterns order like unsigned integers.
__device__ inline void atomic_max_nonneg(float* address, float value) {
  atomicMax(reinterpret_cast<unsigned int*>(address), __float_as_uint(value));
}
__device__ inline void atomic_max_nonneg(double* address, double value) {
  atomicMax(reinterpret_cast<unsigned long long*>(address),
            static_cast<unsigned long long>(__double_as_longlong(value)));
}

template <typename T>
struct Corners {
  const T* row[3];
  __device__ Corners(const T* base, const int64_t* face) {
    for (int i = 0; i < 3; ++i) row[i] = base + 3 * face[i];
  }
};

template <typename T>
__global__ void cull_kernel(int64_t n, View<T> v, const T* vert, const int64_t* faces,
                            const T* opacities, const T* sigma, bool* keep, T* key) {
  const int64_t i = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  T o;
  min_opacity(opacities, faces + 3 * i, &o);
  keep[i] = visible(v, Corners<T>(vert, faces + 3 * i).row, o, sigma[i], key + i);
}

template <typename T>
__global__ void setup_kernel(int64_t n, View<T> v, const T* vert, const T* colors,
                             const int64_t* faces, const T* opacities, const T* sigma,
                             const int64_t* kept, const int64_t* rank, T* params,
                             int32_t* bounds) {
  const int64_t j = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x;
  if (j >= n) return;
  const int64_t* face = faces + 3 * kept[j];
  T o;
  min_opacity(opacities, face, &o);
  int box[4];
  setup(v, Corners<T>(vert, face).row, Corners<T>(colors, face).row, o, sigma[kept[j]],
        params + rank[j] * kParams, box);
  for (int i = 0; i < 4; ++i) bounds[4 * rank[j] + i] = box[i];
}

// Per-face gradients: world vertices (9), colours (9), and the vertex that gives the opacity.
template <typename T>
__global__ void setup_backward_kernel(int64_t n, View<T> v, const T* vert, const T* colors,
                                      const int64_t* faces, const T* opacities,
                                      const int64_t* kept, const int64_t* rank,
                                      const T* d_params, T* per_face, int64_t* opacity_vertex) {
  const int64_t j = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x;
  if (j >= n) return;
  const int64_t* face = faces + 3 * kept[j];
  T gP[3][3], gcol[3][3], o;
  setup_backward(v, Corners<T>(vert, face).row, Corners<T>(colors, face).row,
                 d_params + rank[j] * kParams, gP, gcol);
  T* out = per_face + 18 * j;
  for (int i = 0; i < 3; ++i) {
    for (int c = 0; c < 3; ++c) {
      out[3 * i + c] = v.R[c] * gP[i][0] + v.R[3 + c] * gP[i][1] + v.R[6 + c] * gP[i][2];
      out[9 + 3 * i + c] = gcol[i][c];
    }
  }
  opacity_vertex[j] = face[min_opacity(opacities, face, &o)];
}

// Loads entries [first, first + n) of a tile into shared memory.
template <typename T>
__device__ void load_batch(const Bins& b, const T* params, int64_t first, int n, T* sp, int* box,
                           int* slot, int* tri) {
  for (int i = threadIdx.x; i < n; i += blockDim.x) {
    slot[i] = b.tile_slots[first + i];
    tri[i] = b.slot_tri[slot[i]];
    for (int c = 0; c < 4; ++c) box[4 * i + c] = b.bounds[4 * static_cast<int64_t>(tri[i]) + c];
  }
  __syncthreads();
  for (int j = threadIdx.x; j < n * kParams; j += blockDim.x) {
    sp[j] = params[static_cast<int64_t>(tri[j / kParams]) * kParams + j % kParams];
  }
  __syncthreads();
}

__device__ inline bool in_box(const int* box, int x, int y) {
  return x >= box[0] && x <= box[2] && y >= box[1] && y <= box[3];
}

template <typename T>
__global__ void __launch_bounds__(kTilePixels)
    forward_kernel(Bins b, const T* params, T* rgb, T* depth, T* alpha, T* normal, T* median,
                   T* distortion, int64_t* dominant, T* transmittance, int32_t* last_entry,
                   int32_t* median_entry, T* slot_max_weight) {
  __shared__ T sp[kBatch * kParams];
  __shared__ int s_box[4 * kBatch], s_slot[kBatch], s_tri[kBatch];
  const int tile = blockIdx.x;
  const int x = (tile % b.tiles_x) * kTile + threadIdx.x % kTile;
  const int y = (tile / b.tiles_x) * kTile + threadIdx.x / kTile;
  const bool inside = x < b.width && y < b.height;
  PixelState<T> s;
  s.reset();
  s.done = !inside;
  const int64_t begin = b.tile_offsets[tile], end = b.tile_offsets[tile + 1];
  for (int64_t first = begin; first < end; first += kBatch) {
    if (__syncthreads_count(!s.done) == 0) break;
    const int n = static_cast<int>(min(static_cast<int64_t>(kBatch), end - first));
    load_batch(b, params, first, n, sp, s_box, s_slot, s_tri);
    for (int i = 0; i < n && !s.done; ++i) {
      if (!in_box(s_box + 4 * i, x, y)) continue;
      const T* p = sp + i * kParams;
      Window<T> w;
      if (!eval_window(p, T(x), T(y), w)) continue;
      const T weight = s.blend(p, w, static_cast<int>(first + i), s_tri[i]);
      if (weight > T(0)) atomic_max_nonneg(slot_max_weight + s_slot[i], weight);
    }
  }
  if (!inside) return;
  write_pixel(s, static_cast<int64_t>(y) * b.width + x, rgb, depth, alpha, normal, median,
              distortion, dominant, transmittance, last_entry, median_entry);
}

template <typename T>
__global__ void __launch_bounds__(kTilePixels)
    backward_kernel(Bins b, const T* params, const T* alpha, const T* depth, const T* distortion,
                    const T* transmittance, const int32_t* last_entry,
                    const int32_t* median_entry, const T* d_rgb, const T* d_depth,
                    const T* d_alpha, const T* d_normal, const T* d_median,
                    const T* d_distortion, T* slot_grads) {
  __shared__ T sp[kBatch * kParams];
  __shared__ int s_box[4 * kBatch], s_slot[kBatch], s_tri[kBatch];
  __shared__ T s_partial[kWarps][kGrads];
  const int tile = blockIdx.x;
  const int x = (tile % b.tiles_x) * kTile + threadIdx.x % kTile;
  const int y = (tile / b.tiles_x) * kTile + threadIdx.x / kTile;
  const bool inside = x < b.width && y < b.height;
  PixelGrad<T> g;
  g.last_entry = -1;
  if (inside) {
    read_pixel(g, static_cast<int64_t>(y) * b.width + x, alpha, depth, distortion, transmittance,
               last_entry, median_entry, d_rgb, d_depth, d_alpha, d_normal, d_median,
               d_distortion);
  }
  const int lane = threadIdx.x % 32, warp = threadIdx.x / 32;
  const int64_t begin = b.tile_offsets[tile], end = b.tile_offsets[tile + 1];
  for (int64_t stop = end; stop > begin; stop -= kBatch) {
    const int64_t first = max(begin, stop - kBatch);
    const int n = static_cast<int>(stop - first);
    __syncthreads();  // the previous batch is no longer read
    load_batch(b, params, first, n, sp, s_box, s_slot, s_tri);
    for (int i = n - 1; i >= 0; --i) {
      const int64_t e = first + i;
      T acc[kGrads];
      for (int c = 0; c < kGrads; ++c) acc[c] = T(0);
      bool any = false;
      if (e <= g.last_entry && in_box(s_box + 4 * i, x, y)) {
        const T* p = sp + i * kParams;
        Window<T> w;
        if (eval_window(p, T(x), T(y), w)) {
          g.unblend(p, T(x), T(y), w, static_cast<int>(e), acc);
          any = true;
        }
      }
      T* out = slot_grads + static_cast<int64_t>(s_slot[i]) * kGrads;
      if (__syncthreads_or(any)) {  // block-uniform: reduce in a fixed order
        for (int c = 0; c < kGrads; ++c) {
          T v = acc[c];
          for (int offset = 16; offset > 0; offset /= 2) v += __shfl_down_sync(0xffffffffu, v, offset);
          if (lane == 0) s_partial[warp][c] = v;
        }
        __syncthreads();
        if (threadIdx.x < kGrads) {
          T sum = T(0);
          for (int w = 0; w < kWarps; ++w) sum += s_partial[w][threadIdx.x];
          out[threadIdx.x] = sum;
        }
      } else if (threadIdx.x < kGrads) {
        out[threadIdx.x] = T(0);
      }
    }
  }
}

template <typename T>
__global__ void reduce_kernel(int64_t n_tri, const int64_t* tri_offsets, const T* slot_grads,
                              const T* slot_max_weight, T* d_params, T* max_weight) {
  const int64_t k = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x;
  if (k >= n_tri) return;
  if (max_weight != nullptr) {
    T m = T(0);
    for (int64_t s = tri_offsets[k]; s < tri_offsets[k + 1]; ++s) m = fmax(m, slot_max_weight[s]);
    max_weight[k] = m;
  }
  if (d_params != nullptr) {
    for (int c = 0; c < kGrads; ++c) {
      T sum = T(0);
      for (int64_t s = tri_offsets[k]; s < tri_offsets[k + 1]; ++s) sum += slot_grads[s * kGrads + c];
      d_params[k * kParams + c] = sum;
    }
  }
}

std::vector<torch::Tensor> forward_cuda(const torch::Tensor& params, const torch::Tensor& bounds,
                                   const torch::Tensor& tile_offsets,
                                   const torch::Tensor& tile_slots, const torch::Tensor& slot_tri,
                                   const torch::Tensor& tri_offsets, int64_t width,
                                   int64_t height) {
  TORCH_CHECK(params.is_cuda(), "params must be on a CUDA device");
  const c10::cuda::OptionalCUDAGuard guard(params.device());
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
  const auto stream = c10::cuda::getCurrentCUDAStream();
  AT_DISPATCH_FLOATING_TYPES(params.scalar_type(), "lts_raster_forward_cuda", [&] {
    forward_kernel<scalar_t><<<b.n_tiles, kTilePixels, 0, stream>>>(
        b, params.data_ptr<scalar_t>(), rgb.data_ptr<scalar_t>(), depth.data_ptr<scalar_t>(),
        alpha.data_ptr<scalar_t>(), normal.data_ptr<scalar_t>(), median.data_ptr<scalar_t>(),
        distortion.data_ptr<scalar_t>(), dominant.data_ptr<int64_t>(),
        transmittance.data_ptr<scalar_t>(), last_entry.data_ptr<int32_t>(),
        median_entry.data_ptr<int32_t>(), slot_max_weight.data_ptr<scalar_t>());
    if (n_tri > 0) {
      reduce_kernel<scalar_t><<<blocks_for(n_tri, 256), 256, 0, stream>>>(
          n_tri, b.tri_offsets, static_cast<const scalar_t*>(nullptr),
          slot_max_weight.data_ptr<scalar_t>(), static_cast<scalar_t*>(nullptr),
          max_weight.data_ptr<scalar_t>());
    }
  });
  C10_CUDA_KERNEL_LAUNCH_CHECK();
  return {rgb,      depth,      alpha,         normal,     median,      distortion,
          dominant, max_weight, transmittance, last_entry, median_entry};
}

torch::Tensor backward_cuda(const torch::Tensor& params, const torch::Tensor& bounds,
                       const torch::Tensor& tile_offsets, const torch::Tensor& tile_slots,
                       const torch::Tensor& slot_tri, const torch::Tensor& tri_offsets,
                       int64_t width, int64_t height, const torch::Tensor& alpha,
                       const torch::Tensor& depth, const torch::Tensor& distortion,
                       const torch::Tensor& transmittance, const torch::Tensor& last_entry,
                       const torch::Tensor& median_entry, const torch::Tensor& d_rgb,
                       const torch::Tensor& d_depth, const torch::Tensor& d_alpha,
                       const torch::Tensor& d_normal, const torch::Tensor& d_median,
                       const torch::Tensor& d_distortion) {
  TORCH_CHECK(params.is_cuda(), "params must be on a CUDA device");
  const c10::cuda::OptionalCUDAGuard guard(params.device());
  const Bins b =
      make_bins(params, bounds, tile_offsets, tile_slots, slot_tri, tri_offsets, width, height);
  const int64_t n_tri = params.size(0);
  auto slot_grads = torch::empty({tile_slots.numel(), kGrads}, params.options());
  auto d_params = torch::zeros({n_tri, kParams}, params.options());
  const auto stream = c10::cuda::getCurrentCUDAStream();
  AT_DISPATCH_FLOATING_TYPES(params.scalar_type(), "lts_raster_backward_cuda", [&] {
    backward_kernel<scalar_t><<<b.n_tiles, kTilePixels, 0, stream>>>(
        b, params.data_ptr<scalar_t>(), alpha.data_ptr<scalar_t>(), depth.data_ptr<scalar_t>(),
        distortion.data_ptr<scalar_t>(), transmittance.data_ptr<scalar_t>(),
        last_entry.data_ptr<int32_t>(), median_entry.data_ptr<int32_t>(),
        d_rgb.data_ptr<scalar_t>(), d_depth.data_ptr<scalar_t>(), d_alpha.data_ptr<scalar_t>(),
        d_normal.data_ptr<scalar_t>(), d_median.data_ptr<scalar_t>(),
        d_distortion.data_ptr<scalar_t>(), slot_grads.data_ptr<scalar_t>());
    if (n_tri > 0) {
      reduce_kernel<scalar_t><<<blocks_for(n_tri, 256), 256, 0, stream>>>(
          n_tri, b.tri_offsets, slot_grads.data_ptr<scalar_t>(),
          static_cast<const scalar_t*>(nullptr), d_params.data_ptr<scalar_t>(),
          static_cast<scalar_t*>(nullptr));
    }
  });
  C10_CUDA_KERNEL_LAUNCH_CHECK();
  return d_params;
}

std::vector<torch::Tensor> setup_cull_cuda(const torch::Tensor& vertices, const torch::Tensor& faces,
                                      const torch::Tensor& opacities, const torch::Tensor& sigma,
                                      const torch::Tensor& view, int64_t width, int64_t height) {
  const c10::cuda::OptionalCUDAGuard guard(vertices.device());
  const int64_t n = faces.size(0);
  auto keep = torch::empty({n}, faces.options().dtype(torch::kBool));
  auto key = torch::empty({n}, vertices.options());
  if (n == 0) return {keep, key};
  AT_DISPATCH_FLOATING_TYPES(vertices.scalar_type(), "lts_setup_cull_cuda", [&] {
    cull_kernel<scalar_t><<<blocks_for(n, 256), 256, 0, c10::cuda::getCurrentCUDAStream()>>>(
        n, make_view<scalar_t>(view, width, height), vertices.data_ptr<scalar_t>(),
        faces.data_ptr<int64_t>(), opacities.data_ptr<scalar_t>(), sigma.data_ptr<scalar_t>(),
        keep.data_ptr<bool>(), key.data_ptr<scalar_t>());
  });
  C10_CUDA_KERNEL_LAUNCH_CHECK();
  return {keep, key};
}

std::vector<torch::Tensor> setup_forward_cuda(const torch::Tensor& vertices, const torch::Tensor& faces,
                                         const torch::Tensor& colors,
                                         const torch::Tensor& opacities,
                                         const torch::Tensor& sigma, const torch::Tensor& kept,
                                         const torch::Tensor& rank, const torch::Tensor& view,
                                         int64_t width, int64_t height) {
  const c10::cuda::OptionalCUDAGuard guard(vertices.device());
  const int64_t n = kept.size(0);
  auto params = torch::empty({n, kParams}, vertices.options());
  auto bounds = torch::empty({n, 4}, faces.options().dtype(torch::kInt32));
  if (n == 0) return {params, bounds};
  AT_DISPATCH_FLOATING_TYPES(vertices.scalar_type(), "lts_setup_forward_cuda", [&] {
    setup_kernel<scalar_t><<<blocks_for(n, 256), 256, 0, c10::cuda::getCurrentCUDAStream()>>>(
        n, make_view<scalar_t>(view, width, height), vertices.data_ptr<scalar_t>(),
        colors.data_ptr<scalar_t>(), faces.data_ptr<int64_t>(), opacities.data_ptr<scalar_t>(),
        sigma.data_ptr<scalar_t>(), kept.data_ptr<int64_t>(), rank.data_ptr<int64_t>(),
        params.data_ptr<scalar_t>(), bounds.data_ptr<int32_t>());
  });
  C10_CUDA_KERNEL_LAUNCH_CHECK();
  return {params, bounds};
}

std::vector<torch::Tensor> setup_backward_cuda(const torch::Tensor& vertices,
                                          const torch::Tensor& faces,
                                          const torch::Tensor& colors,
                                          const torch::Tensor& opacities,
                                          const torch::Tensor& kept, const torch::Tensor& rank,
                                          const torch::Tensor& view, int64_t width,
                                          int64_t height, const torch::Tensor& d_params,
                                          int64_t n_faces) {
  const c10::cuda::OptionalCUDAGuard guard(vertices.device());
  const int64_t n = kept.size(0);
  auto per_face = torch::empty({n, 18}, vertices.options());
  auto opacity_vertex = torch::empty({n}, faces.options());
  if (n > 0) {
    AT_DISPATCH_FLOATING_TYPES(vertices.scalar_type(), "lts_setup_backward_cuda", [&] {
      setup_backward_kernel<scalar_t>
          <<<blocks_for(n, 256), 256, 0, c10::cuda::getCurrentCUDAStream()>>>(
              n, make_view<scalar_t>(view, width, height), vertices.data_ptr<scalar_t>(),
              colors.data_ptr<scalar_t>(), faces.data_ptr<int64_t>(),
              opacities.data_ptr<scalar_t>(), kept.data_ptr<int64_t>(), rank.data_ptr<int64_t>(),
              d_params.data_ptr<scalar_t>(), per_face.data_ptr<scalar_t>(),
              opacity_vertex.data_ptr<int64_t>());
    });
    C10_CUDA_KERNEL_LAUNCH_CHECK();
  }
  // Shared vertices: scatter with index_add_ (atomic on the GPU, so not bit-reproducible there).
  const auto vertex_ids = faces.index_select(0, kept).reshape({-1});
  const auto g = d_params.index_select(0, rank);  // rows in face order
  auto d_vertices = torch::zeros_like(vertices).index_add_(0, vertex_ids, per_face.slice(1, 0, 9).reshape({-1, 3}));
  auto d_colors = torch::zeros_like(colors).index_add_(0, vertex_ids, per_face.slice(1, 9, 18).reshape({-1, 3}));
  auto d_opacities = torch::zeros_like(opacities).index_add_(0, opacity_vertex, g.select(1, kOpacity));
  auto d_sigma = torch::zeros({n_faces}, vertices.options()).index_add_(0, kept, g.select(1, kSigma));
  return {d_vertices, d_colors, d_opacities, d_sigma};
}

}  // namespace

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("forward", &forward_cuda, "triangle rasteriser forward (CUDA)");
  m.def("backward", &backward_cuda, "triangle rasteriser backward (CUDA)");
  m.def("setup_cull", &setup_cull_cuda, "visibility and depth key per face (CUDA)");
  m.def("setup_forward", &setup_forward_cuda, "per-triangle kernel parameters (CUDA)");
  m.def("setup_backward", &setup_backward_cuda, "backward of setup_forward (CUDA)");
}
