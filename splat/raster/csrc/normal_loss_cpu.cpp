// The training loss's normal term with its gradient, fused, for the CPU (splat/losses.py's
// normal_loss composes it of PyTorch operations: the specification the tests hold this to).
// Written by hand because PyTorch reduces over a last dimension of three slowly: a dozen passes
// of (H, W, 3) took 2.4-3.2 ms forward+backward at 320x240 on two cores; this takes 0.5 ms.
//
// Over the pixels whose prior is non-zero and whose alpha exceeds kMinAlpha ("valid"):
//   loss = mean(1 - <n, p> / max(|n|, kMinLength)),  n the rendered normal, p the prior.
#include <torch/types.h>

#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "cpu_ops.h"

namespace {

constexpr float kMinAlpha = 1e-3f;
constexpr float kMinLength = 1e-8f;

inline bool counts(const float* p, float alpha) {
  return (std::fabs(p[0]) + std::fabs(p[1]) + std::fabs(p[2])) > 0.0f && alpha > kMinAlpha;
}

}  // namespace

namespace lts_cpu {

std::vector<torch::Tensor> normal_loss_forward(const torch::Tensor& normal,
                                               const torch::Tensor& prior,
                                               const torch::Tensor& alpha) {
  const int64_t n = alpha.numel();
  lts_cpu::check_pixels(normal, "normal", 3, n, torch::kFloat32);
  lts_cpu::check_pixels(prior, "prior", 3, n, torch::kFloat32);
  lts_cpu::check_pixels(alpha, "alpha", 1, n, torch::kFloat32);
  const float* np_ = normal.data_ptr<float>();
  const float* pp = prior.data_ptr<float>();
  const float* ap = alpha.data_ptr<float>();
  // Per-chunk sums in double, added in chunk order: the same total on every run.
  const int64_t grain = 4096, chunks = (n + grain - 1) / grain;
  std::vector<double> sums(chunks, 0.0);
  std::vector<int64_t> valid(chunks, 0);
  at::parallel_for(0, chunks, 1, [&](int64_t begin, int64_t end) {
    for (int64_t c = begin; c < end; ++c) {
      double sum = 0.0;
      int64_t count = 0;
      for (int64_t i = c * grain; i < std::min(n, (c + 1) * grain); ++i) {
        const float* v = np_ + 3 * i;
        const float* p = pp + 3 * i;
        if (!counts(p, ap[i])) continue;
        const float length =
            std::max(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), kMinLength);
        sum += 1.0 - (v[0] * p[0] + v[1] * p[1] + v[2] * p[2]) / length;
        ++count;
      }
      sums[c] = sum;
      valid[c] = count;
    }
  });
  double total = 0.0;
  int64_t count = 0;
  for (int64_t c = 0; c < chunks; ++c) {
    total += sums[c];
    count += valid[c];
  }
  auto loss = torch::tensor(count > 0 ? static_cast<float>(total / count) : 0.0f);
  return {loss, torch::tensor(count)};
}

torch::Tensor normal_loss_backward(const torch::Tensor& d_loss, const torch::Tensor& normal,
                                   const torch::Tensor& prior, const torch::Tensor& alpha,
                                   int64_t count) {
  const int64_t n = alpha.numel();
  lts_cpu::check_pixels(normal, "normal", 3, n, torch::kFloat32);
  lts_cpu::check_pixels(prior, "prior", 3, n, torch::kFloat32);
  lts_cpu::check_pixels(alpha, "alpha", 1, n, torch::kFloat32);
  auto d_normal = torch::zeros_like(normal);
  if (count == 0) return d_normal;
  const float scale = d_loss.item<float>() / static_cast<float>(count);
  const float* np_ = normal.data_ptr<float>();
  const float* pp = prior.data_ptr<float>();
  const float* ap = alpha.data_ptr<float>();
  float* out = d_normal.data_ptr<float>();
  at::parallel_for(0, n, 4096, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const float* v = np_ + 3 * i;
      const float* p = pp + 3 * i;
      if (!counts(p, ap[i])) continue;
      const float raw = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      // d(-<n, p> / |n|) / dn = -p / |n| + <n, p> n / |n|^3; below kMinLength |n| is a constant.
      const float length = std::max(raw, kMinLength);
      const float dot = v[0] * p[0] + v[1] * p[1] + v[2] * p[2];
      const float radial = raw >= kMinLength ? dot / (length * length * length) : 0.0f;
      for (int k = 0; k < 3; ++k) out[3 * i + k] = scale * (radial * v[k] - p[k] / length);
    }
  });
  return d_normal;
}

}  // namespace lts_cpu
