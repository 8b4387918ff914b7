// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>
#include <femesher/stages/IndicatorFunctions.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace femesher {

namespace {

constexpr float kInf = std::numeric_limits<float>::max() / 4;

/// Chunks of the loops over lines and voxels: more than threads, so that a thread slowed by other
/// work (or a chunk of costly lines) does not hold the others up. Nothing is reduced across
/// chunks, so the count does not change any result.
constexpr int kChunks = 64;

/// body(p) for every voxel index p in [0, n), in parallel.
template <class Fn>
void forEachVoxel(size_t n, int threads, Fn&& body) {
  parallelFor(n, threads, [&](size_t b, size_t e, int) {
    for (size_t p = b; p < e; ++p) body(p);
  }, kChunks);
}

/// 1-D squared distance transform (lower envelope of parabolas, Felzenszwalb & Huttenlocher) on
/// samples spaced `s` apart: d[q] = min_p f[p] + (s (q - p))^2.
void distance1d(const float* f, int n, double s, float* d, int* v, double* z) {
  int k = 0;
  v[0] = 0;
  z[0] = -std::numeric_limits<double>::infinity();
  z[1] = std::numeric_limits<double>::infinity();
  const double s2 = s * s;
  for (int q = 1; q < n; ++q) {
    if (f[q] >= kInf) continue;
    if (f[v[0]] >= kInf) {  // first finite sample
      v[0] = q;
      continue;
    }
    double sPos;
    for (;;) {
      const int p = v[k];
      sPos = ((f[q] + s2 * double(q) * q) - (f[p] + s2 * double(p) * p)) / (2.0 * s2 * (q - p));
      if (sPos <= z[k] && k > 0) --k;
      else break;
    }
    if (sPos <= z[k]) {  // k == 0 and the new parabola dominates everywhere
      v[0] = q;
      z[1] = std::numeric_limits<double>::infinity();
      continue;
    }
    ++k;
    v[k] = q;
    z[k] = sPos;
    z[k + 1] = std::numeric_limits<double>::infinity();
  }
  if (f[v[0]] >= kInf) {
    for (int q = 0; q < n; ++q) d[q] = kInf;
    return;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < q) ++k;
    const double dq = s * (q - v[k]);
    d[q] = float(f[v[k]] + dq * dq);
  }
}

/// Separable squared EDT in place on a box (x fastest); g = 0 at features, kInf elsewhere.
void squaredEdt(std::vector<float>& g, const std::array<int, 3>& dims, const Vec3& spacing,
                int threads) {
  const size_t sx = 1, sy = size_t(dims[0]), sz = size_t(dims[0]) * dims[1];
  const size_t strides[3] = {sx, sy, sz};
  for (int axis = 0; axis < 3; ++axis) {
    const int n = dims[axis];
    // Consecutive lines of a chunk are neighbours along x where the line is not along x, so the
    // strided reads of one line hit the cache lines the previous one brought in.
    const int a1 = axis == 0 ? 1 : 0, a2 = axis == 2 ? 1 : 2;
    const size_t lines = size_t(dims[a1]) * dims[a2];
    parallelFor(lines, threads, [&](size_t b, size_t e, int) {
      std::vector<float> f(n), d(n);
      std::vector<int> v(n);
      std::vector<double> z(n + 1);
      for (size_t line = b; line < e; ++line) {
        const size_t u = line % dims[a1], w = line / dims[a1];
        const size_t base = u * strides[a1] + w * strides[a2];
        const size_t st = strides[axis];
        for (int q = 0; q < n; ++q) f[q] = g[base + q * st];
        distance1d(f.data(), n, spacing[axis], d.data(), v.data(), z.data());
        for (int q = 0; q < n; ++q) g[base + q * st] = d[q];
      }
    }, kChunks);
  }
}

