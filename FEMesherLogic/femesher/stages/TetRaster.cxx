// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>
#include <femesher/stages/internal/TetRaster.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace femesher {

namespace {

constexpr double kBaryTol = 1e-9;  ///< barycentric tolerance of the containment test

/// Outward normal lexicographically positive (see the header).
bool lexPositive(const double* n) {
  const double s = std::max({std::fabs(n[0]), std::fabs(n[1]), std::fabs(n[2])}) * 1e-9;
  for (int k = 0; k < 3; ++k) {
    if (n[k] > s) return true;
    if (n[k] < -s) return false;
  }
  return false;
}

/// Barycentric coordinates of one tet as affine functions of the (continuous) voxel index.
struct TetFrame {
  Vec3 a;                  ///< vertex 0
  double g[4][3];          ///< gradients of λ1..λ3 (row 0 unused)
  bool keepOnFace[4];      ///< a point on face f belongs to this tet
  bool flat = false;       ///< no interior: contains nothing
  /// The barycentric coordinates λ0..λ3 of p.
  void coordinates(const Vec3& p, double l[4]) const {
    const double px = p[0] - a[0], py = p[1] - a[1], pz = p[2] - a[2];
    l[1] = g[1][0] * px + g[1][1] * py + g[1][2] * pz;
    l[2] = g[2][0] * px + g[2][1] * py + g[2][2] * pz;
    l[3] = g[3][0] * px + g[3][1] * py + g[3][2] * pz;
    l[0] = 1.0 - l[1] - l[2] - l[3];
  }
  bool contains(const Vec3& p) const {
    double l[4];
    coordinates(p, l);
    return ok(l[1], 1) && ok(l[2], 2) && ok(l[3], 3) && ok(l[0], 0);
  }
  bool ok(double l, int f) const { return l > kBaryTol || (l >= -kBaryTol && keepOnFace[f]); }
  /// Over the unit cube centred at c, each barycentric coordinate lies within reach[k] of its
  /// value at c: 1 when the whole cube is inside the tet (every point of it is contained), -1
  /// when no point of it is, 0 when the cube may straddle the tet's boundary.
  int cube(const Vec3& c) const {
    double l[4];
    coordinates(c, l);
    bool inside = true;
    for (int k = 0; k < 4; ++k) {
      if (l[k] + reach[k] < -kBaryTol) return -1;
      inside = inside && l[k] - reach[k] > kBaryTol;
    }
    return inside ? 1 : 0;
  }
  double reach[4];  ///< half the L1 norm of each coordinate's gradient (with a little margin)
};

TetFrame tetFrame(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  TetFrame f;
  f.a = a;
  const double m[9] = {b[0] - a[0], c[0] - a[0], d[0] - a[0], b[1] - a[1], c[1] - a[1],
                       d[1] - a[1], b[2] - a[2], c[2] - a[2], d[2] - a[2]};
  const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                     m[2] * (m[3] * m[7] - m[4] * m[6]);
  double scale = 0;
  for (double x : m) scale += std::fabs(x);
  if (!(std::fabs(det) > 1e-14 * scale * scale * scale)) {
    f.flat = true;
    return f;
  }
  const double g[4][3] = {{0, 0, 0},
                          {(m[4] * m[8] - m[5] * m[7]) / det, (m[2] * m[7] - m[1] * m[8]) / det,
                           (m[1] * m[5] - m[2] * m[4]) / det},
                          {(m[5] * m[6] - m[3] * m[8]) / det, (m[0] * m[8] - m[2] * m[6]) / det,
                           (m[2] * m[3] - m[0] * m[5]) / det},
                          {(m[3] * m[7] - m[4] * m[6]) / det, (m[1] * m[6] - m[0] * m[7]) / det,
                           (m[0] * m[4] - m[1] * m[3]) / det}};
  std::copy(&g[0][0], &g[0][0] + 12, &f.g[0][0]);
  for (int k = 1; k < 4; ++k) {
    const double n[3] = {-g[k][0], -g[k][1], -g[k][2]};
    f.keepOnFace[k] = lexPositive(n);
  }
  const double n0[3] = {g[1][0] + g[2][0] + g[3][0], g[1][1] + g[2][1] + g[3][1],
                        g[1][2] + g[2][2] + g[3][2]};
  f.keepOnFace[0] = lexPositive(n0);
  // The margin covers rounding in the evaluation at a cube's centre against the one at a sample.
  f.reach[0] = 0.5 * (std::fabs(n0[0]) + std::fabs(n0[1]) + std::fabs(n0[2])) * (1 + 1e-9) + 1e-12;
  for (int k = 1; k < 4; ++k)
    f.reach[k] = 0.5 * (std::fabs(g[k][0]) + std::fabs(g[k][1]) + std::fabs(g[k][2])) * (1 + 1e-9) + 1e-12;
  return f;
}

/// The voxel range [lo, hi] (clamped to the grid) of the tet's index-space bounding box along
/// axis k, `s` sub-samples per voxel: samples X with (X + 0.5) / s - 0.5 in [mn, mx].
void sampleRange(double mn, double mx, int n, int s, int& lo, int& hi) {
  const double eps = 1e-6;
  lo = std::max(0, int(std::max(-1.0, std::ceil(s * (mn + 0.5) - 0.5 - eps))));
  hi = std::min(n * s - 1, int(std::min(double(n) * s, std::floor(s * (mx + 0.5) - 0.5 + eps))));
}

/// A tet's corners (continuous voxel index) and their bounding box.
struct TetCorners {
  TetCorners(const std::vector<Vec3>& idx, const std::array<int32_t, 4>& T)
      : a(idx[size_t(T[0])]), b(idx[size_t(T[1])]), c(idx[size_t(T[2])]), d(idx[size_t(T[3])]) {
    for (int k = 0; k < 3; ++k) {
      mn[k] = std::min({a[k], b[k], c[k], d[k]});
      mx[k] = std::max({a[k], b[k], c[k], d[k]});
    }
  }
  TetFrame frame() const { return tetFrame(a, b, c, d); }
  const Vec3 &a, &b, &c, &d;
  double mn[3], mx[3];
};

/// Calls fn(t, vi) for every voxel centre vi in z range [zs, ze] that a tet t of `candidates`
/// contains.
template <class Fn>
void forEachCentre(const LabelVolume& labels, const TetMesh& mesh, const std::vector<Vec3>& idx,
                   const std::vector<uint32_t>& candidates, int zs, int ze, RunContext* ctx,
                   Fn&& fn) {
  const auto& dims = labels.dims;
  for (size_t i = 0; i < candidates.size(); ++i) {
    if ((i & 0xFFFF) == 0 && ctx && ctx->isCanceled()) return;
    const size_t t = candidates[i];
    const TetCorners q(idx, mesh.tets[t]);
    int lo[3], hi[3];
    for (int k = 0; k < 3; ++k) sampleRange(q.mn[k], q.mx[k], dims[k], 1, lo[k], hi[k]);
    lo[2] = std::max(lo[2], zs);
    hi[2] = std::min(hi[2], ze);
    if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) continue;
    const TetFrame f = q.frame();
    if (f.flat) continue;
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x)
          if (f.contains({double(x), double(y), double(z)})) fn(t, labels.index(x, y, z));
  }
}

