// SSIM of a render against its target with the gradient for the render, fused, for the training
// loss's D-SSIM term (splat/losses.py, whose PyTorch composition is the specification the tests
// hold this to). Written by hand because no library has it on the CPU: PyTorch composes it from
// grouped convolutions and a dozen element-wise steps, each a pass over memory with its own
// allocation: 7.2 ms forward+backward an iteration of the room's training at 320x240 on two
// cores, a quarter of the step; this takes 2.2 ms.
//
// Planes are (C, H, W) float32, one channel after another. The window is separable (1-D taps w,
// odd length 2r+1) with reflected borders:
//   blur(p)[i][j] = sum_a sum_b w[a] w[b] p[R(i+a-r)][R(j+b-r)],
// R(q) = -q below 0 and 2(n-1)-q beyond n-1 (PyTorch's "reflect" padding). Both passes work on
// blocks of rows, each streaming its rows through a ring of the last 2r+1 rows filtered along x,
// so that nothing but the inputs and outputs goes to memory (the work is bound by memory, not
// arithmetic).
#include <torch/types.h>

#include <ATen/Parallel.h>

#include <algorithm>
#include <vector>

#include "cpu_ops.h"

namespace {

constexpr float kC1 = 0.01f * 0.01f;
constexpr float kC2 = 0.03f * 0.03f;
constexpr float kEps = 1e-12f;
constexpr int64_t kBlockRows = 64;  // rows of one task: 12 tasks at 320x240, halo rows 2r/64

inline int64_t reflect(int64_t q, int64_t n) { return q < 0 ? -q : (q >= n ? 2 * (n - 1) - q : q); }

// out (n) = taps w (2r+1) correlated with padded (n + 2r): out[j] = sum_a w[a] padded[j + a].
inline void correlate(const float* __restrict__ padded, const float* w, int64_t r, int64_t n,
                      float* __restrict__ out) {
  for (int64_t j = 0; j < n; ++j) out[j] = 0.0f;
  for (int64_t a = 0; a <= 2 * r; ++a) {
    const float wa = w[a];
    const float* in = padded + a;
    for (int64_t j = 0; j < n; ++j) out[j] += wa * in[j];
  }
}

// The adjoint of correlate on a reflected row: out (n) = the transposed correlation of row (n)
// with taps w, its padding (padded, n + 2r, scratch) folded back onto the columns it reflects.
inline void correlate_adjoint(const float* __restrict__ row, const float* w, int64_t r, int64_t n,
                              float* __restrict__ padded, float* __restrict__ out) {
  for (int64_t q = 0; q < n + 2 * r; ++q) padded[q] = 0.0f;
  for (int64_t a = 0; a <= 2 * r; ++a) {
    const float wa = w[a];
    float* __restrict__ dst = padded + a;
    for (int64_t j = 0; j < n; ++j) dst[j] += wa * row[j];
  }
  for (int64_t j = 0; j < n; ++j) out[j] = padded[j + r];
  for (int64_t q = -r; q < 0; ++q) out[reflect(q, n)] += padded[q + r];
  for (int64_t q = n; q < n + r; ++q) out[reflect(q, n)] += padded[q + r];
}

// SSIM of one row (W) from the render's blurred moments (3 x W: mean, x*x, x*y) and the target's
// mean and mean square, into s (W), and its partials by the three moments into d, d + stride and
// d + 2 stride. The same operations in the same order as splat.losses.composed_ssim_map.
inline void ssim_row(const float* __restrict__ moments, const float* __restrict__ mu_y,
                     const float* __restrict__ yy, int64_t W, float* __restrict__ s,
                     float* __restrict__ d, int64_t stride) {
  const float* __restrict__ mu_x = moments;
  const float* __restrict__ xx = moments + W;
  const float* __restrict__ xy = moments + 2 * W;
  float* __restrict__ d_mu = d;
  float* __restrict__ d_xx = d + stride;
  float* __restrict__ d_xy = d + 2 * stride;
  for (int64_t j = 0; j < W; ++j) {
    const float mu_xy = mu_x[j] * mu_y[j], mu_x2 = mu_x[j] * mu_x[j], mu_y2 = mu_y[j] * mu_y[j];
    const float a1 = 2 * mu_xy + kC1, a2 = 2 * (xy[j] - mu_xy) + kC2;
    const float b1 = mu_x2 + mu_y2 + kC1, b2 = (xx[j] - mu_x2) + (yy[j] - mu_y2) + kC2;
    const float inv = 1.0f / (b1 * b2 + kEps);
    const float value = (a1 * a2) * inv;
    s[j] = value;
    d_mu[j] = 2 * mu_y[j] * (a2 - a1) * inv - 2 * mu_x[j] * value * (b2 - b1) * inv;
    d_xx[j] = -value * b1 * inv;
    d_xy[j] = 2 * a1 * inv;
  }
}

void check_planes(const torch::Tensor& t, const char* name, int64_t C, int64_t H, int64_t W) {
  lts_cpu::check_contiguous_float(t, name);
  TORCH_CHECK(t.dim() == 3 && t.size(0) == C && t.size(1) == H && t.size(2) == W, name,
              ": expected shape (", C, ", ", H, ", ", W, ")");
}

}  // namespace

