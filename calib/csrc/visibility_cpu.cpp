// Which map points each frame sees (calib/photo_consistency.py's _shown_points, whose NumPy form
// is the specification the tests hold this to): a z-buffer of the points' depths, its minimum
// over a window (the map is sparse: a surface in front hides what lies behind it between its
// points), and the points no more than a tolerance behind it. Written by hand because no library
// keeps the nearest of scattered points per pixel (NumPy's minimum.at is an unbuffered scatter),
// and `lts calibrate` asks this of every frame about a hundred times. The arithmetic is NumPy's
// float32 arithmetic, without fused multiply-adds (the build's -ffp-contract=off), so that the
// same points come out (pinhole.h). Frames on `threads` threads, each a block of whole frames.
#include <torch/types.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "parallel_blocks.h"
#include "pinhole.h"

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

struct View {
  Pinhole camera;
  float relative, metres;
  int64_t width, height, window;
};

// One thread's images, kept from frame to frame.
struct Buffers {
  std::vector<int64_t> pixel;
  std::vector<float> nearest, ring, eroded;
};

// Marks in `shown` (n_map,) the first n_map of the n points X, Y, Z (camera coordinates) that the
// frame sees; the others (occluders) only hide.
void shown_in_frame(const float* X, const float* Y, const float* Z, int64_t n, int64_t n_map,
                    const View& view, Buffers& buffers, bool* shown) {
  const int64_t width = view.width, height = view.height, window = view.window;
  buffers.pixel.resize(n);
  buffers.nearest.assign(width * height, kInf);
  buffers.ring.resize(window * width);
  buffers.eroded.resize(width * height);
  int64_t* pixel = buffers.pixel.data();
  float* nearest = buffers.nearest.data();
  for (int64_t i = 0; i < n; ++i) {
    const float z = Z[i];
    float u, v;
    if (!view.camera.project(X[i], Y[i], z, u, v)) {
      pixel[i] = -1;
      continue;
    }
    // nearbyint: round half to even, as np.rint
    const int64_t p = int64_t(std::nearbyint(v)) * width + int64_t(std::nearbyint(u));
    pixel[i] = p;
    nearest[p] = std::min(nearest[p], z);
  }

  // The window's minimum: each row's minimum along the row (each offset one contiguous loop, so
  // that it vectorises), kept for the `window` rows a column's minimum needs (they stay in
  // cache), then the minimum of those rows. Exact, so the order is free.
  const int64_t before = window / 2, after = window - 1 - before;
  const auto row_minimum = [&](int64_t y) {
    const float* __restrict in = nearest + y * width;
    float* __restrict out = buffers.ring.data() + (y % window) * width;
    std::copy_n(in, width, out);
    for (int64_t d = 1; d <= std::max(before, after); ++d) {
      if (d <= after)  // out[x] takes in[x + d]
        for (int64_t x = 0; x < width - d; ++x) out[x] = std::min(out[x], in[x + d]);
      if (d <= before)  // out[x] takes in[x - d]
        for (int64_t x = d; x < width; ++x) out[x] = std::min(out[x], in[x - d]);
    }
  };
  for (int64_t y = 0; y < std::min(after, height); ++y) row_minimum(y);
  for (int64_t y = 0; y < height; ++y) {
    if (y + after < height) row_minimum(y + after);
    float* __restrict out = buffers.eroded.data() + y * width;
    const int64_t first = std::max<int64_t>(0, y - before), last = std::min(height - 1, y + after);
    std::copy_n(buffers.ring.data() + (first % window) * width, width, out);
    for (int64_t k = first + 1; k <= last; ++k) {
      const float* __restrict in = buffers.ring.data() + (k % window) * width;
      for (int64_t x = 0; x < width; ++x) out[x] = std::min(out[x], in[x]);
    }
  }

  const float* eroded = buffers.eroded.data();
  for (int64_t i = 0; i < n_map; ++i)
    shown[i] = pixel[i] >= 0 && Z[i] <= eroded[pixel[i]] * view.relative + view.metres;
}

}  // namespace

// cameras: per frame (3, N_f) float32, its points in the camera's coordinates by axis, the map's
// n_map points first (then the frame's occluders, which hide and are not marked). Returns
// (F, n_map) bool: the map points in each frame's image (depth over 5 cm, pinhole pixel within
// [0, width - 1] x [0, height - 1]) whose depth is at most `relative` times the smallest depth
// rounded to a pixel within the `window` x `window` pixels around theirs (anchored at the
// centre, as OpenCV's erode), plus `metres`.
torch::Tensor shown_points(const std::vector<torch::Tensor>& cameras, int64_t n_map, double fx,
                           double fy, double cx, double cy, int64_t width, int64_t height,
                           int64_t window, double relative, double metres, int64_t threads) {
  TORCH_CHECK(width > 0 && height > 0 && window > 0, "width, height and window must be positive");
  const int64_t n_frames = int64_t(cameras.size());
  for (int64_t f = 0; f < n_frames; ++f) {
    const auto& c = cameras[f];
    TORCH_CHECK(c.device().is_cpu() && c.scalar_type() == torch::kFloat32 && c.is_contiguous() &&
                    c.dim() == 2 && c.size(0) == 3 && c.size(1) >= n_map,
                "cameras[", f, "]: expected a contiguous (3, N >= ", n_map, ") float32 CPU tensor");
  }
  const View view{Pinhole(fx, fy, cx, cy, width, height), float(relative), float(metres), width,
                  height, window};
  auto seen = torch::empty({n_frames, n_map}, torch::kBool);
  bool* out = seen.data_ptr<bool>();

  const int64_t n_threads = std::max<int64_t>(1, std::min(threads, n_frames));
  run_blocks(n_threads, [&](int64_t b) {
    Buffers buffers;
    for (int64_t f = n_frames * b / n_threads; f < n_frames * (b + 1) / n_threads; ++f) {
      const int64_t n = cameras[f].size(1);
      const float* X = cameras[f].data_ptr<float>();
      shown_in_frame(X, X + n, X + 2 * n, n, n_map, view, buffers, out + f * n_map);
    }
  });
  return seen;
}