/// A deterministic offset in [0, 1) for cell (X, Y, Z) along `axis` (stratified sampling: one line
/// at a random place in each cell, so the lines do not alias with voxel faces or mesh planes).
double jitter(int X, int Y, int Z, int axis) {
  uint64_t h = uint64_t(uint32_t(X)) * 0x9E3779B97F4A7C15ull ^ uint64_t(uint32_t(Y)) * 0xC2B2AE3D27D4EB4Full ^
               uint64_t(uint32_t(Z)) * 0x165667B19E3779F9ull ^ uint64_t(axis + 1) * 0x27D4EB2F165667C5ull;
  h ^= h >> 31;
  h *= 0x7FB5D329728EA185ull;
  h ^= h >> 27;
  return double(h >> 11) * (1.0 / 9007199254740992.0);
}

/// Calls fn(t, vi, length) for every voxel vi with cut[vi], in z range [zs, ze], and tet t of
/// `candidates` that meets it: the voxel is crossed by s x s lines along x (stratified: one at a
/// random place in each of the s x s cells of its y-z face), and `length` is the total length
/// (in voxels) of those lines inside t. Along x the integral is exact; the lines of a voxel are the
/// same for every tet, so in a conformal mesh the tets share each line out exactly.
template <class Fn>
void forEachCutLine(const LabelVolume& labels, const TetMesh& mesh, const std::vector<Vec3>& idx,
                    const std::vector<uint32_t>& candidates, const std::vector<uint8_t>& cut,
                    int s, int zs, int ze, RunContext* ctx, Fn&& fn) {
  const auto& dims = labels.dims;
  const double cell = 1.0 / s;  // a line cell's width (voxels)
  for (size_t i = 0; i < candidates.size(); ++i) {
    if ((i & 0xFFFF) == 0 && ctx && ctx->isCanceled()) return;
    const size_t t = candidates[i];
    const TetCorners q(idx, mesh.tets[t]);
    int lo[3], hi[3], slo[3], shi[3];  // voxel range and line cell range of the tet
    for (int k = 0; k < 3; ++k) {
      const double mn = q.mn[k], mx = q.mx[k];
      lo[k] = std::max(0, int(std::floor(mn + 0.5)));
      hi[k] = std::min(dims[k] - 1, int(std::floor(mx + 0.5)));
      slo[k] = int(std::floor(s * (mn + 0.5)));
      shi[k] = int(std::floor(s * (mx + 0.5)));
    }
    lo[2] = std::max(lo[2], zs);
    hi[2] = std::min(hi[2], ze);
    if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) continue;
    TetFrame f;
    bool framed = false;
    // How each barycentric coordinate changes along x, and its inverse (0: it does not).
    double dx[4] = {0, 0, 0, 0}, inv[4] = {0, 0, 0, 0};
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const size_t vi = labels.index(x, y, z);
          if (!cut[vi]) continue;
          if (!framed) {
            f = q.frame();
            framed = true;
            dx[1] = f.g[1][0];
            dx[2] = f.g[2][0];
            dx[3] = f.g[3][0];
            dx[0] = -(dx[1] + dx[2] + dx[3]);
            for (int k = 0; k < 4; ++k) inv[k] = dx[k] != 0 ? 1 / dx[k] : 0;
          }
          if (f.flat) break;
          // A voxel wholly outside the tet holds none of its lines, one wholly inside all.
          const int where = f.cube({double(x), double(y), double(z)});
          if (where < 0) continue;
          if (where > 0) {
            fn(t, vi, double(s) * s);
            continue;
          }
          // The line cells of this voxel that the tet's box reaches.
          const int z0 = std::max(z * s, slo[2]), z1 = std::min(z * s + s - 1, shi[2]);
          const int y0 = std::max(y * s, slo[1]), y1 = std::min(y * s + s - 1, shi[1]);
          double length = 0;
          for (int Z = z0; Z <= z1; ++Z)
            for (int Y = y0; Y <= y1; ++Y) {
              // The line's start on the voxel's x face, then the part of [0, 1] where every
              // barycentric coordinate is non-negative.
              const Vec3 p{x - 0.5, (Y + jitter(x, Y, Z, 1)) * cell - 0.5,
                           (Z + jitter(x, Y, Z, 2)) * cell - 0.5};
              double l[4];
              f.coordinates(p, l);
              double a = 0, b = 1;
              for (int k = 0; k < 4 && a < b; ++k) {
                if (dx[k] > 0)
                  a = std::max(a, -l[k] * inv[k]);
                else if (dx[k] < 0)
                  b = std::min(b, -l[k] * inv[k]);
                else if (l[k] < 0)
                  b = a;
              }
              if (b > a) length += b - a;
            }
          if (length > 0) fn(t, vi, length);
        }
  }
}

