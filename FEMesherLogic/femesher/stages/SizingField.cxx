// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/stages/SizingField.h>

#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>
#include <femesher/stages/IndicatorFunctions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

namespace femesher {

namespace {

/// Largest float not above x.
inline float floatNotAbove(double x) {
  float f = float(x);
  if (double(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

struct Neighbour {
  int di, dj, dk;
  double length;  // mm
};

/// The 13 neighbours that precede a voxel in raster order (x fastest, then y, then z).
std::vector<Neighbour> precedingNeighbours(const Grid3& grid) {
  std::vector<Neighbour> out;
  for (int dk = -1; dk <= 1; ++dk)
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) {
        const bool before = dk < 0 || (dk == 0 && (dj < 0 || (dj == 0 && di < 0)));
        if (!before) continue;
        out.push_back({di, dj, dk, std::sqrt(grid.squaredDistance(di, dj, dk))});
      }
  return out;
}

Grid3 gridOf(const LabelVolume& volume) {
  Grid3 g;
  g.dims = volume.dims;
  g.spacing = volume.spacing;
  return g;
}


/// Height (mm, along `n`) of the smooth interface f_a = f_b above the grid-mm point `p`, by
/// Newton steps on g = f_a - f_b along n; false when the interface is not within `reach` mm.
bool interfaceHeight(const IndicatorField& f, int a, int b, const Vec3& sp, const Vec3& p,
                     const Vec3& n, double reach, double& z) {
  z = 0;
  for (int it = 0; it < 4; ++it) {
    const Vec3 q = add(p, scale(n, z));
    const Vec3 l{{q[0] / sp[0], q[1] / sp[1], q[2] / sp[2]}};
    Vec3 ga, gb;
    const double g = f.evalGradient(a, l, ga) - f.evalGradient(b, l, gb);
    double dg = 0;
    for (int k = 0; k < 3; ++k) dg += (ga[k] - gb[k]) / sp[k] * n[k];
    if (!(dg > 1e-6)) return false;
    z -= g / dg;
    if (!(std::fabs(z) < reach)) return false;
  }
  return true;
}

/// The largest principal curvature (1/mm) of the smooth interface between a and b at grid-mm
/// point `x0` on it: chords of half-length r in four tangent directions give the normal
/// curvature in each (sagitta sum / r²), and the curvature tensor is their least-squares fit
/// (which averages out some of the voxel bumps a single direction would read as curvature).
/// Directions where a probe does not find the interface within r, or comes within r of the
/// input's box (grid mm, `box`), are skipped; with fewer than four, the largest of the others.
double probeCurvature(const IndicatorField& f, int a, int b, const Vec3& sp, const Vec3& x0,
                      const Vec3& n, double r, const std::array<Vec3, 2>& box) {
  auto inBox = [&](const Vec3& p) {
    for (int c = 0; c < 3; ++c)
      if (p[c] - r < box[0][c] || p[c] + r > box[1][c]) return false;
    return true;
  };
  const Vec3 helper = std::fabs(n[0]) < 0.6 ? Vec3{{1, 0, 0}} : Vec3{{0, 1, 0}};
  Vec3 t1 = cross(n, helper);
  t1 = scale(t1, 1 / norm(t1));
  const Vec3 t2 = cross(n, t1);
  static const double c[4] = {1, 0.70710678118654752, 0, -0.70710678118654752};
  static const double s[4] = {0, 0.70710678118654752, 1, 0.70710678118654752};
  double k[4];
  int found = 0;
  double largest = 0;
  for (int d = 0; d < 4; ++d) {
    const Vec3 dir = add(scale(t1, c[d]), scale(t2, s[d]));
    const Vec3 pp = add(x0, scale(dir, r)), pm = sub(x0, scale(dir, r));
    double zp = 0, zm = 0;
    k[d] = std::numeric_limits<double>::quiet_NaN();
    if (!inBox(pp) || !inBox(pm) || !interfaceHeight(f, a, b, sp, pp, n, r, zp) ||
        !interfaceHeight(f, a, b, sp, pm, n, r, zm))
      continue;  // another material, the band's end or the box is there
    k[d] = (zp + zm) / (r * r);
    largest = std::max(largest, std::fabs(k[d]));
    ++found;
  }
  if (found < 4) return largest;
  // κ(θ) = A cos²θ + 2B sinθ cosθ + E sin²θ fitted to θ = 0, 45, 90, 135°.
  const double t = (k[1] + k[3] - k[0] - k[2]) / 4;
  const double A = k[0] + t, E = k[2] + t, B = (k[1] - k[3]) / 2;
  const double mean = (A + E) / 2, dev = std::sqrt((A - E) * (A - E) / 4 + B * B);
  return std::max(std::fabs(mean + dev), std::fabs(mean - dev));
}

/// Lowers h0 at interface voxels where the smooth interface bends: a triangle of edge h on a
/// surface of curvature κ has its centroid κh²/6 off the surface, so h ≤ sqrt(6 d / κ).
void limitByCurvature(const LabelVolume& volume, const IndicatorField& f, double d,
                      SizingField& field, int threads, RunContext& ctx) {
  const Grid3& grid = field.grid;
  const Vec3 sp = grid.spacing;
  const double smin = std::min({sp[0], sp[1], sp[2]});
  const int nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  // The input's box in grid mm (probes beyond it would read the box, not the interface).
  const WorkingGrid& wg = f.volume();
  std::array<Vec3, 2> box;
  for (int c = 0; c < 3; ++c) {
    const bool known = wg.inputDims[c] > 0;
    box[0][c] = known ? (-wg.offset[c] - 0.5) * sp[c] : -1e300;
    box[1][c] = known ? (wg.inputDims[c] - wg.offset[c] - 0.5) * sp[c] : 1e300;
  }
  parallelFor(size_t(nz), threads, [&](size_t b0, size_t e0, int) {
    ctx.checkCancel();
    for (size_t kk = b0; kk < e0; ++kk) {
      const int k = int(kk);
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const size_t v = grid.index(i, j, k);
          const double h0 = field.h[v];
          const int32_t a = volume.labels[v];
          int32_t b = a;
          static const int dn[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                                       {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
          for (int q = 0; q < 6 && b == a; ++q) {
            const int ii = i + dn[q][0], jj = j + dn[q][1], kc = k + dn[q][2];
            if (ii < 0 || jj < 0 || kc < 0 || ii >= nx || jj >= ny || kc >= nz) continue;
            b = volume.labels[grid.index(ii, jj, kc)];
          }
          if (b == a || a >= f.labelCount() || b >= f.labelCount()) continue;
          // onto the interface from the voxel centre; its unit normal there (grid mm)
          Vec3 l{{double(i), double(j), double(k)}};
          if (!moveOntoInterface(f, a, b, l)) continue;
          const Vec3 ga = f.gradient(a, l), gb = f.gradient(b, l);
          Vec3 n;
          for (int c = 0; c < 3; ++c) n[c] = (ga[c] - gb[c]) / sp[c];
          const double len = norm(n);
          if (!(len > 1e-6)) continue;
          n = scale(n, 1 / len);
          const Vec3 x{{l[0] * sp[0], l[1] * sp[1], l[2] * sp[2]}};
          // Chords of half the candidate size, but at least two voxels (the smooth interface of
          // a voxel map has bumps of a fraction of a voxel, which shorter chords would read as
          // curvature) and at most five (longer chords overstate a small sphere's curvature).
          const double r = std::clamp(0.5 * h0, 2 * smin, 5 * smin);
          const double kappa = probeCurvature(f, a, b, sp, x, n, r, box);
          const double h = kappa > 0 ? std::sqrt(6 * d / kappa) : h0;
          if (h < h0) field.h[v] = float(std::max(h, field.hMin));
        }
    }
  }, nz);  // one chunk per plane: only interface voxels cost, and they cluster
}

}  // namespace

void SizingField::pack(int threads) {
  if (h.empty()) return;
  packed = BrickGrid(h, grid.dims, threads);
  std::vector<float>().swap(h);
}

std::vector<float> SizingField::values(int threads) const {
  return h.empty() ? packed.dense(threads) : h;
}

float SizingField::at(const Vec3& c) const {
  if (empty()) return 0.f;
  int i0[3];
  double t[3];
  int i1[3];
  for (int a = 0; a < 3; ++a) {
    const int n = grid.dims[a];
    double x = c[a] / grid.spacing[a];
    x = std::clamp(x, 0.0, double(n - 1));
    i0[a] = std::min(int(std::floor(x)), n - 1);
    i1[a] = std::min(i0[a] + 1, n - 1);
    t[a] = x - i0[a];
  }
  double v = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const int bx = corner & 1, by = (corner >> 1) & 1, bz = (corner >> 2) & 1;
    const double wgt = (bx ? t[0] : 1 - t[0]) * (by ? t[1] : 1 - t[1]) * (bz ? t[2] : 1 - t[2]);
    if (wgt == 0) continue;
    v += wgt * value(bx ? i1[0] : i0[0], by ? i1[1] : i0[1], bz ? i1[2] : i0[2]);
  }
  return float(v);
}

double uniformEdgeLength(const LabelVolume& in, const SizingParameters& p) {
  if (p.targetEdgeLength > 0) return p.targetEdgeLength;
  const double mean = (in.spacing[0] + in.spacing[1] + in.spacing[2]) / 3.0;
  double h = p.edgeLengthFactor * mean;
  std::array<int, 3> lo{{in.dims[0], in.dims[1], in.dims[2]}}, hi{{-1, -1, -1}};
  const bool all = in.hasNoBackground();
  for (int k = 0; k < in.dims[2]; ++k)
    for (int j = 0; j < in.dims[1]; ++j)
      for (int i = 0; i < in.dims[0]; ++i)
        if (all || in.at(i, j, k) != 0) {
          lo = {std::min(lo[0], i), std::min(lo[1], j), std::min(lo[2], k)};
          hi = {std::max(hi[0], i), std::max(hi[1], j), std::max(hi[2], k)};
        }
  for (int a = 0; a < 3; ++a)
    if (hi[a] >= lo[a]) h = std::min(h, 0.25 * (hi[a] - lo[a] + 1) * in.spacing[a]);
  return h;
}

MedialAxisParameters medialAxisParameters(const SizingParameters& params) {
  MedialAxisParameters mp;
  mp.pruning = params.pruning;
  mp.gamma = params.gamma;
  mp.gammaConstant = params.gammaConstant;
  mp.threads = params.threads;
  return mp;
}

void resolveSizingBounds(const SizingParameters& p, const LabelVolume& volume, double& hMin,
                         double& hMax) {
  auto bad = [](const std::string& what) {
    throw Error(ErrorCode::InvalidArgument, "Sizing field: " + what);
  };
  if (!(p.scale > 0) || !std::isfinite(p.scale))
    bad("scale must be > 0 (got " + std::to_string(p.scale) + "); try 1.25.");
  if (!(p.gradation > 0) || !std::isfinite(p.gradation))
    bad("gradation must be > 0 (got " + std::to_string(p.gradation) + "); try 0.4.");
  if (!(p.hMin >= 0) || !std::isfinite(p.hMin))
    bad("hMin must be >= 0 mm (0 = automatic); got " + std::to_string(p.hMin) + ".");
  if (!(p.hMax >= 0) || !std::isfinite(p.hMax))
    bad("hMax must be >= 0 mm (0 = automatic); got " + std::to_string(p.hMax) + ".");
  const double h = p.hMin > 0 && p.hMax > 0 ? 0 : uniformEdgeLength(volume, p);
  hMin = p.hMin > 0 ? p.hMin : 0.5 * h;
  hMax = p.hMax > 0 ? p.hMax : 2.5 * h;
  if (hMin > hMax && p.hMin > 0 && p.hMax > 0)
    bad("hMax (" + std::to_string(hMax) + " mm) is below hMin (" + std::to_string(hMin) +
        " mm); raise hMax or lower hMin.");
  if (hMin > hMax) hMin = hMax;
}

std::vector<float> localFeatureSize(const Grid3& grid, const std::vector<uint8_t>& medialMask,
                                    int threads, RunContext* ctx) {
  const std::vector<uint32_t> ft = featureTransform(grid, medialMask, threads, ctx);
  return featureDistances(grid, ft, threads);
}

int limitGradation(const Grid3& grid, std::vector<float>& h, double L, RunContext* ctx) {
  if (h.size() != grid.size())
    throw Error(ErrorCode::InvalidArgument, "limitGradation: field and grid sizes differ.");
  const auto nbs = precedingNeighbours(grid);
  const int nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  std::vector<double> step(nbs.size());
  std::vector<long long> offset(nbs.size());
  for (size_t n = 0; n < nbs.size(); ++n) {
    step[n] = L * nbs[n].length;
    offset[n] = nbs[n].di + (long long)nx * (nbs[n].dj + (long long)ny * nbs[n].dk);
  }
  tbb::task_arena arena(resolveThreads(ctx ? ctx->threads() : 0));
  // One row (j, k) of a sweep: in raster order it reads only rows (j - 1, k) and (j - 1 .. j + 1,
  // k - 1) and its own earlier voxels (mirrored for the backward sweep), so all rows on one
  // wavefront j + 2 k (counted from the sweep's start) are independent: they run in parallel
  // with exactly the arithmetic of the sequential sweep, hence the same result.
  auto sweepRow = [&](int sign, int j, int k) {
    bool changed = false;
    const bool innerRow = j > 0 && k > 0 && j < ny - 1 && k < nz - 1;
    for (int ii = 0; ii < nx; ++ii) {
      const int i = sign > 0 ? ii : nx - 1 - ii;
      const size_t v = grid.index(i, j, k);
      const bool inner = innerRow && i > 0 && i < nx - 1;  // every neighbour inside the grid
      double hv = h[v];
      bool lowered = false;
      for (size_t n = 0; n < nbs.size(); ++n) {
        if (!inner) {
          const int ni = i + sign * nbs[n].di, nj = j + sign * nbs[n].dj,
                    nk = k + sign * nbs[n].dk;
          if (ni < 0 || nj < 0 || nk < 0 || ni >= nx || nj >= ny || nk >= nz) continue;
        }
        const double cand = double(h[v + sign * offset[n]]) + step[n];
        if (cand < hv) {
          hv = cand;
          lowered = true;
        }
      }
      if (lowered) {
        h[v] = floatNotAbove(hv);
        changed = true;
      }
    }
    return changed;
  };
  int sweeps = 0;
  for (;;) {
    std::atomic<bool> changed{false};
    // sign = +1: forward sweep in raster order, reading the preceding neighbours (offset < 0,
    // already final in this sweep); -1: backward sweep, reading the following ones. Two sweeps
    // give the chamfer envelope (every neighbour path reorders into forward moves then backward
    // moves); the loop repeats only to confirm it (or to finish paths bent by the grid border).
    for (int sign : {1, -1}) {
      ++sweeps;
      if (arena.max_concurrency() == 1) {  // one thread: plain raster order (cache-friendliest)
        bool any = false;
        for (int kk = 0; kk < nz; ++kk) {
          if (ctx && (kk & 15) == 0) ctx->checkCancel();
          for (int jj = 0; jj < ny; ++jj)
            any |= sweepRow(sign, sign > 0 ? jj : ny - 1 - jj, sign > 0 ? kk : nz - 1 - kk);
        }
        if (any) changed.store(true, std::memory_order_relaxed);
        continue;
      }
      // Rows (j, k) in skewed coordinates (t = j + 2 k, k): row (t, k) reads rows (t - 1, k),
      // (t - 3 .. t - 1, k - 1) only. Tiles of kTileT x kTileK rows: tile (T, K) reads tiles
      // (T - 1, K), (T, K - 1) and (T - 1, K - 1), so the tiles on one wavefront T + K are
      // independent; inside a tile the rows go by t, then k. Every row reads exactly the rows
      // the sequential sweep finished before it: the same arithmetic, the same sweeps, with a few
      // hundred synchronisations per sweep instead of one per row wavefront (too short for a
      // second thread to join).
      constexpr int kTileT = 64, kTileK = 16;
      const int tMax = (ny - 1) + 2 * (nz - 1);
      const int nT = tMax / kTileT + 1, nK = (nz + kTileK - 1) / kTileK;
      auto tile = [&](int T, int K) {
        bool any = false;
        for (int t = T * kTileT; t <= std::min(tMax, T * kTileT + kTileT - 1); ++t) {
          const int kLo = std::max({0, (t - (ny - 1) + 1) / 2, K * kTileK});
          const int kHi = std::min({nz - 1, t / 2, K * kTileK + kTileK - 1});
          for (int kk = kLo; kk <= kHi; ++kk) {
            const int jj = t - 2 * kk;
            any |= sweepRow(sign, sign > 0 ? jj : ny - 1 - jj, sign > 0 ? kk : nz - 1 - kk);
          }
        }
        if (any) changed.store(true, std::memory_order_relaxed);
      };
      for (int w = 0; w <= (nT - 1) + (nK - 1); ++w) {
        if (ctx) ctx->checkCancel();
        const int kLo = std::max(0, w - (nT - 1)), kHi = std::min(nK - 1, w);
        if (kHi == kLo) {
          tile(w - kLo, kLo);
          continue;
        }
        arena.execute([&] {
          tbb::parallel_for(tbb::blocked_range<int>(kLo, kHi + 1, 1),
                            [&](const tbb::blocked_range<int>& r) {
                              for (int K = r.begin(); K < r.end(); ++K) tile(w - K, K);
                            });
        });
      }
    }
    if (!changed.load()) break;
  }
  return sweeps;
}

SizingField computeSizingField(const LabelVolume& volume, const SizingParameters& params,
                               RunContext& ctx) {
  const MedialAxisParameters mp = medialAxisParameters(params);
  double hMin = 0, hMax = 0;
  resolveSizingBounds(params, volume, hMin, hMax);  // fail early
  if (volume.voxelCount() == 0)
    throw Error(ErrorCode::InvalidArgument, "Sizing field: the label map has no voxels.");
  const LabelMedialAxes axes = computeAllMedialAxes(volume, mp, ctx, 0.0, 0.6);
  return computeSizingField(volume, axes, params, ctx);
}

SizingField computeSizingField(const LabelVolume& volume, const LabelMedialAxes& axes,
                               const SizingParameters& params, RunContext& ctx,
                               const IndicatorField* surfaces) {
  SizingField field;
  field.grid = gridOf(volume);
  const Grid3& grid = field.grid;
  resolveSizingBounds(params, volume, field.hMin, field.hMax);
  const size_t n = grid.size();
  if (n == 0) throw Error(ErrorCode::InvalidArgument, "Sizing field: the label map has no voxels.");
  if (volume.labels.size() != n || axes.unionMask.size() != n)
    throw Error(ErrorCode::InvalidArgument,
                  "Sizing field: the label map and its medial axes do not have the same size.");
  field.medialVoxels = axes.voxelCount();
  ctx.progress(0.6);
  const std::vector<float> lfs = localFeatureSize(grid, axes.unionMask, params.threads, &ctx);
  ctx.progress(0.75);

  const bool meshBorder = volume.hasNoBackground();
  const int nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  const float fMax = float(field.hMax);
  field.h.assign(n, fMax);
  std::vector<size_t> interfaceCount(size_t(nz), 0);
  parallelFor(size_t(nz), params.threads, [&](size_t b, size_t e, int) {
    ctx.checkCancel();
    for (size_t kk = b; kk < e; ++kk) {
      const int k = int(kk);
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          const size_t v = grid.index(i, j, k);
          const int32_t l = volume.labels[v];
          bool isInterface = !params.interfacesOnly;
          if (!isInterface) {
            const bool border = i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 ||
                                k == nz - 1;
            if (border && (l != 0 || meshBorder)) isInterface = true;
            static const int d[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                                        {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
            for (int q = 0; q < 6 && !isInterface; ++q) {
              const int a = i + d[q][0], bb = j + d[q][1], c = k + d[q][2];
              if (a < 0 || bb < 0 || c < 0 || a >= nx || bb >= ny || c >= nz) continue;
              if (volume.labels[grid.index(a, bb, c)] != l) isInterface = true;
            }
          }
          if (!isInterface) continue;
          ++interfaceCount[kk];
          const double h0 = params.scale * double(lfs[v]);  // +inf when no axis at all
          field.h[v] = float(std::clamp(h0, field.hMin, field.hMax));
        }
    }
  });
  for (size_t c : interfaceCount) field.interfaceVoxels += c;
  if (surfaces && params.curvatureDistance > 0)
    limitByCurvature(volume, *surfaces, params.curvatureDistance * std::min({grid.spacing[0], grid.spacing[1], grid.spacing[2]}), field,
                     params.threads, ctx);
  ctx.progress(0.8);
  const auto t0 = std::chrono::steady_clock::now();
  const int sweeps = limitGradation(grid, field.h, params.gradation, &ctx);
  ctx.debug("SizingField: gradation limit in " + std::to_string(sweeps) + " sweeps, " +
            std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()) + " s");
  if (!field.h.empty()) {
    const auto [lowest, highest] = std::minmax_element(field.h.begin(), field.h.end());
    field.lowest = *lowest;
    field.highest = *highest;
  }
  ctx.progress(1.0);
  return field;
}

}  // namespace femesher
