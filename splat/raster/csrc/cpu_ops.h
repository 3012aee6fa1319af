// Operations of the CPU extension (bound to Python in raster_cpu.cpp).
#pragma once

#include <torch/types.h>

#include <vector>

namespace lts_cpu {

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

}  // namespace lts_cpu