/// The z-slabs a parallel sweep of the grid uses (about eight per thread): slab k holds voxel
/// planes [first[k], first[k + 1]), and tets[k] the tets whose z extent (continuous voxel index,
/// grown by half a voxel) reaches it, in mesh order.
struct Slabs {
  std::vector<int> first;
  std::vector<std::vector<uint32_t>> tets;
};

Slabs slabsOf(const LabelVolume& labels, const TetMesh& mesh, const std::vector<Vec3>& idx,
              int threads) {
  const int nz = labels.dims[2];
  const int n = std::min(nz, resolveThreads(threads) * 8);
  Slabs sl;
  sl.first.resize(size_t(n) + 1);
  if (n <= 0) return sl;
  for (int k = 0; k <= n; ++k) sl.first[size_t(k)] = int(int64_t(nz) * k / n);
  std::vector<int> slabOfPlane(size_t(std::max(nz, 1)));
  for (int k = 0; k < n; ++k)
    for (int z = sl.first[size_t(k)]; z < sl.first[size_t(k) + 1]; ++z) slabOfPlane[size_t(z)] = k;
  // The slab range of every tet (k0 > k1: none), then each slab's tets in mesh order.
  std::vector<std::array<int, 2>> range(mesh.tets.size());
  parallelFor(mesh.tets.size(), threads, [&](size_t b, size_t e, int) {
    for (size_t t = b; t < e; ++t) {
      double mn = 1e300, mx = -1e300;
      for (int32_t v : mesh.tets[t]) {
        mn = std::min(mn, idx[size_t(v)][2]);
        mx = std::max(mx, idx[size_t(v)][2]);
      }
      const double lo = std::floor(mn - 0.5), hi = std::ceil(mx + 0.5);
      if (!(hi >= 0) || !(lo <= nz - 1)) {
        range[t] = {1, 0};
        continue;
      }
      range[t] = {slabOfPlane[size_t(std::max(0.0, lo))],
                  slabOfPlane[size_t(std::min(double(nz - 1), hi))]};
    }
  });
  sl.tets.resize(size_t(n));
  parallelFor(size_t(n), threads, [&](size_t b, size_t e, int) {
    for (size_t k = b; k < e; ++k)
      for (size_t t = 0; t < range.size(); ++t)
        if (range[t][0] <= int(k) && int(k) <= range[t][1]) sl.tets[k].push_back(uint32_t(t));
  }, n);
  return sl;
}

