// The variance densification's statistics of one render in one pass (splat/strategy/variance.py's
// composed_error_sums, its depth, normal and colour errors summed per face by
// splat/raster/stats.py's dominant_sums, is the specification the tests hold this to). Written by
// hand because the composition takes a dozen passes over the image, three of them over (H, W, 3)
// with PyTorch's slow reductions over a last dimension of three: 3.1 ms of each of the first 1500
// iterations of a 320x240 training.
//
// Each error is computed with the composition's operations in its order (the normal's length is
// PyTorch's, passed in), and summed serially in pixel order and in the values' precision like
// dominant_sums' bincounts: the same sums to the bit.
#include <torch/types.h>

#include <cmath>
#include <limits>
#include <vector>

#include "cpu_ops.h"

namespace {

template <typename T>
const T* optional_data(const torch::Tensor& t) {
  return t.numel() > 0 ? t.data_ptr<T>() : nullptr;
}

}  // namespace

namespace lts_cpu {

std::vector<torch::Tensor> error_sums(const torch::Tensor& dominant, int64_t n_faces,
                                      const torch::Tensor& accumulated_depth,
                                      const torch::Tensor& lidar_depth,
                                      const torch::Tensor& normal,
                                      const torch::Tensor& normal_length,
                                      const torch::Tensor& prior, const torch::Tensor& known,
                                      const torch::Tensor& rgb, const torch::Tensor& image,
                                      const torch::Tensor& alpha, const torch::Tensor& moving) {
  const int64_t n = dominant.numel();
  const auto dtype = accumulated_depth.scalar_type();
  check_pixels(dominant, "dominant", 1, n, torch::kInt64);
  check_pixels(accumulated_depth, "accumulated_depth", 1, n, dtype);
  check_pixels(lidar_depth, "lidar_depth", 1, n, dtype, true);
  check_pixels(normal, "normal", 3, n, dtype);
  check_pixels(normal_length, "normal_length", 1, n, dtype, prior.numel() == 0);
  check_pixels(prior, "prior", 3, n, dtype, true);
  check_pixels(known, "known", 1, n, torch::kBool, prior.numel() == 0);
  check_pixels(rgb, "rgb", 3, n, dtype);
  check_pixels(image, "image", 3, n, dtype);
  check_pixels(alpha, "alpha", 1, n, dtype);
  check_pixels(moving, "moving", 1, n, torch::kBool, true);
  std::vector<torch::Tensor> sums;
  for (int q = 0; q < 3; ++q) {
    sums.push_back(torch::zeros({n_faces}, dominant.options()));
    sums.push_back(torch::zeros({n_faces}, accumulated_depth.options()));
    sums.push_back(torch::zeros({n_faces}, accumulated_depth.options()));
  }
  const int64_t* face = dominant.data_ptr<int64_t>();
  const bool* kn = optional_data<bool>(known);
  const bool* mv = optional_data<bool>(moving);
  AT_DISPATCH_FLOATING_TYPES(dtype, "lts_error_sums", [&] {
    using T = scalar_t;
    const T* acc = accumulated_depth.data_ptr<T>();
    const T* lidar = optional_data<T>(lidar_depth);
    const T* nrm = normal.data_ptr<T>();
    const T* len = optional_data<T>(normal_length);
    const T* pri = optional_data<T>(prior);
    const T* col = rgb.data_ptr<T>();
    const T* img = image.data_ptr<T>();
    const T* alp = alpha.data_ptr<T>();
    const T tiny = std::numeric_limits<T>::min();
    int64_t* count[3];
    T* sum[3];
    T* sum_sq[3];
    for (int q = 0; q < 3; ++q) {
      count[q] = sums[3 * q].data_ptr<int64_t>();
      sum[q] = sums[3 * q + 1].data_ptr<T>();
      sum_sq[q] = sums[3 * q + 2].data_ptr<T>();
    }
    // Adds value to quantity q's sums of face f.
    const auto add = [&](int q, int64_t f, T value) {
      count[q][f] += 1;
      sum[q][f] += value;
      sum_sq[q][f] += value * value;
    };
    for (int64_t i = 0; i < n; ++i) {
      const int64_t f = face[i];
      if (f < 0) continue;
      TORCH_CHECK(f < n_faces, "dominant: face ", f, " of ", n_faces);
      // variance.lidar_returns: a finite return > 0.
      const bool returned = lidar != nullptr && std::isfinite(lidar[i]) && lidar[i] > T(0);
      if (returned) add(0, f, lidar[i] - acc[i]);
      if (pri != nullptr && kn[i] && len[i] > T(0)) {
        const T l = std::max(len[i], tiny);
        const T* p = pri + 3 * i;
        const T* v = nrm + 3 * i;
        add(1, f, T(1) - ((p[0] * (v[0] / l) + p[1] * (v[1] / l)) + p[2] * (v[2] / l)));
      }
      if (alp[i] >= T(0.5) && !returned && !(mv != nullptr && mv[i])) {
        const T* a = img + 3 * i;
        const T* b = col + 3 * i;
        add(2, f, (((a[0] - b[0]) + (a[1] - b[1])) + (a[2] - b[2])) / T(3));
      }
    }
  });
  return sums;
}

}  // namespace lts_cpu
