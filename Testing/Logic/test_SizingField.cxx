// SPDX-License-Identifier: GPL-3.0-or-later
// Sizing field: local feature size, clamp, gradation and the thin-versus-thick behaviour.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/SizingField.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "MeshInvariants.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

/// Background, a thin plate (label 3, three voxels = 1.5 mm thick) and a big ball (label 5).
LabelVolume plateAndBall() {
  LabelVolume vol;
  vol.dims = {{56, 40, 40}};
  vol.spacing = {{0.5, 0.5, 0.5}};
  vol.labels.assign(vol.voxelCount(), 0);
  for (int k = 0; k < 40; ++k)
    for (int j = 0; j < 40; ++j)
      for (int i = 0; i < 56; ++i) {
        int32_t l = 0;
        if (i >= 5 && i <= 7 && j >= 6 && j <= 33 && k >= 6 && k <= 33) l = 3;
        if ((i - 32) * (i - 32) + (j - 20) * (j - 20) + (k - 20) * (k - 20) <= 15 * 15) l = 5;
        vol.labels[vol.index(i, j, k)] = l;
      }
  return vol;
}

void expectGradation(const Grid3& g, const std::vector<float>& h, double L) {
  size_t violations = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        for (int dk = -1; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
              if (!g.inside(i + di, j + dj, k + dk)) continue;
              const double d = std::sqrt(g.squaredDistance(di, dj, dk));
              if (double(h[g.index(i, j, k)]) >
                  double(h[g.index(i + di, j + dj, k + dk)]) + L * d + 1e-6)
                ++violations;
            }
  EXPECT_EQ(violations, 0u);
}

/// A grid of `dims` voxels of `spacing` mm, and a size field on it drawn uniformly from [lo, hi)
/// with `seed`.
std::vector<float> randomSizes(Grid3& g, std::array<int, 3> dims, std::array<double, 3> spacing,
                               unsigned seed, float lo, float hi) {
  g.dims = dims;
  g.spacing = spacing;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<float> h(g.size());
  for (auto& x : h) x = u(rng);
  return h;
}

}  // namespace

TEST(SizingField, LocalFeatureSizeIsDistanceToMedialVoxels) {
  Grid3 g;
  g.dims = {{12, 9, 7}};
  g.spacing = {{0.7, 0.36, 0.36}};
  std::vector<uint8_t> mask(g.size(), 0);
  mask[g.index(2, 3, 1)] = mask[g.index(9, 7, 5)] = 1;
  const auto lfs = localFeatureSize(g, mask, 2);
  for (size_t v = 0; v < g.size(); ++v) {
    const double ref = std::sqrt(
        std::min(g.squaredDistance(v, g.index(2, 3, 1)), g.squaredDistance(v, g.index(9, 7, 5))));
    ASSERT_NEAR(lfs[v], ref, 1e-5);
  }
  const auto none = localFeatureSize(g, std::vector<uint8_t>(g.size(), 0));
  EXPECT_TRUE(std::isinf(none[0]));
}

TEST(SizingField, GradationLimitIsExactAndOnlyLowers) {
  Grid3 g;
  std::vector<float> h = randomSizes(g, {{17, 13, 11}}, {{0.7, 0.36, 0.5}}, 3, 0.2f, 9.f);
  const auto before = h;
  limitGradation(g, h, 0.3);
  expectGradation(g, h, 0.3);
  for (size_t v = 0; v < h.size(); ++v) ASSERT_LE(h[v], before[v]);
  // A single small seed grows by L per mm along 26-neighbour paths.
  std::vector<float> one(g.size(), 100.f);
  one[g.index(0, 0, 0)] = 1.f;
  limitGradation(g, one, 0.5);
  EXPECT_NEAR(one[g.index(10, 0, 0)], 1.0 + 0.5 * 7.0, 1e-5);
  expectGradation(g, one, 0.5);
}

