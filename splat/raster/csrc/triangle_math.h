// Per-(pixel, triangle) maths of the triangle rasteriser: the parameter layout and thresholds
// both kernels share, and the per-pixel form the CUDA kernel runs (the CPU kernel runs the same
// operations over a row of pixels in SIMD lanes: lane_math.h).
//
// The kernels are hand-written because no library rasterises triangle *windows* (soft,
// sigma-sharpened edge functions) with the outputs and backward pass we need; the loop structure
// differs per target (tile-major on the CPU, pixel-per-thread on the GPU), the maths does not.
//
// A triangle arrives pre-processed (splat/raster/project.py) as kParams numbers:
//   [0, 9)   three normalised edge functions l_j(x, y) = a_j x + b_j y + d_j; l_j = 1 at the
//            incentre, 0 on edge j, so the TS window ratio phi(p)/phi(s) is min_j l_j(p)
//   [9, 18)  colour coefficients C_j (rgb each): colour(p) = sum_j l_j(p) C_j (barycentric)
//   [18, 21) inverse-depth coefficients W_j: 1/z(p) = sum_j l_j(p) W_j (perspective-correct)
//   21 opacity o, 22 sharpness sigma, [23, 26) camera-frame unit normal,
//   26 support threshold (min l inside which alpha can reach 1/255; binning only, no gradient).
#pragma once

#include <math.h>  // the kernels call sqrt, fmin, isfinite unqualified: float overloads in ::

#include <cmath>
#include <cstdint>

#ifdef __CUDACC__
#define LTS_HD __host__ __device__ __forceinline__
#else
#define LTS_HD inline
#endif

namespace lts {

constexpr int kTile = 16;
constexpr int kTilePixels = kTile * kTile;
constexpr int kParams = 27;
constexpr int kGrads = 26;  // every parameter but the support threshold
constexpr int kLine = 0, kColor = 9, kInvDepth = 18, kOpacity = 21, kSigma = 22, kNormal = 23;

LTS_HD float exponential(float a) { return expf(a); }
LTS_HD double exponential(double a) { return exp(a); }
LTS_HD float logarithm(float a) { return logf(a); }
LTS_HD double logarithm(double a) { return log(a); }

template <typename T>
struct Thresholds {
  static constexpr T alpha_min = T(1.0 / 255.0);
  static constexpr T alpha_max = T(0.99);
  static constexpr T transmittance_min = T(1e-4);
  static constexpr T median_transmittance = T(0.5);
};

// Opacity of one triangle at one pixel, with what the backward pass needs to differentiate it.
template <typename T>
struct Window {
  T l[3];        // edge functions
  T m;           // min_j l_j (window ratio)
  T log_m;       // log(m), reused by the sigma gradient
  int arg;       // index of the minimum (first one on ties)
  T intensity;   // I = m^sigma
  T alpha;       // min(alpha_max, o I)
  bool clamped;  // o I > alpha_max: alpha does not depend on o or I
};

// Evaluates the window at pixel (x, y); false when the pair does not contribute (alpha < 1/255).
template <typename T>
LTS_HD bool eval_window(const T* p, T x, T y, Window<T>& w) {
  w.arg = 0;
  for (int j = 0; j < 3; ++j) {
    w.l[j] = p[kLine + 3 * j] * x + p[kLine + 3 * j + 1] * y + p[kLine + 3 * j + 2];
  }
  w.m = w.l[0];
  if (w.l[1] < w.m) { w.m = w.l[1]; w.arg = 1; }
  if (w.l[2] < w.m) { w.m = w.l[2]; w.arg = 2; }
  if (!(w.m > T(0))) return false;
  w.log_m = logarithm(w.m);
  w.intensity = exponential(p[kSigma] * w.log_m);
  const T raw = p[kOpacity] * w.intensity;
  w.clamped = raw > Thresholds<T>::alpha_max;
  w.alpha = w.clamped ? Thresholds<T>::alpha_max : raw;
  return w.alpha >= Thresholds<T>::alpha_min;
}

// Colour and depth of the triangle at a pixel from its edge functions.
template <typename T>
LTS_HD void eval_attributes(const T* p, const Window<T>& w, T colour[3], T& depth) {
  T inv = T(0);
  for (int c = 0; c < 3; ++c) colour[c] = T(0);
  for (int j = 0; j < 3; ++j) {
    for (int c = 0; c < 3; ++c) colour[c] += w.l[j] * p[kColor + 3 * j + c];
    inv += w.l[j] * p[kInvDepth + j];
  }
  depth = T(1) / inv;
}

// Chain rule from d(loss)/d(alpha, colour, depth, normal) of one pair to its parameters,
// accumulated into g[kGrads].
template <typename T>
LTS_HD void pair_backward(const T* p, T x, T y, const Window<T>& w, T depth, T d_alpha,
                          const T d_colour[3], T d_depth, const T d_normal[3], T* g) {
  T d_m = T(0);
  if (!w.clamped) {
    g[kOpacity] += d_alpha * w.intensity;
    const T d_intensity = d_alpha * p[kOpacity];
    g[kSigma] += d_intensity * w.intensity * w.log_m;
    d_m = d_intensity * p[kSigma] * w.intensity / w.m;
  }
  // Selects rather than d_l[w.arg]: a run-time index would keep d_l in memory.
  T d_l[3] = {w.arg == 0 ? d_m : T(0), w.arg == 1 ? d_m : T(0), w.arg == 2 ? d_m : T(0)};
  const T d_inv = -depth * depth * d_depth;
  for (int j = 0; j < 3; ++j) {
    for (int c = 0; c < 3; ++c) {
      g[kColor + 3 * j + c] += w.l[j] * d_colour[c];
      d_l[j] += p[kColor + 3 * j + c] * d_colour[c];
    }
    g[kInvDepth + j] += w.l[j] * d_inv;
    d_l[j] += p[kInvDepth + j] * d_inv;
    g[kLine + 3 * j] += d_l[j] * x;
    g[kLine + 3 * j + 1] += d_l[j] * y;
    g[kLine + 3 * j + 2] += d_l[j];
  }
  for (int c = 0; c < 3; ++c) g[kNormal + c] += d_normal[c];
}

// Per-pixel compositing state of the forward pass (front to back).
template <typename T>
struct PixelState {
  T transmittance;
  T rgb[3];
  T weight_sum;      // accumulated alpha
  T depth_sum;       // sum w z
  T normal[3];
  // Distortion: sum_{i<j} w_i w_j (z_i - z_j)^2 = A S2 - S1^2 with S1, S2 sums of w (z - c) and
  // w (z - c)^2 for any shift c; c = depth of the first pair keeps the difference well
  // conditioned without a per-pair division.
  T depth_shift, shifted_sum, shifted_sq;
  T median;
  T best_weight;
  int median_entry;  // position in the tile's list of the median triangle, -1 if none
  int last_entry;    // position of the last triangle composited, -1 if none
  long best;         // sorted index of the dominant triangle, -1 if none
  bool done;