std::vector<Vec3> indexPositions(const LabelVolume& labels, const TetMesh& mesh, int threads) {
  std::vector<Vec3> idx(mesh.points.size());
  parallelFor(idx.size(), threads, [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) idx[i] = labels.physicalToIndex(mesh.points[i]);
  });
  return idx;
}

/// True when triangle (a, b, c) meets the axis-aligned cube of half-width h centred at o: no
/// separating axis among the triangle's normal and the nine products of a cube axis with a
/// triangle edge (the cube's own axes are the caller's bounding-box test).
bool triangleMeetsCube(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& o, double h) {
  const Vec3 v[3] = {sub(a, o), sub(b, o), sub(c, o)};
  const Vec3 e[3] = {sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])};
  auto separates = [&](const Vec3& axis) {
    const double p0 = dot(axis, v[0]), p1 = dot(axis, v[1]), p2 = dot(axis, v[2]);
    const double r = h * (std::fabs(axis[0]) + std::fabs(axis[1]) + std::fabs(axis[2]));
    return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
  };
  for (const Vec3& edge : e) {
    if (separates({0.0, -edge[2], edge[1]}) || separates({edge[2], 0.0, -edge[0]}) ||
        separates({-edge[1], edge[0], 0.0}))
      return false;
  }
  return !separates(cross(e[0], e[1]));
}