TEST(SizingField, ThinPlateSmallBigBallLarge) {
  const LabelVolume vol = plateAndBall();
  RunContext ctx;
  SizingParameters p;
  p.scale = 0.5;
  p.hMin = 0.5;
  p.hMax = 8.0;
  const SizingField f = computeSizingField(vol, p, ctx);
  EXPECT_DOUBLE_EQ(f.hMin, 0.5);
  EXPECT_DOUBLE_EQ(f.hMax, 8.0);
  ASSERT_EQ(f.h.size(), vol.voxelCount());
  for (float x : f.h) {
    ASSERT_GE(x, float(f.hMin) * (1 - 1e-6f));
    ASSERT_LE(x, float(f.hMax) * (1 + 1e-6f));
  }
  expectGradation(f.grid, f.h, p.gradation);
  // Thin plate: its mid-sheet is medial, lfs = 0.5 mm on its faces -> h = hMin there.
  EXPECT_NEAR(f.h[vol.index(5, 20, 20)], f.hMin, 1e-6);
  EXPECT_NEAR(f.h[vol.index(7, 20, 20)], f.hMin, 1e-6);
  EXPECT_LE(f.h[vol.index(6, 20, 20)], f.hMin + p.gradation * 0.5 + 1e-6);
  // Ball of radius 7.5 mm: surface h = scale x lfs, where lfs is bounded by the ball's own axis
  // (its centre, 7.5 mm away) and by the background's axis in the gaps around it (~2.5 mm); the
  // interior grows away from the surface.
  const float surface = f.h[vol.index(32 - 15, 20, 20)];
  const float centre = f.h[vol.index(32, 20, 20)];
  EXPECT_GT(surface, 0.9f);
  EXPECT_LT(surface, 0.5f * 7.5f + 0.5f);
  EXPECT_GT(centre, surface + 0.3 * p.gradation * 7.5);
  EXPECT_GT(centre, 5 * f.hMin);
  // Trilinear lookup reproduces grid values at voxel centres.
  EXPECT_FLOAT_EQ(f.at({32 * 0.5, 20 * 0.5, 20 * 0.5}), centre);
  EXPECT_GT(f.medialVoxels, 0u);
  EXPECT_GT(f.interfaceVoxels, 0u);
}

TEST(SizingField, TrilinearAt) {
  SizingField f;
  f.grid.dims = {{4, 3, 2}};
  f.grid.spacing = {{2.0, 1.0, 0.5}};
  f.h.resize(f.grid.size());
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i) f.h[f.grid.index(i, j, k)] = float(1 + i + 2 * j + 3 * k);
  // Linear in the index: trilinear interpolation is exact.
  EXPECT_NEAR(f.at({3.0, 1.5, 0.25}), 1 + 1.5 + 3.0 + 1.5, 1e-5);
  EXPECT_NEAR(f.at({-5, -5, -5}), 1.f, 1e-6);        // clamped
  EXPECT_NEAR(f.at({100, 100, 100}), 1 + 3 + 4 + 3, 1e-5);
}

TEST(SizingField, BadParametersAndCancel) {
  const LabelVolume vol = plateAndBall();
  RunContext ctx;
  SizingParameters p;
  p.scale = 0;
  expectError(ErrorCode::InvalidArgument, [&] { computeSizingField(vol, p, ctx); });
  p = SizingParameters{};
  p.hMin = 5;
  p.hMax = 2;
  expectError(ErrorCode::InvalidArgument, [&] { computeSizingField(vol, p, ctx); });
  p = SizingParameters{};
  p.gradation = -1;
  expectError(ErrorCode::InvalidArgument, [&] { computeSizingField(vol, p, ctx); });
  LabelVolume empty;
  expectError(ErrorCode::InvalidArgument, [&] { computeSizingField(empty, SizingParameters{}, ctx); });
  RunContext canceled;
  canceled.cancel();
  expectError(ErrorCode::Canceled, [&] { computeSizingField(vol, SizingParameters{}, canceled); });
}

TEST(SizingField, OnlyBackgroundGivesHMax) {
  LabelVolume vol;
  vol.dims = {{6, 5, 4}};
  vol.labels.assign(vol.voxelCount(), 0);
  RunContext ctx;
  const SizingField f = computeSizingField(vol, SizingParameters{}, ctx);
  // auto hMax = 2.5 x the uniform edge length = 2.5 x edge_length_factor (3) x mean spacing (1)
  for (float x : f.h) EXPECT_FLOAT_EQ(x, 7.5f);
}

