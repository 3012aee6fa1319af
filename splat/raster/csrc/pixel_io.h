// Per-pixel image I/O of the triangle rasteriser, shared by the CPU and CUDA kernels: what the
// forward pass writes for a pixel, and what the backward pass reads back for it (the forward
// outputs and the upstream gradients). `o` is the pixel's row-major index y * width + x.
#pragma once

#include <cstdint>

#include "triangle_math.h"

namespace lts {

// Writes a pixel's composited state into the forward output images.
template <typename T>
LTS_HD void write_pixel(const PixelState<T>& s, int64_t o, T* rgb, T* depth, T* alpha, T* normal,
                        T* median, T* distortion, int64_t* dominant, T* transmittance,
                        int32_t* last_entry, int32_t* median_entry) {
  for (int c = 0; c < 3; ++c) {
    rgb[3 * o + c] = s.rgb[c];
    normal[3 * o + c] = s.normal[c];
  }
  depth[o] = s.depth_sum;
  alpha[o] = s.weight_sum;
  median[o] = s.median;
  distortion[o] = s.distortion();
  dominant[o] = s.best;
  transmittance[o] = s.transmittance;
  last_entry[o] = s.last_entry;
  median_entry[o] = s.median_entry;
}

// Starts a pixel's backward pass: its upstream gradients and the forward outputs it needs.
template <typename T>
LTS_HD void read_pixel(PixelGrad<T>& g, int64_t o, const T* alpha, const T* depth,
                       const T* distortion, const T* transmittance, const int32_t* last_entry,
                       const int32_t* median_entry, const T* d_rgb, const T* d_depth,
                       const T* d_alpha, const T* d_normal, const T* d_median,
                       const T* d_distortion) {
  for (int c = 0; c < 3; ++c) {
    g.d_rgb[c] = d_rgb[3 * o + c];
    g.d_normal[c] = d_normal[3 * o + c];
  }
  g.d_depth = d_depth[o];
  g.d_alpha = d_alpha[o];
  g.d_median = d_median[o];
  g.d_distortion = d_distortion[o];
  g.weight_sum = alpha[o];
  const bool hit = alpha[o] > T(0);
  g.depth_mean = hit ? depth[o] / alpha[o] : T(0);
  g.depth_m2 = hit ? distortion[o] / alpha[o] : T(0);
  g.transmittance = transmittance[o];
  g.suffix = T(0);
  g.median_entry = median_entry[o];
  g.last_entry = last_entry[o];
}

}  // namespace lts