/// Normalised Gaussian kernel (sigma in samples), radius ceil(3 sigma) and at least 1.
std::vector<float> gaussianKernel(double sigma) {
  const int r = std::max(1, int(std::ceil(3 * sigma)));
  std::vector<float> kernel(2 * r + 1);
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += kernel[i + r] = float(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (auto& k : kernel) k = float(k / sum);
  return kernel;
}

/// Separable Gaussian blur (sigma in voxels) in place; borders replicate.
void gaussianBlur(std::vector<float>& g, const std::array<int, 3>& dims, double sigma, int threads) {
  if (sigma <= 0) return;
  const std::vector<float> kernel = gaussianKernel(sigma);
  const int r = int(kernel.size() / 2);
  const size_t strides[3] = {1, size_t(dims[0]), size_t(dims[0]) * dims[1]};
  for (int axis = 0; axis < 3; ++axis) {
    const int n = dims[axis];
    // Consecutive lines of a chunk are neighbours along x where the line is not along x, so the
    // strided reads of one line hit the cache lines the previous one brought in.
    const int a1 = axis == 0 ? 1 : 0, a2 = axis == 2 ? 1 : 2;
    const size_t lines = size_t(dims[a1]) * dims[a2];
    parallelFor(lines, threads, [&](size_t b, size_t e, int) {
      std::vector<float> in(n);
      for (size_t line = b; line < e; ++line) {
        const size_t u = line % dims[a1], w = line / dims[a1];
        const size_t base = u * strides[a1] + w * strides[a2];
        const size_t st = strides[axis];
        for (int q = 0; q < n; ++q) in[q] = g[base + q * st];
        for (int q = 0; q < n; ++q) {
          double acc = 0;
          for (int t = -r; t <= r; ++t) acc += kernel[t + r] * in[std::clamp(q + t, 0, n - 1)];
          g[base + q * st] = float(acc);
        }
      }
    }, kChunks);
  }
}

/// Separable Gaussian blur (sigma in voxels) in place of a mostly-zero field: each line scatters
/// its nonzero samples only (the weight falling past the border stays on the border sample, so the
/// sum is kept).
void sparseGaussianBlur(std::vector<float>& g, const std::array<int, 3>& dims, double sigma,
                        int threads) {
  const std::vector<float> kernel = gaussianKernel(sigma);
  const int r = int(kernel.size() / 2);
  const size_t strides[3] = {1, size_t(dims[0]), size_t(dims[0]) * dims[1]};
  for (int axis = 0; axis < 3; ++axis) {
    const int n = dims[axis];
    // Consecutive lines of a chunk are neighbours along x where the line is not along x, so the
    // strided reads of one line hit the cache lines the previous one brought in.
    const int a1 = axis == 0 ? 1 : 0, a2 = axis == 2 ? 1 : 2;
    const size_t lines = size_t(dims[a1]) * dims[a2];
    parallelFor(lines, threads, [&](size_t b, size_t e, int) {
      std::vector<float> in(n);
      for (size_t line = b; line < e; ++line) {
        const size_t u = line % dims[a1], w = line / dims[a1];
        const size_t base = u * strides[a1] + w * strides[a2];
        const size_t st = strides[axis];
        bool any = false;
        for (int q = 0; q < n; ++q) any |= (in[q] = g[base + q * st]) != 0.f;
        if (!any) continue;
        for (int q = 0; q < n; ++q) g[base + q * st] = 0.f;
        for (int q = 0; q < n; ++q) {
          if (in[q] == 0.f) continue;
          for (int t = -r; t <= r; ++t)
            g[base + std::clamp(q + t, 0, n - 1) * st] += kernel[t + r] * in[q];
        }
      }
    }, kChunks);
  }
}

/// Volume-preserving correction of one material's f (mm; `inside` = its voxels). The zero set of
/// the trilinear f cuts every convex voxel corner and edge (a corner to about 0.28 of the voxel
/// diagonal instead of 0.5) and fills concave ones: a label of a few hundred voxels, mostly
/// corners, loses about 10 % of its volume, a large smooth one nothing. Per voxel near the zero
/// set, the share of the voxel inside {f > 0} (3x3x3 sub-samples) is compared with the label; the
/// residual, smoothed over about a voxel, moves f by the distance that gives the missing volume
/// back (the voxel's extent along the gradient times the residual). Flat faces have no residual
/// and stay. Every material's field is corrected, so an interface f_a = f_b moves by the residual
/// once (half from each side). The sign at every voxel centre is kept (|f| >= eps).
void preserveVolume(std::vector<float>& f, const std::vector<uint8_t>& inside,
                    const std::array<int, 3>& dims, const Vec3& spacing, float eps, int iterations,
                    int threads) {
  const size_t n = f.size();
  const double smax = std::max({spacing[0], spacing[1], spacing[2]});
  const float nearZero = float(0.9 * smax);
  const size_t sy = size_t(dims[0]), sz = size_t(dims[0]) * dims[1];
  std::vector<float> r(n);
  for (int it = 0; it < iterations; ++it) {
    parallelFor(size_t(dims[2]), threads, [&](size_t zb, size_t ze, int) {
      for (size_t z = zb; z < ze; ++z)
        for (int y = 0; y < dims[1]; ++y)
          for (int x = 0; x < dims[0]; ++x) {
            const size_t p = size_t(x) + sy * y + sz * z;
            if (std::abs(f[p]) >= nearZero) {
              r[p] = 0;
              continue;
            }
            // The 3x3x3 neighbourhood (border replicated); the sub-samples at -1/3, 0, +1/3 of
            // a voxel along each axis are its trilinear interpolant, one axis at a time.
            float nb[27];
            int pos = 0, neg = 0;
            for (int c = -1; c <= 1; ++c)
              for (int b = -1; b <= 1; ++b)
                for (int a = -1; a <= 1; ++a) {
                  const size_t q = size_t(std::clamp(x + a, 0, dims[0] - 1)) +
                                   sy * size_t(std::clamp(y + b, 0, dims[1] - 1)) +
                                   sz * size_t(std::clamp(int(z) + c, 0, dims[2] - 1));
                  const float v = nb[(c + 1) * 9 + (b + 1) * 3 + (a + 1)] = f[q];
                  pos += v > 0;
                  neg += v <= 0;
                }
            if (pos == 27 || neg == 27) {  // the interpolant has one sign in the whole voxel
              r[p] = float(inside[p]) - (pos == 27 ? 1.f : 0.f);
              continue;
            }
            static constexpr float w[3][3] = {
                {1 / 3.f, 2 / 3.f, 0}, {0, 1, 0}, {0, 2 / 3.f, 1 / 3.f}};
            float sx[27], sxy[27];  // [c][b][o] then [c][o][o]
            for (int cb = 0; cb < 9; ++cb)
              for (int o = 0; o < 3; ++o)
                sx[cb * 3 + o] =
                    w[o][0] * nb[cb * 3] + w[o][1] * nb[cb * 3 + 1] + w[o][2] * nb[cb * 3 + 2];
            for (int c = 0; c < 3; ++c)
              for (int ob = 0; ob < 3; ++ob)
                for (int oa = 0; oa < 3; ++oa)
                  sxy[c * 9 + ob * 3 + oa] = w[ob][0] * sx[c * 9 + oa] +
                                             w[ob][1] * sx[c * 9 + 3 + oa] +
                                             w[ob][2] * sx[c * 9 + 6 + oa];
            int in = 0;
            for (int oc = 0; oc < 3; ++oc)
              for (int k = 0; k < 9; ++k)
                in += w[oc][0] * sxy[k] + w[oc][1] * sxy[9 + k] + w[oc][2] * sxy[18 + k] > 0;
            r[p] = float(inside[p]) - float(in) / 27.f;
          }
    }, kChunks);
    // Smoothing spreads a one-voxel residual over about 2.5 voxels across the surface: scale back.
    constexpr double kSigma = 1.0, kSpread = 2.5066 * kSigma, kDamping = 0.8;
    sparseGaussianBlur(r, dims, kSigma, threads);
    parallelFor(size_t(dims[2]), threads, [&](size_t zb, size_t ze, int) {
      for (size_t z = zb; z < ze; ++z)
        for (int y = 0; y < dims[1]; ++y)
          for (int x = 0; x < dims[0]; ++x) {
            const size_t p = size_t(x) + sy * y + sz * z;
            if (r[p] == 0) continue;
            const int c[3] = {x, y, int(z)};
            const size_t st[3] = {1, sy, sz};
            double g[3], norm = 0;
            for (int a = 0; a < 3; ++a) {
              const size_t lo = c[a] > 0 ? p - st[a] : p, hi = c[a] + 1 < dims[a] ? p + st[a] : p;
              const double h = spacing[a] * double((hi - lo) / st[a]);
              g[a] = h > 0 ? (f[hi] - f[lo]) / h : 0.0;
              norm += g[a] * g[a];
            }
            norm = std::sqrt(norm);
            double extent = 0;
            for (int a = 0; a < 3; ++a)
              extent += norm > 0 ? std::abs(g[a]) / norm * spacing[a] : spacing[a] / 3;
            r[p] = float(kDamping * kSpread * r[p] * extent);  // f is read here: apply below
          }
    }, kChunks);
    parallelFor(n, threads, [&](size_t b, size_t e, int) {
      for (size_t p = b; p < e; ++p) {
        if (r[p] == 0) continue;
        const float v = f[p] + r[p];
        f[p] = inside[p] ? std::max(v, eps) : std::min(v, -eps);
      }
    }, kChunks);
  }
}

}  // namespace