namespace lts_cpu {

std::vector<torch::Tensor> ssim_forward(const torch::Tensor& x, const torch::Tensor& y,
                                        const torch::Tensor& target_moments,
                                        const torch::Tensor& window) {
  TORCH_CHECK(x.dim() == 3, "x: expected (C, H, W)");
  const int64_t C = x.size(0), H = x.size(1), W = x.size(2);
  check_planes(x, "x", C, H, W);
  check_planes(y, "y", C, H, W);
  check_planes(target_moments, "target_moments", 2 * C, H, W);
  TORCH_CHECK(window.dim() == 1 && window.size(0) % 2 == 1 && window.is_contiguous() &&
                  window.scalar_type() == torch::kFloat32,
              "window: expected odd-length contiguous float32 taps");
  const int64_t r = window.size(0) / 2;
  TORCH_CHECK(H > r && W > r, "images must be larger than the window's radius ", r);
  const int64_t plane = H * W;
  const float* w = window.data_ptr<float>();
  const float* xp = x.data_ptr<float>();
  const float* yp = y.data_ptr<float>();

  auto ssim = torch::empty({C, H, W}, x.options());
  auto partials = torch::empty({3, C, H, W}, x.options());  // d/d mu_x, d/d blur(xx), d/d blur(xy)
  float* sp = ssim.data_ptr<float>();
  float* dp = partials.data_ptr<float>();
  const float* mp = target_moments.data_ptr<float>();
  const int64_t taps = 2 * r + 1, block = std::min(H, kBlockRows), blocks = (H + block - 1) / block;
  at::parallel_for(0, C * blocks, 1, [&](int64_t begin, int64_t end) {
    std::vector<float> padded(3 * (W + 2 * r)), ring(3 * taps * W), moments(3 * W);
    float* px = padded.data();
    float* pxx = px + W + 2 * r;
    float* pxy = pxx + W + 2 * r;
    for (int64_t task = begin; task < end; ++task) {
      const int64_t c = task / blocks, i0 = (task % blocks) * block, i1 = std::min(H, i0 + block);
      const float* xc = xp + c * plane;
      const float* yc = yp + c * plane;
      for (int64_t q = i0 - r; q < i1 + r; ++q) {
        const int64_t src = reflect(q, H) * W;
        for (int64_t j = -r; j < W + r; ++j) {
          const int64_t k = src + reflect(j, W);
          px[j + r] = xc[k];
          pxx[j + r] = xc[k] * xc[k];
          pxy[j + r] = xc[k] * yc[k];
        }
        const int64_t slot = ((q - i0 + r) % taps) * W;
        correlate(px, w, r, W, ring.data() + slot);
        correlate(pxx, w, r, W, ring.data() + taps * W + slot);
        correlate(pxy, w, r, W, ring.data() + 2 * taps * W + slot);
        const int64_t i = q - r;
        if (i < i0) continue;
        for (int64_t m = 0; m < 3; ++m) {  // blur along y: the ring's rows i-r .. i+r
          float* __restrict__ out = moments.data() + m * W;
          for (int64_t j = 0; j < W; ++j) out[j] = 0.0f;
          for (int64_t a = 0; a < taps; ++a) {
            const float wa = w[a];
            const float* __restrict__ row = ring.data() + (m * taps + (i - i0 + a) % taps) * W;
            for (int64_t j = 0; j < W; ++j) out[j] += wa * row[j];
          }
        }
        ssim_row(moments.data(), mp + c * plane + i * W, mp + (C + c) * plane + i * W, W,
                 sp + c * plane + i * W, dp + c * plane + i * W, C * plane);
      }
    }
  });
  return {ssim, partials};
}

torch::Tensor ssim_backward(const torch::Tensor& d_ssim, const torch::Tensor& x,
                            const torch::Tensor& y, const torch::Tensor& partials,
                            const torch::Tensor& window) {
  const int64_t C = x.size(0), H = x.size(1), W = x.size(2);
  check_planes(d_ssim, "d_ssim", C, H, W);
  check_planes(x, "x", C, H, W);
  check_planes(y, "y", C, H, W);
  TORCH_CHECK(partials.is_contiguous() && partials.numel() == 3 * C * H * W,
              "partials: expected (3, C, H, W)");
  const int64_t r = window.size(0) / 2, plane = H * W;
  const float* w = window.data_ptr<float>();
  const float* gp = d_ssim.data_ptr<float>();
  const float* pp = partials.data_ptr<float>();

  // d x = B'(g d_mu) + 2 x B'(g d_xx) + y B'(g d_xy), B' the adjoint of the blur: along x, the
  // transposed correlation of each row folded at its ends; along y, out row m gathers rows
  // m - r .. m + r of that (from the ring) plus, near the top and bottom, the padding rows that
  // reflect onto m.
  auto d_x = torch::empty_like(x);
  float* out = d_x.data_ptr<float>();
  const float* xp = x.data_ptr<float>();
  const float* yp = y.data_ptr<float>();
  const int64_t taps = 2 * r + 1, block = std::min(H, kBlockRows), blocks = (H + block - 1) / block;
  at::parallel_for(0, C * blocks, 1, [&](int64_t begin, int64_t end) {
    std::vector<float> product(W), padded(W + 2 * r), ring(3 * taps * W), spread(3 * W);
    for (int64_t task = begin; task < end; ++task) {
      const int64_t c = task / blocks, m0 = (task % blocks) * block, m1 = std::min(H, m0 + block);
      auto slot = [&](int64_t k, int64_t i) {
        return ring.data() + (k * taps + (i - m0 + 2 * taps) % taps) * W;
      };
      // t (W) += padded row p of term k's transposed correlation along y: sum_a w[a] row p - a.
      auto gather = [&](int64_t k, int64_t p, float* __restrict__ t) {
        for (int64_t a = 0; a <= 2 * r; ++a) {
          if (p - a < 0 || p - a >= H) continue;
          const float wa = w[a];
          const float* __restrict__ row = slot(k, p - a);
          for (int64_t j = 0; j < W; ++j) t[j] += wa * row[j];
        }
      };
      int64_t next = std::max<int64_t>(0, m0 - r);  // the next row to take along x
      for (int64_t m = m0; m < m1; ++m) {
        for (; next <= std::min(H - 1, m + r); ++next) {
          const float* g = gp + c * plane + next * W;
          for (int64_t k = 0; k < 3; ++k) {
            const float* d = pp + (k * C + c) * plane + next * W;
            for (int64_t j = 0; j < W; ++j) product[j] = g[j] * d[j];
            correlate_adjoint(product.data(), w, r, W, padded.data(), slot(k, next));
          }
        }
        for (int64_t k = 0; k < 3; ++k) {
          float* t = spread.data() + k * W;
          for (int64_t j = 0; j < W; ++j) t[j] = 0.0f;
          gather(k, m + r, t);
          if (m >= 1 && m <= r) gather(k, r - m, t);  // the top padding reflects onto rows 1 .. r
          if (m >= H - 1 - r && m <= H - 2) gather(k, 2 * (H - 1) - m + r, t);  // and the bottom's
        }
        const int64_t offset = c * plane + m * W;
        const float* __restrict__ t0 = spread.data();
        const float* __restrict__ t1 = t0 + W;
        const float* __restrict__ t2 = t1 + W;
        float* __restrict__ o = out + offset;
        const float* __restrict__ xm = xp + offset;
        const float* __restrict__ ym = yp + offset;
        for (int64_t j = 0; j < W; ++j) o[j] = t0[j] + 2 * xm[j] * t1[j] + ym[j] * t2[j];
      }
    }
  });
  return d_x;
}

}  // namespace lts_cpu
