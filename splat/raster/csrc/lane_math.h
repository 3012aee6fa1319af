// The per-pair maths of triangle_math.h over a block of pixels of one tile at once (SIMD lanes),
// for the CPU kernel. Each pixel's compositing state is independent of its neighbours', so the
// lanes only share the triangle; the branches of the scalar form become lane masks. The values
// are those of the scalar form (the same operations in the same order, -ffp-contract=off) but
// for exp/log, which are SLEEF's vector versions (1 ulp, as PyTorch's reference uses).
//
// Lanes are at::vec::Vectorized<T>: AVX-512 or AVX2 where the build machine has them (the
// extension is built with -march=native), PyTorch's portable scalar fallback elsewhere. This
// header must be included before anything that includes ATen/cpu/vec/vec.h.
#pragma once

#if defined(__AVX512F__) && defined(__AVX512BW__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
#define CPU_CAPABILITY AVX512
#define CPU_CAPABILITY_AVX512
#elif defined(__AVX2__) && defined(__FMA__)
#define CPU_CAPABILITY AVX2
#define CPU_CAPABILITY_AVX2
#endif

#include <ATen/cpu/vec/functional.h>
#include <ATen/cpu/vec/vec.h>

#include <cstdint>
#include <functional>

#include "triangle_math.h"

namespace lts {

template <typename T>
using Lanes = at::vec::Vectorized<T>;

// Number of lanes in one vector of T.
template <typename T>
constexpr int lane_count() {
  return Lanes<T>::size();
}

// Vector instruction set of the lanes, for reports.
inline const char* lane_instruction_set() {
#if defined(CPU_CAPABILITY_AVX512)
  return "AVX-512";
#elif defined(CPU_CAPABILITY_AVX2)
  return "AVX2";
#else
  return "compiler default";
#endif
}

// Bit i set where lane i of a comparison result is true (all bits set).
template <typename T>
inline uint32_t lane_bits(const Lanes<T>& mask) {
  return ~static_cast<uint32_t>(mask.zero_mask()) & ((1u << lane_count<T>()) - 1u);
}

// The lanes whose bit is set in `bits` (lane i: bit i), as a comparison result.
template <typename T>
inline Lanes<T> lanes_of_bits(uint32_t bits) {
  using I = at::vec::int_same_size_t<T>;
  using VI = Lanes<I>;
  static const VI lane_bit = [] {
    alignas(64) I b[VI::size()];
    for (int i = 0; i < VI::size(); ++i) b[i] = I(1) << i;
    return VI::loadu(b);
  }();
  return at::vec::cast<T>((VI(I(bits)) & lane_bit) == lane_bit);
}

template <typename T>
inline Lanes<T> select(const Lanes<T>& mask, const Lanes<T>& a, const Lanes<T>& b) {
  return Lanes<T>::blendv(b, a, mask);  // a where mask, else b
}

template <typename T>
inline Lanes<T> and_not(const Lanes<T>& a, const Lanes<T>& b) {
  return select(b, Lanes<T>(T(0)), a);
}

// Broadcast of parameter i of a triangle.
template <typename T>
inline Lanes<T> param(const T* p, int i) {
  return Lanes<T>(p[i]);
}

// eval_window of triangle_math.h on lanes: `hit` is the mask of contributing pixels among `in`.
template <typename T>
struct LaneWindow {
  Lanes<T> l[3], m, log_m, intensity, alpha;
  Lanes<T> hit, clamped;
};

template <typename T>
inline LaneWindow<T> eval_window(const T* p, const Lanes<T>& x, const Lanes<T>& y,
                                 const Lanes<T>& in) {
  using V = Lanes<T>;
  LaneWindow<T> w;
  for (int j = 0; j < 3; ++j) {
    // (a x + b y) + d in that order, as the scalar form and the reference compute it.
    w.l[j] = param(p, kLine + 3 * j) * x + param(p, kLine + 3 * j + 1) * y +
             param(p, kLine + 3 * j + 2);
  }
  w.m = at::vec::minimum(w.l[0], at::vec::minimum(w.l[1], w.l[2]));
  // Below the support threshold t (triangle_setup.h) alpha < 1/255: such lanes skip exp and log.
  // The 1e-3 margin is far above the rounding of m^sigma, so no contributing lane is dropped.
  w.hit = in & (w.m > V(T(0))) & (w.m >= V(p[kParams - 1] * T(1 - 1e-3)));
  if (lane_bits<T>(w.hit) == 0) return w;
  w.log_m = w.m.log();
  w.intensity = (param(p, kSigma) * w.log_m).exp();
  const V raw = param(p, kOpacity) * w.intensity;
  w.clamped = raw > V(Thresholds<T>::alpha_max);
  w.alpha = select(w.clamped, V(Thresholds<T>::alpha_max), raw);
  w.hit = w.hit & (w.alpha >= V(Thresholds<T>::alpha_min));
  return w;
}

// eval_attributes of triangle_math.h on lanes: colour and (not yet inverted) inverse depth.
template <typename T>
inline void eval_attributes(const T* p, const LaneWindow<T>& w, Lanes<T> colour[3],
                            Lanes<T>& inv_depth) {
  for (int c = 0; c < 3; ++c) colour[c] = w.l[0] * param(p, kColor + c);
  inv_depth = w.l[0] * param(p, kInvDepth);
  for (int j = 1; j < 3; ++j) {
    for (int c = 0; c < 3; ++c) colour[c] = colour[c] + w.l[j] * param(p, kColor + 3 * j + c);
    inv_depth = inv_depth + w.l[j] * param(p, kInvDepth + j);
  }
}

// Sums of a pair's parameter gradients over its pixels, one vector per parameter.
template <typename T>
struct LaneGrads {
  Lanes<T> g[kGrads];

