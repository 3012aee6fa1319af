// Per-triangle set-up (projection, culling, window coefficients) and its backward, shared by the
// compiled backends. splat/raster/project.py is the PyTorch specification of the same maths.
#pragma once

#include "triangle_math.h"

namespace lts {

constexpr double kEdgeOnCos = 1e-3;     // |cos(normal, view ray)| below this: edge-on
constexpr double kMinInradiusPx = 1e-2;  // projected inradius below this: too thin
constexpr double kBoxPadPx = 0.5;        // keeps pixel boxes conservative against rounding

template <typename T>
struct View {
  T R[9], t[3];  // world-to-camera rotation (row-major) and translation
  T fx, fy, cx, cy, near;
  int width, height;
};

// Triangle opacity (TS+: the min of its vertices, first on ties); returns which vertex.
template <typename T>
LTS_HD int min_opacity(const T* opacities, const int64_t* face, T* value) {
  int arg = 0;
  for (int i = 1; i < 3; ++i) {
    if (opacities[face[i]] < opacities[face[arg]]) arg = i;
  }
  *value = opacities[face[arg]];
  return arg;
}

// Camera-frame vertices and their projections.
template <typename T>
struct Projected {
  T P[3][3];  // camera-frame vertices
  T iz[3];    // inverse depths
  T q[3][2];  // pixel positions
};

template <typename T>
LTS_HD void project(const View<T>& v, const T* const world[3], Projected<T>& pr) {
  for (int i = 0; i < 3; ++i) {
    for (int r = 0; r < 3; ++r) {
      pr.P[i][r] = v.R[3 * r] * world[i][0] + v.R[3 * r + 1] * world[i][1] +
                   v.R[3 * r + 2] * world[i][2] + v.t[r];
    }
    pr.iz[i] = T(1) / pr.P[i][2];
    pr.q[i][0] = v.fx * pr.P[i][0] * pr.iz[i] + v.cx;
    pr.q[i][1] = v.fy * pr.P[i][1] * pr.iz[i] + v.cy;
  }
}

// Side vectors d_j = q_{j+1} - q_j, their lengths, the perimeter and twice the signed area.
template <typename T>
struct Sides {
  T d[3][2], len[3], perimeter, twice_area;
};

template <typename T>
LTS_HD void sides(const Projected<T>& pr, Sides<T>& s) {
  s.perimeter = T(0);
  for (int j = 0; j < 3; ++j) {
    const int n = (j + 1) % 3;
    s.d[j][0] = pr.q[n][0] - pr.q[j][0];
    s.d[j][1] = pr.q[n][1] - pr.q[j][1];
    s.len[j] = sqrt(s.d[j][0] * s.d[j][0] + s.d[j][1] * s.d[j][1]);
    s.perimeter += s.len[j];
  }
  s.twice_area = s.d[0][0] * (-s.d[2][1]) - s.d[0][1] * (-s.d[2][0]);
}

// Euclidean length of a 3-vector, scaled by its largest |component| first: the squares of a
// float32 cross product of ~1e-10 m edges (or a tiny scene seen with extreme focal lengths)
// underflow to 0, which made the unit normal inf/NaN. 0 for the zero vector.
template <typename T>
LTS_HD T safe_length(const T x[3]) {
  const T m = fmax(fabs(x[0]), fmax(fabs(x[1]), fabs(x[2])));
  if (!(m > T(0))) return m;
  const T a = x[0] / m, b = x[1] / m, c = x[2] / m;
  return m * sqrt(a * a + b * b + c * c);
}

template <typename T>
LTS_HD void face_normal(const Projected<T>& pr, T N[3]) {
  T e1[3], e2[3];
  for (int r = 0; r < 3; ++r) {
    e1[r] = pr.P[1][r] - pr.P[0][r];
    e2[r] = pr.P[2][r] - pr.P[0][r];
  }
  N[0] = e1[1] * e2[2] - e1[2] * e2[1];
  N[1] = e1[2] * e2[0] - e1[0] * e2[2];
  N[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

// Whether a triangle can be drawn; its depth-sort key (centroid depth) in *key.
template <typename T>
LTS_HD bool visible(const View<T>& v, const T* const world[3], T opacity, T sigma, T* key) {
  Projected<T> pr;
  project(v, world, pr);
  *key = (pr.P[0][2] + pr.P[1][2] + pr.P[2][2]) / T(3);
  for (int i = 0; i < 3; ++i) {
    if (!(pr.P[i][2] > v.near)) return false;
  }
  // Projections that overflow (float32 with a vertex grazing the near plane, extreme focal
  // lengths) turn into inf - inf = NaN further on: such a triangle cannot be drawn meaningfully.
  for (int i = 0; i < 3; ++i) {
    if (!isfinite(pr.q[i][0]) || !isfinite(pr.q[i][1])) return false;
  }
  // The cheap tests first: most faces of a scene lie outside any one view.
  T lo[2] = {pr.q[0][0], pr.q[0][1]}, hi[2] = {pr.q[0][0], pr.q[0][1]};
  for (int i = 1; i < 3; ++i) {
    for (int a = 0; a < 2; ++a) {
      lo[a] = fmin(lo[a], pr.q[i][a]);
      hi[a] = fmax(hi[a], pr.q[i][a]);
    }
  }
  const T pad = T(kBoxPadPx);
  if (!(hi[0] >= -pad && lo[0] <= T(v.width - 1) + pad && hi[1] >= -pad &&
        lo[1] <= T(v.height - 1) + pad && opacity >= Thresholds<T>::alpha_min && sigma > T(0))) {
    return false;
  }
  Sides<T> s;
  sides(pr, s);
  if (!isfinite(s.twice_area)) return false;
  if (!(fabs(s.twice_area) / s.perimeter >= T(kMinInradiusPx))) return false;
  T N[3], g[3];
  face_normal(pr, N);
  for (int r = 0; r < 3; ++r) g[r] = (pr.P[0][r] + pr.P[1][r] + pr.P[2][r]) / T(3);
  const T n_len = safe_length(N);
  const T g_len = safe_length(g);
  return fabs(N[0] * g[0] + N[1] * g[1] + N[2] * g[2]) >= T(kEdgeOnCos) * n_len * g_len;
}

// Kernel parameters (kParams, layout in triangle_math.h) and the inclusive pixel box of the
// region where alpha can reach 1/255, for a visible triangle.
template <typename T>
LTS_HD void setup(const View<T>& v, const T* const world[3], const T* const colour[3], T opacity,
                  T sigma, T* p, int box[4]) {
  Projected<T> pr;
  project(v, world, pr);
  Sides<T> s;
  sides(pr, s);
  for (int j = 0; j < 3; ++j) {
    const int o = (j + 2) % 3;  // vertex opposite side j
    const T k = s.perimeter / (s.len[j] * s.twice_area);
    p[kLine + 3 * j] = -k * s.d[j][1];
    p[kLine + 3 * j + 1] = k * s.d[j][0];
    p[kLine + 3 * j + 2] = k * (s.d[j][1] * pr.q[j][0] - s.d[j][0] * pr.q[j][1]);
    const T share = s.len[j] / s.perimeter;
    for (int c = 0; c < 3; ++c) p[kColor + 3 * j + c] = share * colour[o][c];
    p[kInvDepth + j] = share * pr.iz[o];
  }
  p[kOpacity] = opacity;
  p[kSigma] = sigma;
  T N[3];
  face_normal(pr, N);
  const T inv_len = T(1) / safe_length(N);
  T facing = T(0);
  for (int r = 0; r < 3; ++r) facing += N[r] * inv_len * (pr.P[0][r] + pr.P[1][r] + pr.P[2][r]);
  const T flip = facing > T(0) ? T(-1) : T(1);
  for (int r = 0; r < 3; ++r) p[kNormal + r] = flip * N[r] * inv_len;
  // Support: min_j l_j >= t with t = (1 / (255 o))^(1/sigma), the triangle shrunk about its
  // incentre by 1 - t.
  T t = exponential(logarithm(Thresholds<T>::alpha_min / opacity) / sigma);
  t = t < T(0) ? T(0) : (t > T(1) ? T(1) : t);
  p[kParams - 1] = t;
  T inc[2] = {T(0), T(0)};
  for (int i = 0; i < 3; ++i) {
    const T w = s.len[(i + 1) % 3] / s.perimeter;
    inc[0] += w * pr.q[i][0];
    inc[1] += w * pr.q[i][1];
  }
  T lo[2] = {T(1e30), T(1e30)}, hi[2] = {T(-1e30), T(-1e30)};
  for (int i = 0; i < 3; ++i) {
    for (int a = 0; a < 2; ++a) {
      const T x = inc[a] + (T(1) - t) * (pr.q[i][a] - inc[a]);
      lo[a] = fmin(lo[a], x);
      hi[a] = fmax(hi[a], x);
    }
  }
  const T limit[2] = {T(v.width - 1), T(v.height - 1)};
  // Clamp on both sides *before* the int cast: the support of a visible triangle can lie
  // billions of pixels off the image, and casting such a float to int is undefined (x86 gives
  // INT_MIN: a box spanning 2^31 pixels that the binning walks out of bounds). lo > limit or
  // hi < 0 is an empty box.
  for (int a = 0; a < 2; ++a) {
    box[a] = static_cast<int>(fmin(fmax(ceil(lo[a] - T(kBoxPadPx)), T(0)), limit[a] + T(1)));
    box[2 + a] = static_cast<int>(fmax(fmin(floor(hi[a] + T(kBoxPadPx)), limit[a]), T(-1)));
  }
}

// Backward of setup(): from d(loss)/d(params) to the triangle's camera-frame vertices
// (gP[3][3]) and its colours (gcol[3][3]); opacity and sigma gradients pass straight through.
template <typename T>
LTS_HD void setup_backward(const View<T>& v, const T* const world[3], const T* const colour[3],
                           const T* g, T gP[3][3], T gcol[3][3]) {
  Projected<T> pr;
  project(v, world, pr);
  Sides<T> s;
  sides(pr, s);
  T gq[3][2] = {}, gd[3][2] = {}, giz[3] = {}, gL[3], gk[3], gshare[3], k[3];
  T g_per = T(0), g_area = T(0);
  for (int j = 0; j < 3; ++j) {
    const int o = (j + 2) % 3;
    k[j] = s.perimeter / (s.len[j] * s.twice_area);
    const T share = s.len[j] / s.perimeter;
    const T ga = g[kLine + 3 * j], gb = g[kLine + 3 * j + 1], gc = g[kLine + 3 * j + 2];
    const T dx = s.d[j][0], dy = s.d[j][1], qx = pr.q[j][0], qy = pr.q[j][1];
    gk[j] = -ga * dy + gb * dx + gc * (dy * qx - dx * qy);
    gd[j][0] += k[j] * gb - k[j] * gc * qy;
    gd[j][1] += -k[j] * ga + k[j] * gc * qx;
    gq[j][0] += k[j] * gc * dy;
    gq[j][1] -= k[j] * gc * dx;
    gshare[j] = g[kInvDepth + j] * pr.iz[o];
    giz[o] += share * g[kInvDepth + j];
    for (int c = 0; c < 3; ++c) {
      gshare[j] += g[kColor + 3 * j + c] * colour[o][c];
      gcol[o][c] = share * g[kColor + 3 * j + c];
    }
    g_per += gk[j] / (s.len[j] * s.twice_area) - gshare[j] * s.len[j] / (s.perimeter * s.perimeter);
    g_area -= gk[j] * k[j] / s.twice_area;
  }
  for (int j = 0; j < 3; ++j) {
    gL[j] = gshare[j] / s.perimeter - gk[j] * k[j] / s.len[j] + g_per;
    gd[j][0] += gL[j] * s.d[j][0] / s.len[j];
    gd[j][1] += gL[j] * s.d[j][1] / s.len[j];
  }
  // twice_area = -d0x d2y + d0y d2x
  gd[0][0] -= g_area * s.d[2][1];
  gd[2][1] -= g_area * s.d[0][0];
  gd[0][1] += g_area * s.d[2][0];
  gd[2][0] += g_area * s.d[0][1];
  for (int j = 0; j < 3; ++j) {
    const int n = (j + 1) % 3;
    for (int a = 0; a < 2; ++a) {
      gq[n][a] += gd[j][a];
      gq[j][a] -= gd[j][a];
    }
  }
  for (int i = 0; i < 3; ++i) {
    gP[i][0] = v.fx * pr.iz[i] * gq[i][0];
    gP[i][1] = v.fy * pr.iz[i] * gq[i][1];
    giz[i] += v.fx * pr.P[i][0] * gq[i][0] + v.fy * pr.P[i][1] * gq[i][1];
    gP[i][2] = -pr.iz[i] * pr.iz[i] * giz[i];
  }
  // Normal n = flip * N / |N| with N = (P1 - P0) x (P2 - P0).
  T N[3], e1[3], e2[3];
  face_normal(pr, N);
  for (int r = 0; r < 3; ++r) {
    e1[r] = pr.P[1][r] - pr.P[0][r];
    e2[r] = pr.P[2][r] - pr.P[0][r];
  }
  const T len = safe_length(N);
  T facing = T(0);
  for (int r = 0; r < 3; ++r) facing += N[r] / len * (pr.P[0][r] + pr.P[1][r] + pr.P[2][r]);
  const T flip = facing > T(0) ? T(-1) : T(1);
  T gn[3], dot = T(0);
  for (int r = 0; r < 3; ++r) {
    gn[r] = flip * g[kNormal + r];
    dot += N[r] / len * gn[r];
  }
  T gN[3];
  for (int r = 0; r < 3; ++r) gN[r] = (gn[r] - N[r] / len * dot) / len;
  const T gE1[3] = {e2[1] * gN[2] - e2[2] * gN[1], e2[2] * gN[0] - e2[0] * gN[2],
                    e2[0] * gN[1] - e2[1] * gN[0]};
  const T gE2[3] = {gN[1] * e1[2] - gN[2] * e1[1], gN[2] * e1[0] - gN[0] * e1[2],
                    gN[0] * e1[1] - gN[1] * e1[0]};
  for (int r = 0; r < 3; ++r) {
    gP[1][r] += gE1[r];
    gP[2][r] += gE2[r];
    gP[0][r] -= gE1[r] + gE2[r];
  }
}

}  // namespace lts
