// Operations of the CPU extension (bound to Python in raster_cpu.cpp).
#pragma once

#include <torch/types.h>

#include <vector>

namespace lts_cpu {

// The fused loss kernels' arguments must be contiguous float32 CPU tensors.
inline void check_contiguous_float(const torch::Tensor& t, const char* name) {
  TORCH_CHECK(t.device().is_cpu() && t.scalar_type() == torch::kFloat32 && t.is_contiguous(), name,
              ": expected a contiguous float32 CPU tensor");
}

// A per-pixel argument of the fused kernels: a contiguous CPU tensor of `dtype` with `per_pixel`
// values for each of `n` pixels (or empty, where `optional`).
inline void check_pixels(const torch::Tensor& t, const char* name, int64_t per_pixel, int64_t n,
                         torch::ScalarType dtype, bool optional = false) {
  if (optional && t.numel() == 0) return;
  TORCH_CHECK(t.device().is_cpu() && t.scalar_type() == dtype && t.is_contiguous() &&
                  t.numel() == per_pixel * n,
              name, ": expected a contiguous CPU tensor of ", per_pixel, " ",
              c10::toString(dtype), " a pixel");
}

// Visibility (F,) bool and depth-sort key (F,) of every face.
std::vector<torch::Tensor> setup_cull(const torch::Tensor& vertices, const torch::Tensor& faces,
                                      const torch::Tensor& opacities, const torch::Tensor& sigma,
                                      const torch::Tensor& view, int64_t width, int64_t height);

// Kernel parameters (K, 27) and pixel boxes (K, 4) of the faces `kept` (K,), ascending, each
// written to row `rank` (K,) (its place in depth order): reading faces in order is cache-friendly.
std::vector<torch::Tensor> setup_forward(const torch::Tensor& vertices, const torch::Tensor& faces,
                                         const torch::Tensor& colors,
                                         const torch::Tensor& opacities,
                                         const torch::Tensor& sigma, const torch::Tensor& kept,
                                         const torch::Tensor& rank, const torch::Tensor& view,
                                         int64_t width, int64_t height);

// Gradients for vertices, colours, opacities and sigma (n_faces,) from d(params).
std::vector<torch::Tensor> setup_backward(const torch::Tensor& vertices,
                                          const torch::Tensor& faces,
                                          const torch::Tensor& colors,
                                          const torch::Tensor& opacities,
                                          const torch::Tensor& kept, const torch::Tensor& rank,
                                          const torch::Tensor& view, int64_t width,
                                          int64_t height, const torch::Tensor& d_params,
                                          int64_t n_faces);

// SSIM (C, H, W) of a render x (C, H, W) against its target y (C, H, W), whose blurred mean and
// mean square are target_moments (2C, H, W), with the window's 1-D taps; and the per-pixel
// partials (3, C, H, W) of SSIM by the render's blurred x, x*x and x*y that ssim_backward needs.
std::vector<torch::Tensor> ssim_forward(const torch::Tensor& x, const torch::Tensor& y,
                                        const torch::Tensor& target_moments,
                                        const torch::Tensor& window);

// The gradient (C, H, W) for x from d(SSIM) (C, H, W).
torch::Tensor ssim_backward(const torch::Tensor& d_ssim, const torch::Tensor& x,
                            const torch::Tensor& y, const torch::Tensor& partials,
                            const torch::Tensor& window);

// The normal loss (a 0-d tensor) and how many pixels it averages (a 0-d int64 tensor) of rendered
// normals (H, W, 3) against a prior (H, W, 3) where alpha (H, W) shows a surface.
std::vector<torch::Tensor> normal_loss_forward(const torch::Tensor& normal,
                                               const torch::Tensor& prior,
                                               const torch::Tensor& alpha);

// The gradient (H, W, 3) for the rendered normals from d(loss) (0-d).
torch::Tensor normal_loss_backward(const torch::Tensor& d_loss, const torch::Tensor& normal,
                                   const torch::Tensor& prior, const torch::Tensor& alpha,
                                   int64_t count);

// The variance densification's depth, normal and colour error sums of one render: count (F,)
// int64, sum and sum of squares (F,) of each, in that order (9 tensors). lidar_depth (H, W), prior
// (H, W, 3) with normal_length (H, W) and known (H, W) bool, and moving (H, W) bool may be empty.
std::vector<torch::Tensor> error_sums(const torch::Tensor& dominant, int64_t n_faces,
                                      const torch::Tensor& accumulated_depth,
                                      const torch::Tensor& lidar_depth,
                                      const torch::Tensor& normal,
                                      const torch::Tensor& normal_length,
                                      const torch::Tensor& prior, const torch::Tensor& known,
                                      const torch::Tensor& rgb, const torch::Tensor& image,
                                      const torch::Tensor& alpha, const torch::Tensor& moving);

}  // namespace lts_cpu
