// The photo-consistency cost's inner loop (calib/photo_consistency.py's _Problem.point_sums, whose
// NumPy form is the specification the tests hold this to), in one pass over the observations.
// Written by hand because the search scores thousands of extrinsics, each over ~200 000 (frame,
// point) observations, and the NumPy form takes some forty passes over them (4 ms a score, three
// quarters of `lts calibrate`'s search).
//
// Per observation: the map point moved into the camera by its frame's transform (the candidate
// extrinsic, and the frame placed where the candidate time offset puts it), projected,
// and its grey level sampled bilinearly in its frame (edges repeated); per frame, the grey levels
// of the observations inside the image standardised (auto-exposure); per map point, the sums of
// its standardised grey levels, of their squares and their count, added in observation order.
// The frames' grey levels on `threads` threads, each a block of whole frames; the per-point sums on
// one, in observation order, so that any number of threads gives the same sums to the bit. One
// thread where another process is busy: with OpenMP's two a score took 1.4 ms instead of 2.3 on a
// quiet 2-core machine but 27 ms while another process kept a core busy, and `lts reconstruct`
// maps in a process beside the calibration (so it asks for one).
#include <torch/csrc/utils/pybind.h>  // the module's Tensor arguments
#include <torch/types.h>  // not torch/extension.h: all of libtorch's C++ API doubles the compile time

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "parallel_blocks.h"
#include "pinhole.h"

namespace {

// Observations projected at once before their samples are gathered.
constexpr int64_t kChunk = 256;

void check(const torch::Tensor& t, const char* name, torch::ScalarType dtype, int64_t dims) {
  TORCH_CHECK(t.device().is_cpu() && t.scalar_type() == dtype && t.is_contiguous() && t.dim() == dims,
              name, ": expected a contiguous ", dims, "-d ", c10::toString(dtype), " CPU tensor");
}

}  // namespace