/// Voxels an interface or boundary triangle of the mesh meets (the voxel's cube grown by 1e-6
/// voxel, so that a triangle on a voxel face counts for both voxels): every other voxel lies in
/// one material region of the mesh.
std::vector<uint8_t> cutVoxels(const LabelVolume& labels,
                               const std::vector<InterfaceTriangle>& tris,
                               const std::vector<Vec3>& idx, int threads) {
  constexpr double kGrow = 1e-6;
  std::vector<uint8_t> cut(labels.voxelCount(), 0);
  const int nz = labels.dims[2];
  // Fixed z-slabs, each flagging the voxels of its own planes: every voxel is flagged by the same
  // test as in one sequential pass (a flag is set once any triangle meets the voxel).
  const int slabs = std::max(1, std::min(nz, 64));
  auto inSlab = std::vector<std::vector<uint32_t>>(size_t(slabs));
  for (size_t t = 0; t < tris.size(); ++t) {
    const InterfaceTriangle& tri = tris[t];
    const double z0 = std::min({idx[size_t(tri.v[0])][2], idx[size_t(tri.v[1])][2], idx[size_t(tri.v[2])][2]});
    const double z1 = std::max({idx[size_t(tri.v[0])][2], idx[size_t(tri.v[1])][2], idx[size_t(tri.v[2])][2]});
    const int lo = std::max(0, int(std::ceil(z0 - 0.5 - kGrow)));
    const int hi = std::min(nz - 1, int(std::floor(z1 + 0.5 + kGrow)));
    if (lo > hi) continue;
    const int s0 = int(int64_t(lo) * slabs / nz), s1 = int(int64_t(hi) * slabs / nz);
    for (int s = s0; s <= s1; ++s) inSlab[size_t(s)].push_back(uint32_t(t));
  }
  parallelFor(size_t(slabs), threads, [&](size_t sb, size_t se, int) {
    for (size_t s = sb; s < se; ++s) {
      // Planes z with z * slabs / nz == s.
      const int zs = int((int64_t(s) * nz + slabs - 1) / slabs);
      const int ze = int((int64_t(s + 1) * nz + slabs - 1) / slabs) - 1;
      for (uint32_t t : inSlab[s]) {
        const InterfaceTriangle& tri = tris[t];
        const Vec3 &a = idx[size_t(tri.v[0])], &b = idx[size_t(tri.v[1])], &c = idx[size_t(tri.v[2])];
        int lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
          const double mn = std::min({a[k], b[k], c[k]}), mx = std::max({a[k], b[k], c[k]});
          lo[k] = std::max(0, int(std::ceil(mn - 0.5 - kGrow)));
          hi[k] = std::min(labels.dims[k] - 1, int(std::floor(mx + 0.5 + kGrow)));
        }
        lo[2] = std::max(lo[2], zs);
        hi[2] = std::min(hi[2], ze);
        for (int z = lo[2]; z <= hi[2]; ++z)
          for (int y = lo[1]; y <= hi[1]; ++y)
            for (int x = lo[0]; x <= hi[0]; ++x) {
              uint8_t& flag = cut[labels.index(x, y, z)];
              if (!flag && triangleMeetsCube(a, b, c, {double(x), double(y), double(z)}, 0.5 + kGrow))
                flag = 1;
            }
      }
    }
  }, slabs);
  return cut;
}

}  // namespace

LabelIndex::LabelIndex(const std::vector<int32_t>& sorted) : ids_(sorted) {
  lo_ = sorted.empty() ? 0 : sorted.front();
  const int64_t range = sorted.empty() ? 0 : int64_t(sorted.back()) - lo_ + 1;
  if (range <= (int64_t(1) << 22)) {
    table_.assign(size_t(range), 0);
    for (size_t k = 0; k < sorted.size(); ++k)
      table_[size_t(int64_t(sorted[k]) - lo_)] = uint16_t(k);
  } else {
    for (size_t k = 0; k < sorted.size(); ++k) map_[sorted[k]] = uint16_t(k);
  }
}