TEST(SizingField, AutomaticBoundsFollowTheUniformEdgeLength) {
  const LabelVolume vol = plateAndBall();
  RunContext ctx;
  SizingParameters p;
  p.targetEdgeLength = 1.2;
  double hMin = 0, hMax = 0;
  resolveSizingBounds(p, vol, hMin, hMax);
  EXPECT_DOUBLE_EQ(hMin, 0.6);
  EXPECT_DOUBLE_EQ(hMax, 3.0);
  p.targetEdgeLength = 0;  // automatic: 3 x mean spacing (0.5 mm), the labelled box is larger
  EXPECT_DOUBLE_EQ(uniformEdgeLength(vol, p), 1.5);
  p.hMin = 5;  // above the automatic hMax: lowered to it
  resolveSizingBounds(p, vol, hMin, hMax);
  EXPECT_DOUBLE_EQ(hMin, hMax);
  const SizingField f = computeSizingField(vol, p, ctx);
  EXPECT_DOUBLE_EQ(f.hMin, f.hMax);
}

namespace {

/// The sizing field of a run on `vol` (the working grid, as MeshingRun computes it) with or
/// without the curvature term (`curvatureDistance` in voxels).
SizingField runSizing(const LabelVolume& vol, double curvatureDistance, PreprocessedVolume& pv) {
  RunContext ctx;
  pv = preprocessLabels(vol, {}, ctx);
  const IndicatorField field = computeIndicatorFunctions(pv, {}, ctx);
  LabelVolume work;
  work.dims = pv.dims;
  work.spacing = pv.spacing;
  work.labels.assign(pv.labels.begin(), pv.labels.end());
  SizingParameters p;
  p.scale = 5;
  p.hMin = 0.5;
  p.hMax = 20;
  p.curvatureDistance = curvatureDistance;
  const LabelMedialAxes axes = computeAllMedialAxes(work, medialAxisParameters(p), ctx);
  return computeSizingField(work, axes, p, ctx, &field);
}

/// h at the voxels of label `inside` (compact) with a 6-neighbour of another label, away from
/// the working grid's border by `margin` voxels.
std::vector<double> interfaceSizes(const SizingField& f, const PreprocessedVolume& pv, int margin) {
  std::vector<double> out;
  const auto& d = pv.dims;
  for (int k = margin; k < d[2] - margin; ++k)
    for (int j = margin; j < d[1] - margin; ++j)
      for (int i = margin; i < d[0] - margin; ++i) {
        const auto l = pv.labels[pv.index(i, j, k)];
        if (l == 0) continue;
        bool iface = false;
        static const int n6[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& o : n6) iface |= pv.labels[pv.index(i + o[0], j + o[1], k + o[2])] != l;
        if (iface) out.push_back(f.h[pv.index(i, j, k)]);
      }
  return out;
}

double medianOf(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

// Curvature term: on a ball of radius R a triangle of edge h has its centroid h^2 / (6R) off the
// sphere, so with the term on, the surface size is sqrt(6 d R) where the local feature size alone
// would allow far more; on a flat interface it changes nothing.
TEST(SizingField, CurvatureTermSizesABallBySqrtSixDRAndLeavesAPlaneAlone) {
  const double R = 12, d = 0.25;  // mm (1 mm voxels), voxels
  LabelVolume ball;
  ball.dims = {{56, 56, 56}};
  ball.spacing = {{1, 1, 1}};
  ball.labels.assign(ball.voxelCount(), 0);
  for (int k = 0; k < 56; ++k)
    for (int j = 0; j < 56; ++j)
      for (int i = 0; i < 56; ++i) {
        const double x = i - 27.5, y = j - 27.5, z = k - 27.5;
        if (x * x + y * y + z * z <= R * R) ball.labels[ball.index(i, j, k)] = 1;
      }
  PreprocessedVolume pv;
  const double plain = medianOf(interfaceSizes(runSizing(ball, 0, pv), pv, 1));
  const double curved = medianOf(interfaceSizes(runSizing(ball, d, pv), pv, 1));
  const double finer = medianOf(interfaceSizes(runSizing(ball, d / 4, pv), pv, 1));
  const double expected = std::sqrt(6 * d * R);  // 4.24 mm
  EXPECT_GT(plain, 1.3 * expected) << "the local feature size alone allows much more on this ball";
  // The voxel bumps of the smooth interface add some curvature and the gradation limit lowers
  // the sizes next to smaller ones (without it the median is 0.85 x expected).
  EXPECT_GT(curved, 0.65 * expected);
  EXPECT_LT(curved, 1.1 * expected);
  // A quarter of the distance, half the size.
  EXPECT_GT(curved / finer, 1.7);
  EXPECT_LT(curved / finer, 2.3);

  // Two half-spaces meeting on the plane z = 20: flat, so the term leaves every size alone.
  LabelVolume slab;
  slab.dims = {{40, 40, 40}};
  slab.spacing = {{1, 1, 1}};
  slab.labels.assign(slab.voxelCount(), 1);
  for (size_t v = 0; v < slab.labels.size(); ++v)
    if (v / (40 * 40) >= 20) slab.labels[v] = 2;
  const std::vector<double> flat0 = interfaceSizes(runSizing(slab, 0, pv), pv, 1);
  const std::vector<double> flat1 = interfaceSizes(runSizing(slab, d, pv), pv, 1);
  ASSERT_EQ(flat0.size(), flat1.size());
  ASSERT_FALSE(flat0.empty());
  for (size_t q = 0; q < flat0.size(); ++q) EXPECT_NEAR(flat1[q], flat0[q], 1e-6 * flat0[q]) << q;
}

// The gradation sweeps run their wavefronts of rows in parallel: the same floats on any number of
// threads (a grid large enough that the rows are split).
TEST(SizingField, GradationLimitIsTheSameOnAnyNumberOfThreads) {
  Grid3 g;
  const std::vector<float> start = randomSizes(g, {{23, 61, 47}}, {{0.7, 0.36, 0.5}}, 7, 0.2f, 9.f);
  std::vector<float> reference;
  for (int threads : {1, 2, 3, 8}) {
    RunContext ctx;
    ctx.setThreads(threads);
    std::vector<float> h = start;
    limitGradation(g, h, 0.3, &ctx);
    if (reference.empty()) {
      reference = h;
      expectGradation(g, h, 0.3);
    } else {
      ASSERT_EQ(h, reference) << threads << " threads";
    }
  }
}

// The tiled wavefronts give exactly the plain sequential chamfer sweeps: forward in raster
// order, backward in reverse, repeated until nothing changes (written out here, one voxel at a
// time, as a reference). The grid spans several tiles of rows, partial ones too.
TEST(SizingField, GradationLimitMatchesThePlainSequentialSweeps) {
  Grid3 g;
  const std::vector<float> start =
      randomSizes(g, {{7, 150, 70}}, {{0.5, 0.4, 0.9}}, 11, 0.1f, 12.f);
  const double L = 0.25;
  std::vector<float> ref = start;
  const int nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
  int refSweeps = 0;
  for (bool changed = true; changed;) {
    changed = false;
    refSweeps += 2;
    for (int sign : {1, -1})
      for (int kk = 0; kk < nz; ++kk)
        for (int jj = 0; jj < ny; ++jj)
          for (int ii = 0; ii < nx; ++ii) {
            const int i = sign > 0 ? ii : nx - 1 - ii, j = sign > 0 ? jj : ny - 1 - jj,
                      k = sign > 0 ? kk : nz - 1 - kk;
            double hv = ref[g.index(i, j, k)];
            bool lowered = false;
            for (int dk = -1; dk <= 0; ++dk)
              for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                  if (!(dk < 0 || (dk == 0 && (dj < 0 || (dj == 0 && di < 0))))) continue;
                  const int ni = i + sign * di, nj = j + sign * dj, nk = k + sign * dk;
                  if (ni < 0 || nj < 0 || nk < 0 || ni >= nx || nj >= ny || nk >= nz) continue;
                  const double cand = double(ref[g.index(ni, nj, nk)]) +
                                      L * std::sqrt(g.squaredDistance(di, dj, dk));
                  if (cand < hv) {
                    hv = cand;
                    lowered = true;
                  }
                }
            if (!lowered) continue;
            float f = float(hv);
            if (double(f) > hv) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
            ref[g.index(i, j, k)] = f;
            changed = true;
          }
  }
  for (int threads : {1, 2, 4}) {
    RunContext ctx;
    ctx.setThreads(threads);
    std::vector<float> h = start;
    // The same number of sweeps too: a row reading a neighbour row before the sequential order
    // has finished it would still converge to the same field, only later.
    EXPECT_EQ(limitGradation(g, h, L, &ctx), refSweeps) << threads << " threads";
    ASSERT_EQ(h, ref) << threads << " threads";
  }
}