  void reset() {
    for (auto& v : g) v = Lanes<T>(T(0));
  }

  // Reduces the lanes into g_out[kGrads] (a fixed order: deterministic).
  void sum_into(T* g_out) const {
    for (int i = 0; i < kGrads; ++i) {
      g_out[i] = at::vec::vec_reduce_all<T>(std::plus<Lanes<T>>(), g[i]);
    }
  }
};

// pair_backward of triangle_math.h on lanes. Lanes outside `w.hit` must arrive with zero
// upstream gradients and finite depth; they add nothing.
template <typename T>
inline void pair_backward(const T* p, const Lanes<T>& x, const Lanes<T>& y,
                          const LaneWindow<T>& w, const Lanes<T>& depth, const Lanes<T>& d_alpha,
                          const Lanes<T> d_colour[3], const Lanes<T>& d_depth,
                          const Lanes<T> d_normal[3], LaneGrads<T>& acc) {
  using V = Lanes<T>;
  V* g = acc.g;
  const V zero(T(0));
  const V free = and_not(w.hit, w.clamped);  // alpha = o I, not clamped
  const V intensity = select(free, w.intensity, zero);
  g[kOpacity] = g[kOpacity] + d_alpha * intensity;
  const V d_intensity = d_alpha * param(p, kOpacity);
  g[kSigma] = g[kSigma] + d_intensity * intensity * select(free, w.log_m, zero);
  const V d_m = d_intensity * param(p, kSigma) * intensity / select(free, w.m, V(T(1)));
  // The minimum's index, first one on ties (as the scalar form's).
  const V first_is_1 = w.l[1] < w.l[0];
  const V is_2 = w.l[2] < select(first_is_1, w.l[1], w.l[0]);
  const V is_1 = and_not(first_is_1, is_2);
  V d_l[3] = {select(is_1 | is_2, zero, d_m), select(is_1, d_m, zero), select(is_2, d_m, zero)};
  const V d_inv = zero - depth * depth * d_depth;
  for (int j = 0; j < 3; ++j) {
    for (int c = 0; c < 3; ++c) {
      g[kColor + 3 * j + c] = g[kColor + 3 * j + c] + w.l[j] * d_colour[c];
      d_l[j] = d_l[j] + param(p, kColor + 3 * j + c) * d_colour[c];
    }
    g[kInvDepth + j] = g[kInvDepth + j] + w.l[j] * d_inv;
    d_l[j] = d_l[j] + param(p, kInvDepth + j) * d_inv;
    g[kLine + 3 * j] = g[kLine + 3 * j] + d_l[j] * x;
    g[kLine + 3 * j + 1] = g[kLine + 3 * j + 1] + d_l[j] * y;
    g[kLine + 3 * j + 2] = g[kLine + 3 * j + 2] + d_l[j];
  }
  for (int c = 0; c < 3; ++c) g[kNormal + c] = g[kNormal + c] + d_normal[c];
}

}  // namespace lts