  LTS_HD void reset() {
    transmittance = T(1);
    weight_sum = depth_sum = depth_shift = shifted_sum = shifted_sq = median = best_weight = T(0);
    for (int c = 0; c < 3; ++c) rgb[c] = normal[c] = T(0);
    median_entry = last_entry = -1;
    best = -1;
    done = false;
  }

  // Composites one contributing pair; returns its blending weight, or -1 when the pixel is
  // saturated (transmittance would fall below the threshold: the pair is not composited).
  LTS_HD T blend(const T* p, const Window<T>& w, int entry, long triangle) {
    const T next = transmittance * (T(1) - w.alpha);
    if (next < Thresholds<T>::transmittance_min) {
      done = true;
      return T(-1);
    }
    T colour[3], z;
    eval_attributes(p, w, colour, z);
    const T weight = w.alpha * transmittance;
    for (int c = 0; c < 3; ++c) {
      rgb[c] += weight * colour[c];
      normal[c] += weight * p[kNormal + c];
    }
    if (last_entry < 0) depth_shift = z;
    const T dz = z - depth_shift;
    shifted_sum += weight * dz;
    shifted_sq += weight * dz * dz;
    depth_sum += weight * z;
    weight_sum += weight;
    if (transmittance > Thresholds<T>::median_transmittance) {
      median = z;
      median_entry = entry;
    }
    if (weight > best_weight) {
      best_weight = weight;
      best = triangle;
    }
    transmittance = next;
    last_entry = entry;
    return weight;
  }

  LTS_HD T distortion() const {
    const T d = weight_sum * shifted_sq - shifted_sum * shifted_sum;
    return d > T(0) ? d : T(0);
  }
};

// Upstream gradients of one pixel and the back-to-front state of the backward pass.
template <typename T>
struct PixelGrad {
  T d_rgb[3], d_depth, d_alpha, d_normal[3], d_median, d_distortion;
  T weight_sum, depth_mean, depth_m2;  // from the forward outputs
  T transmittance;                     // transmittance after the current pair
  T suffix;                            // sum over pairs behind the current one of w * dL/dw
  int median_entry, last_entry;

  // Back-propagates through one composited pair, accumulating parameter gradients into g.
  LTS_HD void unblend(const T* p, T x, T y, const Window<T>& w, int entry, T* g) {
    const T keep = T(1) / (T(1) - w.alpha);  // 1 / (1 - alpha)
    transmittance = transmittance * keep;
    T colour[3], z;
    eval_attributes(p, w, colour, z);
    const T weight = w.alpha * transmittance;
    const T dz_mean = z - depth_mean;
    T d_weight = d_depth * z + d_alpha + d_distortion * (depth_m2 + weight_sum * dz_mean * dz_mean);
    for (int c = 0; c < 3; ++c) d_weight += d_rgb[c] * colour[c] + d_normal[c] * p[kNormal + c];
    const T d_alpha_pair = transmittance * d_weight - suffix * keep;
    suffix += weight * d_weight;
    T d_colour[3], d_normal_pair[3];
    for (int c = 0; c < 3; ++c) {
      d_colour[c] = weight * d_rgb[c];
      d_normal_pair[c] = weight * d_normal[c];
    }
    T d_z = weight * d_depth + d_distortion * T(2) * weight * weight_sum * dz_mean;
    if (entry == median_entry) d_z += d_median;
    pair_backward(p, x, y, w, z, d_alpha_pair, d_colour, d_z, d_normal_pair, g);
  }
};

}  // namespace lts