float IndicatorField::valueRaw(int m, int i, int j, int k) const {
  const Box& b = boxes_[m];
  const int x = i - b.lo[0], y = j - b.lo[1], z = k - b.lo[2];
  if (x < 0 || y < 0 || z < 0 || x >= b.dims[0] || y >= b.dims[1] || z >= b.dims[2]) {
    // Outside the grid everything is background (label 0).
    const auto& d = vol_->dims;
    if (m == 0 && (i < 0 || j < 0 || k < 0 || i >= d[0] || j >= d[1] || k >= d[2])) return -far_;
    return far_;
  }
  return b.f.at(x, y, z);
}

void IndicatorField::corners(int m, int i, int j, int k, double out[8]) const {
  const Box& b = boxes_[m];
  const int x = i - b.lo[0], y = j - b.lo[1], z = k - b.lo[2];
  if (b.f.cellInGrid(x, y, z, out)) return;  // the cell lies in the box
  for (int c = 0; c < 8; ++c) out[c] = valueRaw(m, i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
}

IndicatorField::CellPlace IndicatorField::placeOf(const Vec3& l) {
  CellPlace c;
  c.i = int(std::floor(l[0]));
  c.j = int(std::floor(l[1]));
  c.k = int(std::floor(l[2]));
  c.u = l[0] - c.i;
  c.v = l[1] - c.j;
  c.w = l[2] - c.k;
  return c;
}

double IndicatorField::interpolate(const double f[8], const CellPlace& c) {
  const double u = c.u, v = c.v, w = c.w;
  const double x00 = f[0] + u * (f[1] - f[0]), x10 = f[2] + u * (f[3] - f[2]);
  const double x01 = f[4] + u * (f[5] - f[4]), x11 = f[6] + u * (f[7] - f[6]);
  const double y0 = x00 + v * (x10 - x00), y1 = x01 + v * (x11 - x01);
  return y0 + w * (y1 - y0);
}

Vec3 IndicatorField::interpolateGradient(const double fc[8], const CellPlace& p) {
  const double u = p.u, v = p.v, w = p.w;
  Vec3 g{0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    const int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
    const double f = fc[c];
    const double wu = di ? u : 1 - u, wv = dj ? v : 1 - v, ww = dk ? w : 1 - w;
    g[0] += (di ? 1 : -1) * wv * ww * f;
    g[1] += (dj ? 1 : -1) * wu * ww * f;
    g[2] += (dk ? 1 : -1) * wu * wv * f;
  }
  return g;
}

double IndicatorField::evalRaw(int m, const Vec3& l) const {
  const CellPlace c = placeOf(l);
  double f[8];
  corners(m, c.i, c.j, c.k, f);
  return interpolate(f, c);
}

double IndicatorField::boxDistance(const Vec3& l, Vec3* grad) const {
  const Vec3& s = vol_->spacing;
  double out2 = 0, inside = std::numeric_limits<double>::infinity();
  Vec3 excess{0, 0, 0};
  for (int a = 0; a < 3; ++a) {
    const double below = (boxLo_[a] - l[a]) * s[a], above = (l[a] - boxHi_[a]) * s[a];
    if (below > 0) excess[a] = -below;
    if (above > 0) excess[a] = above;
    out2 += excess[a] * excess[a];
    inside = std::min({inside, -below, -above});  // inside: the distance to the nearest face
  }
  if (out2 > 0) {
    const double d = std::sqrt(out2);
    if (grad)
      for (int a = 0; a < 3; ++a) (*grad)[a] = excess[a] * s[a] / d;
    return d;
  }
  if (grad) {
    // The nearest face's normal; near an edge or a corner of the box (within the snapping
    // tolerance of two or three faces) the mean of those faces' normals, not the one face that
    // happens to be a hair nearer: a point sliding along the edge would otherwise see its normal
    // flip from one face's to the other's between two evaluations.
    const double tolerance = 2e-3 * std::min({s[0], s[1], s[2]});
    *grad = {0, 0, 0};
    int faces = 0;
    for (int a = 0; a < 3; ++a) {
      if ((l[a] - boxLo_[a]) * s[a] <= inside + tolerance) {
        (*grad)[a] -= s[a];
        ++faces;
      }
      if ((boxHi_[a] - l[a]) * s[a] <= inside + tolerance) {
        (*grad)[a] += s[a];
        ++faces;
      }
    }
    for (double& x : *grad) x /= faces;  // the nearest face always counts: faces >= 1
  }
  return -inside;
}

Vec3 IndicatorField::snapToBox(const Vec3& l, double tolerance) const {
  if (!(std::fabs(boxDistance(l, nullptr)) <= tolerance)) return l;
  Vec3 q = l;
  for (int a = 0; a < 3; ++a) q[a] = std::clamp(q[a], boxLo_[a], boxHi_[a]);
  const Vec3& s = vol_->spacing;
  for (int a = 0; a < 3; ++a) {  // every face within the tolerance (edges and corners: several)
    if ((q[a] - boxLo_[a]) * s[a] <= tolerance) q[a] = boxLo_[a];
    if ((boxHi_[a] - q[a]) * s[a] <= tolerance) q[a] = boxHi_[a];
  }
  return q;
}

Vec3 IndicatorField::snapToBox(const Vec3& l) const {
  const Vec3& s = vol_->spacing;
  return snapToBox(l, 2e-3 * std::min({s[0], s[1], s[2]}));
}

float IndicatorField::value(int m, int i, int j, int k) const {
  return float(clip(m, valueRaw(m, i, j, k), boxDistance({double(i), double(j), double(k)}, nullptr)));
}

double IndicatorField::eval(int m, const Vec3& l) const {
  return clip(m, evalRaw(m, l), boxDistance(l, nullptr));
}

Vec3 IndicatorField::gradient(int m, const Vec3& l) const {
  Vec3 g;
  evalGradient(m, l, g);
  return g;
}

double IndicatorField::evalGradient(int m, const Vec3& l, Vec3& grad) const {
  const CellPlace c = placeOf(l);
  double corner[8];
  corners(m, c.i, c.j, c.k, corner);
  const double f = interpolate(corner, c), d = boxDistance(l, &grad);
  if (m == 0 ? d > f : -d < f) {  // the box is the active branch
    if (m != 0)
      for (double& x : grad) x = -x;
  } else {
    grad = interpolateGradient(corner, c);
  }
  return clip(m, f, d);
}

int IndicatorField::cornerLabels(const Vec3& l, int out[8]) const {
  const int i = int(std::floor(l[0])), j = int(std::floor(l[1])), k = int(std::floor(l[2]));
  const auto& d = vol_->dims;
  int n = 0;
  for (int c = 0; c < 8; ++c) {
    const int x = i + (c & 1), y = j + ((c >> 1) & 1), z = k + ((c >> 2) & 1);
    int lab = 0;
    if (x >= 0 && y >= 0 && z >= 0 && x < d[0] && y < d[1] && z < d[2]) lab = vol_->at(x, y, z);
    bool seen = false;
    for (int a = 0; a < n; ++a) seen |= out[a] == lab;
    if (!seen) out[n++] = lab;
  }
  std::sort(out, out + n);
  return n;
}

int IndicatorField::argmax(const Vec3& l) const {
  int cand[8];
  const int n = cornerLabels(l, cand);
  if (n == 1) return cand[0];
  int best = cand[0];
  double bestValue = -std::numeric_limits<double>::infinity();
  for (int a = 0; a < n; ++a) {
    const double f = eval(cand[a], l);
    if (f > bestValue) {
      bestValue = f;
      best = cand[a];
    }
  }
  return best;
}

IndicatorField computeIndicatorFunctions(const PreprocessedVolume& vol,
                                         const IndicatorParameters& params, RunContext& ctx) {
  IndicatorField field;
  field.vol_ = &vol;
  // The input's box (local index units); unknown for hand-built volumes: no clip, no extension.
  const bool knownBox = vol.inputDims[0] > 0 && vol.inputDims[1] > 0 && vol.inputDims[2] > 0;
  std::array<int, 3> inLo{{0, 0, 0}}, inHi{{vol.dims[0] - 1, vol.dims[1] - 1, vol.dims[2] - 1}};
  for (int a = 0; a < 3; ++a) {
    const double inf = std::numeric_limits<double>::infinity();
    field.boxLo_[a] = knownBox ? -vol.offset[a] - 0.5 : -inf;
    field.boxHi_[a] = knownBox ? vol.inputDims[a] - vol.offset[a] - 0.5 : inf;
    if (knownBox) {
      inLo[a] = std::clamp(-vol.offset[a], 0, vol.dims[a] - 1);
      inHi[a] = std::clamp(vol.inputDims[a] - 1 - vol.offset[a], 0, vol.dims[a] - 1);
    }
  }
  // Labels extended past the box: a padding voxel takes the label of the nearest voxel inside.
  auto extended = [&](int i, int j, int k) {
    return vol.at(std::clamp(i, inLo[0], inHi[0]), std::clamp(j, inLo[1], inHi[1]),
                  std::clamp(k, inLo[2], inHi[2]));
  };
  const int nLabels = int(vol.userLabel.size());
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const double smax = std::max({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const float bandMm = float(params.band * smax);
  field.far_ = -bandMm;
  const float offset = float(0.5 * smin);
  // Every voxel centre keeps |f| >= eps with the right sign: the smoothed surface never comes
  // closer than about a third of a voxel to a centre, so one-voxel features keep a volume and
  // the piecewise-linear surface has room to stay on the right side of every centre.
  const float eps = float(0.35 * smin);
  const int threads = ctx.threads();

  // Bounding boxes of every label: per chunk of z-planes, then the extremes of the chunks'.
  std::vector<std::array<int, 3>> lo(nLabels, {{vol.dims[0], vol.dims[1], vol.dims[2]}});
  std::vector<std::array<int, 3>> hi(nLabels, {{-1, -1, -1}});
  {
    std::vector<std::vector<std::array<int, 3>>> clo(kChunks, lo), chi(kChunks, hi);
    parallelFor(size_t(vol.dims[2]), threads, [&](size_t kb, size_t ke, int c) {
      auto& cl = clo[size_t(c)];
      auto& ch = chi[size_t(c)];
      for (int k = int(kb); k < int(ke); ++k)
        for (int j = 0; j < vol.dims[1]; ++j)
          for (int i = 0; i < vol.dims[0]; ++i) {
            const int l = extended(i, j, k);
            auto& a = cl[l];
            auto& b = ch[l];
            a[0] = std::min(a[0], i); b[0] = std::max(b[0], i);
            a[1] = std::min(a[1], j); b[1] = std::max(b[1], j);
            a[2] = std::min(a[2], k); b[2] = std::max(b[2], k);
          }
    }, kChunks);
    for (size_t c = 0; c < clo.size(); ++c)
      for (int l = 0; l < nLabels; ++l)
        for (int a = 0; a < 3; ++a) {
          lo[l][a] = std::min(lo[l][a], clo[c][l][a]);
          hi[l][a] = std::max(hi[l][a], chi[c][l][a]);
        }
  }

  const int pad = params.band + int(std::ceil(3 * params.sigma)) + 2;
  double totalVoxels = 0;
  std::vector<IndicatorField::Box> boxes(nLabels);
  for (int m = 0; m < nLabels; ++m) {
    auto& b = boxes[m];
    if (hi[m][0] < 0) continue;  // label absent from the grid
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = std::max(0, lo[m][a] - pad);
      b.dims[a] = std::min(vol.dims[a] - 1, hi[m][a] + pad) - b.lo[a] + 1;
    }
    totalVoxels += double(b.dims[0]) * b.dims[1] * b.dims[2];
  }
  double doneVoxels = 0;
  for (int m = 0; m < nLabels; ++m) {
    auto& b = boxes[m];
    const size_t n = size_t(b.dims[0]) * b.dims[1] * b.dims[2];
    if (n == 0) continue;
    ctx.checkCancel();
    std::vector<uint8_t> inside(n);
    std::vector<float> dOut(n), dIn(n);
    parallelFor(size_t(b.dims[2]), threads, [&](size_t zb, size_t ze, int) {
      for (int z = int(zb); z < int(ze); ++z)
        for (int y = 0; y < b.dims[1]; ++y)
          for (int x = 0; x < b.dims[0]; ++x) {
            const size_t p = size_t(x) + size_t(b.dims[0]) * (size_t(y) + size_t(b.dims[1]) * z);
            const bool in = extended(x + b.lo[0], y + b.lo[1], z + b.lo[2]) == m;
            inside[p] = in;
            dOut[p] = in ? 0.f : kInf;
            dIn[p] = in ? kInf : 0.f;
          }
    }, kChunks);
    squaredEdt(dOut, b.dims, vol.spacing, threads);
    ctx.checkCancel();
    squaredEdt(dIn, b.dims, vol.spacing, threads);
    ctx.checkCancel();
    std::vector<float> f(n);
    forEachVoxel(n, threads, [&](size_t p) {
      const float v = inside[p] ? std::sqrt(dIn[p]) - offset : offset - std::sqrt(dOut[p]);
      f[p] = std::clamp(v, -bandMm, bandMm);
    });
    std::vector<float>().swap(dIn);
    std::vector<float>().swap(dOut);
    // Small labels are smoothed less (sigma <= a quarter of their smallest extent), so a label of
    // a few voxels keeps its volume instead of shrinking to blobs around its voxel centres.
    const int extent = std::min({hi[m][0] - lo[m][0], hi[m][1] - lo[m][1], hi[m][2] - lo[m][2]}) + 1;
    gaussianBlur(f, b.dims, std::min(params.sigma, 0.25 * extent), threads);
    forEachVoxel(n, threads,
                 [&](size_t p) { f[p] = inside[p] ? std::max(f[p], eps) : std::min(f[p], -eps); });
    if (params.volumeIterations > 0)
      preserveVolume(f, inside, b.dims, vol.spacing, eps, params.volumeIterations, threads);
    std::vector<uint8_t>().swap(inside);
    b.f = BrickGrid(f, b.dims, threads);
    doneVoxels += double(n);
    ctx.progress(doneVoxels / std::max(1.0, totalVoxels));
  }
  field.boxes_ = std::move(boxes);
  ctx.debug("IndicatorFunctions: " + std::to_string(field.storedBytes() >> 20) + " MB in bricks, " +
            std::to_string(field.denseBytes() >> 20) + " MB as dense boxes");
  return field;
}

bool moveOntoInterface(const IndicatorField& f, int a, int b, Vec3& x) {
  const PreprocessedVolume& vol = f.volume();
  const double h = vol.minSpacing(), tol = 1e-4 * h;
  const Vec3 start = vol.localToCanonical(x);
  for (int it = 0; it < 25; ++it) {
    Vec3 ga, gb;
    const double fa = f.evalGradient(a, x, ga), fb = f.evalGradient(b, x, gb);
    const double gap = fa - fb;
    Vec3 d;
    for (int k = 0; k < 3; ++k) d[k] = (ga[k] - gb[k]) / vol.spacing[k];
    if (std::fabs(gap) < tol) {
      if (norm(sub(vol.localToCanonical(x), start)) > 2 * h) return false;
      int around[8];
      const int n = f.cornerLabels(x, around);
      const double own = std::min(fa, fb);
      for (int c = 0; c < n; ++c)
        if (around[c] != a && around[c] != b && f.eval(around[c], x) > own + 10 * tol) return false;
      return true;
    }
    const double dd = dot(d, d);
    if (!(dd > 1e-20)) return false;
    double s = -gap / dd;
    const double len = std::fabs(s) * std::sqrt(dd);
    if (len > 0.5 * h) s *= 0.5 * h / len;
    for (int k = 0; k < 3; ++k) x[k] += s * d[k] / vol.spacing[k];
  }
  return false;
}

}  // namespace femesher
