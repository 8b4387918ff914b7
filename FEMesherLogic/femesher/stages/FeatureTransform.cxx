// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/stages/FeatureTransform.h>

#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>

#include <cmath>
#include <string>

namespace femesher {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Scratch for one line of the lower-envelope passes.
struct LineScratch {
  std::vector<double> g;        // g(i): squared distance of site i's candidate so far (mm²)
  std::vector<uint32_t> site;   // candidate feature of position i
  std::vector<int> v;           // envelope: positions of the parabolas
  std::vector<long double> z;   // envelope: start of each parabola's interval
  std::vector<uint32_t> out;
  void resize(int n) {
    g.resize(n);
    site.resize(n);
    v.resize(n);
    z.resize(n + 1);
    out.resize(n);
  }
};

/// Lower envelope of f_i(u) = g[i] + w·(u − i)² over the finite g[i]; writes, for every u, the
/// candidate feature of the minimising i into s.out (kNoFeature when every g is infinite).
void envelope(LineScratch& s, int n, double w) {
  auto value = [&](int i, int u) {
    const double d = double(u - i);
    return s.g[i] + w * d * d;
  };
  auto sep = [&](int a, int b) -> long double {  // where f_b starts to beat f_a (a < b)
    return (static_cast<long double>(a) + b) / 2 +
           (static_cast<long double>(s.g[b]) - s.g[a]) / (2.0L * w * (b - a));
  };
  int k = -1;
  for (int q = 0; q < n; ++q) {
    if (!(s.g[q] < kInf)) continue;
    long double at = -std::numeric_limits<long double>::infinity();
    while (k >= 0) {
      at = sep(s.v[k], q);
      if (at <= s.z[k]) {
        --k;
        at = -std::numeric_limits<long double>::infinity();
      } else {
        break;
      }
    }
    ++k;
    s.v[k] = q;
    s.z[k] = at;
  }
  if (k < 0) {
    for (int u = 0; u < n; ++u) s.out[u] = kNoFeature;
    return;
  }
  int j = 0;
  for (int u = 0; u < n; ++u) {
    while (j < k && s.z[j + 1] <= u) ++j;
    // Guard against rounding of the separators: the exact minimiser of the reference expression
    // is one of the two envelope neighbours when the separator lies within rounding of u.
    int best = s.v[j];
    double bestValue = value(best, u);
    if (j > 0 && value(s.v[j - 1], u) < bestValue) {
      best = s.v[j - 1];
      bestValue = value(best, u);
    }
    if (j < k && value(s.v[j + 1], u) < bestValue) best = s.v[j + 1];
    s.out[u] = s.site[best];
  }
}

}  // namespace

std::vector<uint32_t> featureTransform(const Grid3& grid, const std::vector<uint8_t>& isFeature,
                                       int threads, RunContext* ctx) {
  const size_t n = grid.size();
  if (isFeature.size() != n)
    throw Error(ErrorCode::InvalidArgument,
                "featureTransform: the feature mask has " + std::to_string(isFeature.size()) +
                    " values but the grid has " + std::to_string(n) + " voxels.");
  if (n >= size_t(kNoFeature))
    throw Error(ErrorCode::InvalidArgument,
                "featureTransform: the grid has " + std::to_string(n) +
                    " voxels; at most 4,294,967,294 are supported. Crop or downsample the volume.");
  std::vector<uint32_t> ft(n, kNoFeature);
  if (n == 0) return ft;
  const int nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  const int t = resolveThreads(threads);
  const int chunks = t == 1 ? 1 : t * 8;
  auto check = [&] {
    if (ctx) ctx->checkCancel();
  };

  // Pass 1: x-lines, nearest feature in the row.
  parallelFor(size_t(ny) * nz, t, [&](size_t b, size_t e, int) {
    check();
    for (size_t line = b; line < e; ++line) {
      const size_t base = line * size_t(nx);
      int last = -1;  // last feature to the left
      for (int i = 0; i < nx; ++i) {
        if (isFeature[base + i]) last = i;
        ft[base + i] = last < 0 ? kNoFeature : uint32_t(base + last);
      }
      int next = -1;  // next feature to the right
      for (int i = nx - 1; i >= 0; --i) {
        if (isFeature[base + i]) next = i;
        if (next < 0) continue;
        const uint32_t left = ft[base + i];
        if (left == kNoFeature || (next - i) < (i - int(left - base)))
          ft[base + i] = uint32_t(base + next);
      }
    }
  }, chunks);
  check();

  // Passes 2 and 3: lines along y (axis 1) and z (axis 2).
  for (int axis = 1; axis <= 2; ++axis) {
    const int len = grid.dims[axis];
    if (len == 1) continue;  // nothing to combine along a 1-voxel axis
    const size_t stride = axis == 1 ? size_t(nx) : size_t(nx) * ny;
    const size_t lines = axis == 1 ? size_t(nx) * nz : size_t(nx) * ny;
    const double w = grid.spacing[axis] * grid.spacing[axis];
    parallelFor(lines, t, [&](size_t b, size_t e, int) {
      check();
      LineScratch s;
      s.resize(len);
      for (size_t line = b; line < e; ++line) {
        // line -> base index of its first voxel
        const size_t i0 = line % size_t(nx), rest = line / size_t(nx);
        const size_t base = axis == 1 ? i0 + size_t(nx) * size_t(ny) * rest : i0 + size_t(nx) * rest;
        const auto c0 = grid.coords(base);
        for (int u = 0; u < len; ++u) {
          const size_t idx = base + size_t(u) * stride;
          const uint32_t f = ft[idx];
          s.site[u] = f;
          if (f == kNoFeature) {
            s.g[u] = kInf;
          } else {
            // distance within the hyperplane orthogonal to the line (the axis term is 0)
            const auto cf = grid.coords(f);
            const int dx = cf[0] - c0[0];
            const int dy = axis == 2 ? cf[1] - c0[1] : 0;
            s.g[u] = grid.squaredDistance(dx, dy, 0);
          }
        }
        envelope(s, len, w);
        for (int u = 0; u < len; ++u) ft[base + size_t(u) * stride] = s.out[u];
      }
    }, chunks);
    check();
  }
  return ft;
}

std::vector<double> featureSquaredDistances(const Grid3& grid, const std::vector<uint32_t>& ft,
                                            int threads) {
  std::vector<double> d(ft.size());
  parallelFor(ft.size(), threads, [&](size_t b, size_t e, int) {
    for (size_t v = b; v < e; ++v) d[v] = featureSquaredDistance(grid, v, ft[v]);
  });
  return d;
}

std::vector<float> featureDistances(const Grid3& grid, const std::vector<uint32_t>& ft,
                                    int threads) {
  std::vector<float> d(ft.size());
  parallelFor(ft.size(), threads, [&](size_t b, size_t e, int) {
    for (size_t v = b; v < e; ++v) d[v] = float(std::sqrt(featureSquaredDistance(grid, v, ft[v])));
  });
  return d;
}

}  // namespace femesher
