// CPU per-triangle set-up with its backward (maths in triangle_setup.h). Doing this in C++ rather
// than with ~100 small PyTorch ops makes it ~10x cheaper; the PyTorch version (project.py) is the
// specification the tests hold it to.
#include <torch/types.h>

#include <ATen/Parallel.h>

#include <vector>

#include "bins.h"
#include "cpu_ops.h"
#include "triangle_setup.h"

namespace {

using namespace lts;

// Pointers to a face's three vertex rows of an (N, stride) array.
template <typename T>
struct Corners {
  const T* row[3];
  Corners(const T* base, const int64_t* face, int stride) {
    for (int i = 0; i < 3; ++i) row[i] = base + face[i] * stride;
  }
};

}  // namespace

namespace lts_cpu {

std::vector<torch::Tensor> setup_cull(const torch::Tensor& vertices, const torch::Tensor& faces,
                                      const torch::Tensor& opacities, const torch::Tensor& sigma,
                                      const torch::Tensor& view, int64_t width, int64_t height) {
  const int64_t n = faces.size(0);
  auto keep = torch::empty({n}, faces.options().dtype(torch::kBool));
  auto key = torch::empty({n}, vertices.options());
  AT_DISPATCH_FLOATING_TYPES(vertices.scalar_type(), "lts_setup_cull", [&] {
    const View<scalar_t> v = make_view<scalar_t>(view, width, height);
    const scalar_t* vert = vertices.data_ptr<scalar_t>();
    const scalar_t* op = opacities.data_ptr<scalar_t>();
    const scalar_t* sg = sigma.data_ptr<scalar_t>();
    const int64_t* f = faces.data_ptr<int64_t>();
    bool* kp = keep.data_ptr<bool>();
    scalar_t* ky = key.data_ptr<scalar_t>();
    at::parallel_for(0, n, 2048, [&](int64_t a, int64_t b) {
      for (int64_t i = a; i < b; ++i) {
        scalar_t o;
        min_opacity(op, f + 3 * i, &o);
        kp[i] = visible(v, Corners<scalar_t>(vert, f + 3 * i, 3).row, o, sg[i], ky + i);
      }
    });
  });
  return {keep, key};
}

std::vector<torch::Tensor> setup_forward(const torch::Tensor& vertices, const torch::Tensor& faces,
                                         const torch::Tensor& colors,
                                         const torch::Tensor& opacities,
                                         const torch::Tensor& sigma, const torch::Tensor& kept,
                                         const torch::Tensor& rank, const torch::Tensor& view,
                                         int64_t width, int64_t height) {
  const int64_t n = kept.size(0);
  auto params = torch::empty({n, kParams}, vertices.options());
  auto bounds = torch::empty({n, 4}, faces.options().dtype(torch::kInt32));
  AT_DISPATCH_FLOATING_TYPES(vertices.scalar_type(), "lts_setup_forward", [&] {
    const View<scalar_t> v = make_view<scalar_t>(view, width, height);
    const scalar_t* vert = vertices.data_ptr<scalar_t>();
    const scalar_t* col = colors.data_ptr<scalar_t>();
    const scalar_t* op = opacities.data_ptr<scalar_t>();
    const scalar_t* sg = sigma.data_ptr<scalar_t>();
    const int64_t* f = faces.data_ptr<int64_t>();
    const int64_t* kp = kept.data_ptr<int64_t>();
    const int64_t* rk = rank.data_ptr<int64_t>();
    scalar_t* p = params.data_ptr<scalar_t>();
    int32_t* bd = bounds.data_ptr<int32_t>();
    at::parallel_for(0, n, 2048, [&](int64_t a, int64_t b) {
      for (int64_t j = a; j < b; ++j) {
        const int64_t* face = f + 3 * kp[j];
        scalar_t o;
        min_opacity(op, face, &o);
        int box[4];
        setup(v, Corners<scalar_t>(vert, face, 3).row, Corners<scalar_t>(col, face, 3).row, o,
              sg[kp[j]], p + rk[j] * kParams, box);
        for (int i = 0; i < 4; ++i) bd[4 * rk[j] + i] = box[i];
      }
    });
  });
  return {params, bounds};
}

std::vector<torch::Tensor> setup_backward(const torch::Tensor& vertices,
                                          const torch::Tensor& faces,
                                          const torch::Tensor& colors,
                                          const torch::Tensor& opacities,
                                          const torch::Tensor& kept, const torch::Tensor& rank,
                                          const torch::Tensor& view, int64_t width,
                                          int64_t height, const torch::Tensor& d_params,
                                          int64_t n_faces) {
  const int64_t n = kept.size(0);
  constexpr int kPer = 3 * 3 + 3 * 3;  // world-vertex and colour gradients of one face
  auto per_face = torch::empty({n, kPer}, vertices.options());
  auto d_vertices = torch::zeros_like(vertices);
  auto d_colors = torch::zeros_like(colors);
  auto d_opacities = torch::zeros_like(opacities);
  auto d_sigma = torch::zeros({n_faces}, vertices.options());
  AT_DISPATCH_FLOATING_TYPES(vertices.scalar_type(), "lts_setup_backward", [&] {
    const View<scalar_t> v = make_view<scalar_t>(view, width, height);
    const scalar_t* vert = vertices.data_ptr<scalar_t>();
    const scalar_t* col = colors.data_ptr<scalar_t>();
    const scalar_t* op = opacities.data_ptr<scalar_t>();
    const int64_t* f = faces.data_ptr<int64_t>();
    const int64_t* kp = kept.data_ptr<int64_t>();
    const int64_t* rk = rank.data_ptr<int64_t>();
    const scalar_t* g = d_params.data_ptr<scalar_t>();
    scalar_t* pf = per_face.data_ptr<scalar_t>();
    at::parallel_for(0, n, 2048, [&](int64_t a, int64_t b) {
      for (int64_t j = a; j < b; ++j) {
        const int64_t* face = f + 3 * kp[j];
        scalar_t gP[3][3], gcol[3][3];
        setup_backward(v, Corners<scalar_t>(vert, face, 3).row, Corners<scalar_t>(col, face, 3).row,
                       g + rk[j] * kParams, gP, gcol);
        scalar_t* out = pf + j * kPer;
        for (int i = 0; i < 3; ++i) {
          for (int c = 0; c < 3; ++c) {  // world gradient: R^T gP
            out[3 * i + c] = v.R[c] * gP[i][0] + v.R[3 + c] * gP[i][1] + v.R[6 + c] * gP[i][2];
            out[9 + 3 * i + c] = gcol[i][c];
          }
        }
      }
    });
    // Faces may share vertices: scatter serially, in face order, so sums are deterministic.
    scalar_t* dv = d_vertices.data_ptr<scalar_t>();
    scalar_t* dc = d_colors.data_ptr<scalar_t>();
    scalar_t* dop = d_opacities.data_ptr<scalar_t>();
    scalar_t* ds = d_sigma.data_ptr<scalar_t>();
    for (int64_t j = 0; j < n; ++j) {
      const int64_t* face = f + 3 * kp[j];
      const scalar_t* in = pf + j * kPer;
      for (int i = 0; i < 3; ++i) {
        for (int c = 0; c < 3; ++c) {
          dv[3 * face[i] + c] += in[3 * i + c];
          dc[3 * face[i] + c] += in[9 + 3 * i + c];
        }
      }
      scalar_t o;
      dop[face[min_opacity(op, face, &o)]] += g[rk[j] * kParams + kOpacity];
      ds[kp[j]] += g[rk[j] * kParams + kSigma];
    }
  });
  return {d_vertices, d_colors, d_opacities, d_sigma};
}

}  // namespace lts_cpu