std::vector<uint16_t> rasterize(const LabelVolume& labels, const TetMesh& mesh,
                                const std::vector<uint16_t>& tetValue, uint16_t background,
                                int threads, RunContext* ctx) {
  const std::vector<Vec3> idx = indexPositions(labels, mesh, threads);
  std::vector<uint16_t> meshLabel(labels.voxelCount(), background);
  const Slabs slabs = slabsOf(labels, mesh, idx, threads);
  parallelFor(slabs.tets.size(), threads, [&](size_t s0, size_t s1, int) {
    for (size_t sl = s0; sl < s1; ++sl) {
      const int zs = slabs.first[sl], ze = slabs.first[sl + 1] - 1;
      forEachCentre(labels, mesh, idx, slabs.tets[sl], zs, ze, ctx,
                    [&](size_t t, size_t vi) { meshLabel[vi] = tetValue[t]; });
    }
  }, int(slabs.tets.size()));  // one chunk per slab: their costs differ widely
  return meshLabel;
}

std::vector<double> overlapVolumes(const LabelVolume& labels, const TetMesh& mesh,
                                   const std::vector<InterfaceTriangle>& tris,
                                   const LabelIndex& index, const std::vector<uint16_t>& tetIndex,
                                   const std::vector<uint16_t>& centre, int linesPerAxis,
                                   int threads, RunContext* ctx) {
  const int s = std::max(1, linesPerAxis);
  const std::vector<Vec3> idx = indexPositions(labels, mesh, threads);
  const std::vector<uint8_t> cut = cutVoxels(labels, tris, idx, threads);
  const size_t L = index.size();
  const int nz = labels.dims[2];
  const size_t sliceSize = size_t(labels.dims[0]) * size_t(labels.dims[1]);
  // Per z-slice: whole voxels (uncut, centre agrees) and the length of lines (cut voxels) in
  // tets that agree, in units of 2^-50 voxel (integers: the sums do not depend on their order, so
  // neither on the slabs nor on the thread count; 128 bits hold any grid's total).
  using Length = unsigned __int128;
  constexpr double kUnit = 1125899906842624.0;  // 2^50
  std::vector<std::vector<uint64_t>> whole(static_cast<size_t>(nz));
  std::vector<std::vector<Length>> lines(static_cast<size_t>(nz));
  const Slabs slabs = slabsOf(labels, mesh, idx, threads);
  parallelFor(slabs.tets.size(), threads, [&](size_t s0, size_t s1, int) {
    for (size_t sl = s0; sl < s1; ++sl) {
      const int zs = slabs.first[sl], ze = slabs.first[sl + 1] - 1;
      std::vector<uint64_t> w(L, 0);
      std::vector<Length> len(L, 0);
      for (size_t vi = size_t(zs) * sliceSize; vi < size_t(ze + 1) * sliceSize; ++vi) {
        if (cut[vi]) continue;
        const uint16_t l = index(labels.labels[vi]);
        if (l != 0 && centre[vi] == l) ++w[l];
      }
      forEachCutLine(labels, mesh, idx, slabs.tets[sl], cut, s, zs, ze, ctx,
                     [&](size_t t, size_t vi, double length) {
                       const uint16_t l = tetIndex[t];
                       if (l == index(labels.labels[vi])) len[l] += Length(std::llround(length * kUnit));
                     });
      whole[size_t(zs)] = std::move(w);
      lines[size_t(zs)] = std::move(len);
    }
  }, int(slabs.tets.size()));  // one chunk per slab: their costs differ widely
  const Vec3& sp = labels.spacing;
  // A line of length 1 stands for 1 / s^2 of its voxel.
  const double voxel = sp[0] * sp[1] * sp[2], line = voxel / (double(s) * s);
  std::vector<uint64_t> w(L, 0);
  std::vector<Length> len(L, 0);
  for (int z = 0; z < nz; ++z)
    for (size_t k = 0; k < L && !whole[size_t(z)].empty(); ++k) {
      w[k] += whole[size_t(z)][k];
      len[k] += lines[size_t(z)][k];
    }
  std::vector<double> overlap(L, 0.0);
  for (size_t k = 1; k < L; ++k) overlap[k] = double(w[k]) * voxel + double(len[k]) / kUnit * line;
  return overlap;
}

}  // namespace femesher