// images (F*height, W) float32: the frames' grey levels stacked; the observations grouped by
// frame into runs (first index, length and the first row of the run's frame in `images`: (R,)
// int64 each); moves (R, 3, 4) float32: each run's [R | t] from its points' coordinates into its
// camera; point (M,) int64: each observation's point among n_points; sampled (M,) int64: the
// observations in the order they are sampled, each run's own permuted (by where they fall in
// the image, so that the samples of a run walk its image instead of jumping about it: about 1.7x
// faster on 960-wide images); xyz (3, M) float32: the map point of observation sampled[k] in its
// frame's LiDAR coordinates in column k (coordinates in rows: the projection vectorises). The
// sums are added in observation order whatever the sampling order.
// Returns the per-point sums (n_points,) float64 of the standardised grey levels and of their
// squares, and the count (n_points,) int64 of the observations inside their image.
std::vector<torch::Tensor> point_sums(const torch::Tensor& images, const torch::Tensor& xyz,
                                      const torch::Tensor& moves, double fx, double fy, double cx,
                                      double cy, int64_t height, const torch::Tensor& run_starts,
                                      const torch::Tensor& run_lengths,
                                      const torch::Tensor& run_rows, const torch::Tensor& point,
                                      const torch::Tensor& sampled, int64_t n_points,
                                      int64_t threads) {
  check(images, "images", torch::kFloat32, 2);
  check(xyz, "xyz", torch::kFloat32, 2);
  check(moves, "moves", torch::kFloat32, 3);
  check(run_starts, "run_starts", torch::kInt64, 1);
  check(run_lengths, "run_lengths", torch::kInt64, 1);
  check(run_rows, "run_rows", torch::kInt64, 1);
  check(point, "point", torch::kInt64, 1);
  check(sampled, "sampled", torch::kInt64, 1);
  const int64_t m = point.size(0), n_runs = run_starts.size(0), width = images.size(1);
  TORCH_CHECK(xyz.size(0) == 3 && xyz.size(1) == m, "xyz: expected (3, ", m, ")");
  TORCH_CHECK(moves.size(0) == n_runs && moves.size(1) == 3 && moves.size(2) == 4, "moves: expected (",
              n_runs, ", 3, 4)");
  TORCH_CHECK(run_lengths.size(0) == n_runs && run_rows.size(0) == n_runs, "runs: lengths differ");
  TORCH_CHECK(sampled.size(0) == m, "sampled: expected (", m, ",)");

  const float* img = images.data_ptr<float>();
  const float* X = xyz.data_ptr<float>();
  const float* Y = X + m;
  const float* Z = Y + m;
  const float* all_moves = moves.data_ptr<float>();
  const int64_t* start = run_starts.data_ptr<int64_t>();
  const int64_t* length = run_lengths.data_ptr<int64_t>();
  const int64_t* first_row = run_rows.data_ptr<int64_t>();
  const int64_t* pt = point.data_ptr<int64_t>();
  const int64_t* order = sampled.data_ptr<int64_t>();
  for (int64_t r = 0; r < n_runs; ++r) {
    TORCH_CHECK(start[r] >= 0 && length[r] >= 0 && start[r] + length[r] <= m, "run ", r,
                ": observations outside [0, ", m, ")");
    TORCH_CHECK(first_row[r] >= 0 && first_row[r] + height <= images.size(0), "run ", r,
                ": its frame's rows lie outside the images");
  }
  const Pinhole camera(fx, fy, cx, cy, width, height);

  // Each observation's grey level, then its standardised one; NaN where it falls outside its image.
  std::vector<double> value(m);
  double* const g = value.data();
  const auto grey_levels = [&](int64_t first_run, int64_t last_run) {
    for (int64_t r = first_run; r < last_run; ++r) {
      const float* frame = img + first_row[r] * width;
      const float* T = all_moves + 12 * r;
      const float r00 = T[0], r01 = T[1], r02 = T[2], t0 = T[3], r10 = T[4], r11 = T[5], r12 = T[6];
      const float t1 = T[7], r20 = T[8], r21 = T[9], r22 = T[10], t2 = T[11];
      const int64_t begin = start[r], end = start[r] + length[r];
      // In chunks: the projection of a chunk vectorises; its samples are gathered after it.
      for (int64_t c0 = begin; c0 < end; c0 += kChunk) {
        const int64_t nc = std::min(kChunk, end - c0);
        float us[kChunk], vs[kChunk];
        for (int64_t k = 0; k < nc; ++k) {
          const float px = X[c0 + k], py = Y[c0 + k], pz = Z[c0 + k];
          const float x = r00 * px + r01 * py + r02 * pz + t0;
          const float y = r10 * px + r11 * py + r12 * pz + t1;
          const float z = r20 * px + r21 * py + r22 * pz + t2;
          float u, v;
          const bool in = camera.project(x, y, z, u, v);
          us[k] = in ? u : -1.0f;  // outside: a negative column
          vs[k] = v;
        }
        for (int64_t k = 0; k < nc; ++k) {
          const int64_t i = order[c0 + k];
          TORCH_CHECK(i >= begin && i < end, "sampled: ", i, " outside run ", r);
          const float u = us[k], v = vs[k];
          if (u < 0) {
            g[i] = std::numeric_limits<double>::quiet_NaN();
            continue;
          }
          const int64_t x0 = int64_t(u), y0 = int64_t(v);  // u, v >= 0: truncation is floor
          const int64_t x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
          const float wx = u - float(x0), wy = v - float(y0);
          const float* row0 = frame + y0 * width;
          const float* row1 = frame + y1 * width;
          const float top = row0[x0] * (1 - wx) + row0[x1] * wx;
          const float bottom = row1[x0] * (1 - wx) + row1[x1] * wx;
          g[i] = double(top * (1 - wy) + bottom * wy);
        }
      }
      double sum = 0.0, sum_sq = 0.0;
      int64_t n_in = 0;
      for (int64_t i = begin; i < end; ++i) {
        if (std::isnan(g[i])) continue;
        sum += g[i];
        sum_sq += g[i] * g[i];
        ++n_in;
      }
      const double n = double(std::max<int64_t>(n_in, 1));
      const double mean = sum / n;
      const double scale = 1.0 / std::sqrt(std::max(sum_sq / n - mean * mean, 1e-6));
      for (int64_t i = begin; i < end; ++i) g[i] = (g[i] - mean) * scale;  // NaN stays NaN
    }
  };
  // Blocks of whole runs with about as many observations each; an error in a thread is raised here.
  const int64_t n_threads = std::max<int64_t>(1, std::min(threads, n_runs));
  std::vector<int64_t> bounds{0};
  for (int64_t r = 0, done = 0; r < n_runs; ++r) {
    done += length[r];
    if (done * n_threads >= m * int64_t(bounds.size()) && int64_t(bounds.size()) < n_threads)
      bounds.push_back(r + 1);
  }
  while (int64_t(bounds.size()) <= n_threads) bounds.push_back(n_runs);
  run_blocks(n_threads, [&](int64_t b) { grey_levels(bounds[b], bounds[b + 1]); });

  // Zeroed here, not by torch::zeros: that fills in parallel above 32 768 values, and a thread
  // of another process in the way makes those threads wait for each other (10x the whole call).
  auto sums = torch::empty({n_points}, torch::kFloat64);
  auto sums_sq = torch::empty({n_points}, torch::kFloat64);
  auto count = torch::empty({n_points}, torch::kInt64);
  double* s = sums.data_ptr<double>();
  double* s2 = sums_sq.data_ptr<double>();
  int64_t* c = count.data_ptr<int64_t>();
  std::fill_n(s, n_points, 0.0);
  std::fill_n(s2, n_points, 0.0);
  std::fill_n(c, n_points, int64_t(0));
  for (int64_t i = 0; i < m; ++i) {
    if (std::isnan(g[i])) continue;
    const int64_t p = pt[i];
    TORCH_CHECK(p >= 0 && p < n_points, "point: index ", p, " outside [0, ", n_points, ")");
    s[p] += g[i];
    s2[p] += g[i] * g[i];
    ++c[p];
  }
  return {sums, sums_sq, count};
}

// visibility_cpu.cpp
torch::Tensor shown_points(const std::vector<torch::Tensor>& cameras, int64_t n_map, double fx,
                           double fy, double cx, double cy, int64_t width, int64_t height,
                           int64_t window, double relative, double metres, int64_t threads);

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("point_sums", &point_sums, "photo-consistency sums per map point (CPU)");
  m.def("shown_points", &shown_points, "the map points each frame sees (CPU)");
}
