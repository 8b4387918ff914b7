// SPDX-License-Identifier: GPL-3.0-or-later
// Stage 2 (IndicatorFunctions) on its own: sign at every voxel centre, the unsmoothed field as a
// clamped signed distance, ties on the interface, what smoothing changes, the exact volume box,
// the volume-preserving correction, thread independence and cancel.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "MeshInvariants.h"
#include "TestShapes.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

/// The construction with `sigma` and, unless asked, without the volume-preserving correction.
IndicatorParameters withSigma(double sigma, int volumeIterations = 0) {
  IndicatorParameters p;
  p.sigma = sigma;
  p.band = 4;
  p.volumeIterations = volumeIterations;
  return p;
}

/// ballsInShell(n) with the given spacing, preprocessed (default parameters).
PreprocessedVolume preprocessedBalls(int n, const Vec3& spacing) {
  LabelVolume v = test::ballsInShell(n);
  v.spacing = spacing;
  RunContext ctx;
  return preprocessLabels(v, {}, ctx);
}

IndicatorField indicators(const PreprocessedVolume& pv, double sigma, int threads = 0,
                          int volumeIterations = 0) {
  RunContext ctx;
  ctx.setThreads(threads);
  return computeIndicatorFunctions(pv, withSigma(sigma, volumeIterations), ctx);
}

bool insideInputBox(const PreprocessedVolume& pv, int i, int j, int k) {
  const int q[3] = {i + pv.offset[0], j + pv.offset[1], k + pv.offset[2]};
  for (int a = 0; a < 3; ++a)
    if (q[a] < 0 || q[a] >= pv.inputDims[a]) return false;
  return true;
}

/// Calls fn(i, j, k) for every voxel centre of the working grid that lies in the input's box.
template <class Fn>
void forEachInputVoxel(const PreprocessedVolume& pv, Fn&& fn) {
  for (int k = 0; k < pv.dims[2]; ++k)
    for (int j = 0; j < pv.dims[1]; ++j)
      for (int i = 0; i < pv.dims[0]; ++i)
        if (insideInputBox(pv, i, j, k)) fn(i, j, k);
}

/// Volume (mm^3) of the region where label m wins (IndicatorField::argmax), sampled on a
/// 4 x 4 x 4 sub-grid of every voxel of the input's box.
std::vector<double> argmaxVolumes(const IndicatorField& f) {
  const PreprocessedVolume& pv = f.volume();
  std::vector<double> vol(size_t(f.labelCount()), 0.0);
  const double w = pv.spacing[0] * pv.spacing[1] * pv.spacing[2] / 64;
  forEachInputVoxel(pv, [&](int i, int j, int k) {
    for (int c = 0; c < 4; ++c)
      for (int b = 0; b < 4; ++b)
        for (int a = 0; a < 4; ++a)
          vol[size_t(f.argmax({i + (a - 1.5) / 4, j + (b - 1.5) / 4, k + (c - 1.5) / 4}))] += w;
  });
  return vol;
}

/// Sum over the voxel centres of every label's squared discrete Laplacian of f_m (per mm^2),
/// where all seven samples are inside the band of [-limit, limit] mm: how rough the field is.
double roughness(const IndicatorField& f, double limit) {
  const PreprocessedVolume& pv = f.volume();
  double sum = 0;
  for (int m = 0; m < f.labelCount(); ++m)
    for (int k = 1; k + 1 < pv.dims[2]; ++k)
      for (int j = 1; j + 1 < pv.dims[1]; ++j)
        for (int i = 1; i + 1 < pv.dims[0]; ++i) {
          const double c = f.value(m, i, j, k);
          double lap = 0;
          bool inBand = std::fabs(c) < limit;
          for (int a = 0; a < 3; ++a)
            for (int s : {-1, 1}) {
              int q[3] = {i, j, k};
              q[a] += s;
              const double n = f.value(m, q[0], q[1], q[2]);
              inBand &= std::fabs(n) < limit;
              lap += (n - c) / (pv.spacing[size_t(a)] * pv.spacing[size_t(a)]);
            }
          if (inBand) sum += lap * lap;
        }
  return sum;
}

}  // namespace

TEST(IndicatorFunctions, SignMatchesLabelsAtEveryVoxelCentre) {
  LabelVolume v = test::ballsInShell(24);
  v.spacing = {0.7, 0.4, 0.4};
  RunContext ctx;
  const PreprocessedVolume pv = preprocessLabels(v, {}, ctx);
  const IndicatorField f = computeIndicatorFunctions(pv, {}, ctx);
  size_t wrong = 0;
  for (int k = 0; k < pv.dims[2]; ++k)
    for (int j = 0; j < pv.dims[1]; ++j)
      for (int i = 0; i < pv.dims[0]; ++i) {
        const int l = pv.at(i, j, k);
        if (f.argmax({double(i), double(j), double(k)}) != l) ++wrong;
        if (!(f.value(l, i, j, k) > 0)) ++wrong;
      }
  EXPECT_EQ(wrong, 0u);
  // The interface between two face-neighbours of different labels lies between their centres.
  for (int i = 1; i < pv.dims[0] - 1; ++i) {
    const int j = pv.dims[1] / 2, k = pv.dims[2] / 2;
    const int a = pv.at(i, j, k), b = pv.at(i + 1, j, k);
    if (a == b) continue;
    const double ga = f.value(a, i, j, k) - f.value(b, i, j, k);
    const double gb = f.value(a, i + 1, j, k) - f.value(b, i + 1, j, k);
    EXPECT_GT(ga, 0);
    EXPECT_LT(gb, 0);
  }
}

// The input's box is exact: a material cut by the volume's border ends on the flat box face, and
// the box edges are sharp (not rounded by the half-voxel distance to the outer voxel centres).
TEST(IndicatorFunctions, InputBoxIsExactFlatAndSharp) {
  LabelVolume v = test::ballsInShellWithoutBackground(20);  // label 4 fills the box corners
  v.spacing = {0.5, 1.0, 0.8};
  RunContext ctx;
  const PreprocessedVolume pv = preprocessLabels(v, {}, ctx);
  const IndicatorField f = computeIndicatorFunctions(pv, {}, ctx);
  const int m = pv.at(-pv.offset[0], -pv.offset[1], -pv.offset[2]);  // the corner voxel's label
  ASSERT_NE(m, 0);
  auto F = [&](double x, double y, double z) {  // f_m - f_0 at an input index position
    const Vec3 l{x - pv.offset[0], y - pv.offset[1], z - pv.offset[2]};
    return f.eval(m, l) - f.eval(0, l);
  };
  for (double z : {3.0, 7.3}) {
    EXPECT_NEAR(F(-0.5, 4.2, z), 0, 1e-9) << "box face";
    EXPECT_NEAR(F(-0.5, -0.5, z), 0, 1e-9) << "box edge";
    EXPECT_GT(F(-0.45, 4.2, z), 0);
    EXPECT_LT(F(-0.55, 4.2, z), 0);
    EXPECT_GT(F(-0.45, -0.45, z), 0) << "the edge is rounded";
  }
  EXPECT_GT(F(-0.45, -0.45, -0.45), 0) << "the corner is rounded";
  // Snapping: a point 1e-4 mm off the face lands on it; a point 0.1 voxel off stays.
  const Vec3 near{-0.5 - pv.offset[0] + 2e-4, 4.2 - pv.offset[1], 3.0 - pv.offset[2]};
  EXPECT_EQ(f.snapToBox(near, 1e-3)[0], -0.5 - pv.offset[0]);
  const Vec3 far{-0.4 - pv.offset[0], 4.2 - pv.offset[1], 3.0 - pv.offset[2]};
  EXPECT_EQ(f.snapToBox(far, 1e-3), far);
}

// Without smoothing, f_m at a voxel centre is the distance (mm, anisotropic) to the nearest
// voxel centre of the other side, minus half the smallest spacing, with the sign of "inside m";
// values stop at the band (band x largest spacing) and keep 0.35 x smallest spacing from 0.
TEST(IndicatorFunctions, UnsmoothedFieldIsTheClampedSignedDistance) {
  const PreprocessedVolume pv = preprocessedBalls(16, {0.7, 0.4, 0.5});
  const IndicatorField f = indicators(pv, 0);
  const Vec3& s = pv.spacing;
  const double smin = 0.4, bandMm = 4 * 0.7, eps = 0.35 * smin;
  int reach[3];
  for (int a = 0; a < 3; ++a) reach[a] = int(std::ceil(bandMm / s[size_t(a)])) + 1;
  size_t compared = 0, wrong = 0, wrongFar = 0;
  for (int m = 0; m < f.labelCount(); ++m)
    forEachInputVoxel(pv, [&](int i, int j, int k) {
      const bool in = pv.at(i, j, k) == m;
      double d2 = std::numeric_limits<double>::infinity();  // to the nearest centre across
      for (int dk = -reach[2]; dk <= reach[2]; ++dk)
        for (int dj = -reach[1]; dj <= reach[1]; ++dj)
          for (int di = -reach[0]; di <= reach[0]; ++di) {
            const int x = i + di, y = j + dj, z = k + dk;
            if (x < 0 || y < 0 || z < 0 || x >= pv.dims[0] || y >= pv.dims[1] || z >= pv.dims[2])
              continue;
            if ((pv.at(x, y, z) == m) == in) continue;
            d2 =
                std::min(d2, di * di * s[0] * s[0] + dj * dj * s[1] * s[1] + dk * dk * s[2] * s[2]);
          }
      const double d = std::sqrt(d2);
      double want = in ? d - 0.5 * smin : 0.5 * smin - d;
      const double got = f.value(m, i, j, k);
      if (std::fabs(want) < 4 * smin) {  // inside the band on every axis
        want = in ? std::max(want, eps) : std::min(want, -eps);
        ++compared;
        wrong += std::fabs(got - want) > 1e-4;
      } else {
        wrongFar +=
            (in ? got < 4 * smin - 1e-4 : got > -4 * smin + 1e-4) || std::fabs(got) > bandMm + 1e-4;
      }
    });
  EXPECT_GT(compared, 5000u);
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(wrongFar, 0u);
}

// Without smoothing and with equal spacings, the two labels of two face-neighbours tie exactly
// (both 0) halfway between their centres, and every other label is well below.
TEST(IndicatorFunctions, UnsmoothedNeighboursTieHalfwayBetweenTheirCentres) {
  const PreprocessedVolume pv = preprocessedBalls(20, {0.8, 0.8, 0.8});
  const IndicatorField f = indicators(pv, 0);
  size_t faces = 0, notTied = 0, thirdTooHigh = 0;
  forEachInputVoxel(pv, [&](int i, int j, int k) {
    for (int a = 0; a < 3; ++a) {
      int q[3] = {i, j, k};
      ++q[a];
      if (!insideInputBox(pv, q[0], q[1], q[2])) continue;
      const int la = pv.at(i, j, k), lb = pv.at(q[0], q[1], q[2]);
      if (la == lb) continue;
      ++faces;
      Vec3 mid{double(i), double(j), double(k)};
      mid[size_t(a)] += 0.5;
      notTied += f.eval(la, mid) != 0.0 || f.eval(lb, mid) != 0.0;
      for (int m = 0; m < f.labelCount(); ++m)
        if (m != la && m != lb) thirdTooHigh += f.eval(m, mid) > -0.4 * 0.8;
    }
  });
  EXPECT_GT(faces, 2000u);
  EXPECT_EQ(notTied, 0u);
  EXPECT_EQ(thirdTooHigh, 0u);
}

// Smoothing (sigma in voxels) never changes the sign at a voxel centre, which keeps at least
// 0.35 x the smallest spacing from 0. Sigma 0.3 is a light smoothing: its kernel gives a
// neighbour the weight w = 0.0038, so each of the three passes moves a value by at most
// 2 w x (largest jump between neighbours, 2 x 0.9 - 0.6 mm here), 0.028 mm in all; sigma 0.8
// changes more and smooths the staircase much more.
TEST(IndicatorFunctions, SmoothingKeepsTheSignsAndSmoothsWithSigma) {
  const PreprocessedVolume pv = preprocessedBalls(24, {0.6, 0.6, 0.9});
  const IndicatorField f0 = indicators(pv, 0), f3 = indicators(pv, 0.3), f8 = indicators(pv, 0.8);
  const double eps = 0.35 * 0.6;
  double change3 = 0, change8 = 0;
  size_t badSign = 0;
  for (int m = 0; m < f0.labelCount(); ++m)
    forEachInputVoxel(pv, [&](int i, int j, int k) {
      const bool in = pv.at(i, j, k) == m;
      for (const IndicatorField* f : {&f0, &f3, &f8}) {
        const double x = f->value(m, i, j, k);
        badSign += in ? !(x >= eps - 1e-6) : !(x <= -eps + 1e-6);
      }
      const double x0 = f0.value(m, i, j, k);
      change3 = std::max(change3, std::fabs(f3.value(m, i, j, k) - x0));
      change8 = std::max(change8, std::fabs(f8.value(m, i, j, k) - x0));
    });
  EXPECT_EQ(badSign, 0u);
  EXPECT_GT(change3, 1e-3);
  EXPECT_LT(change3, 0.028);
  EXPECT_GT(change8, 3 * change3);
  const double limit = 3 * 0.6;
  const double r0 = roughness(f0, limit), r3 = roughness(f3, limit), r8 = roughness(f8, limit);
  EXPECT_LT(r3, r0);
  EXPECT_LT(r8, 0.6 * r0);  // measured: 0.41
}

// A label whose bounding box is thinner than 4 sigma is smoothed with a quarter of its
// thickness: a one-voxel plate gets sigma 0.25 and a rod two voxels thick 0.5 whatever larger
// sigma is asked for, while the background around them does get the larger sigma.
TEST(IndicatorFunctions, ThinLabelsAreSmoothedLess) {
  for (const auto& [v, thin] :
       {std::pair(test::oneVoxelPlate(24), 0.25), std::pair(test::thinRod(32), 0.5)}) {
    SCOPED_TRACE("sigma " + std::to_string(thin));
    RunContext ctx;
    const PreprocessedVolume pv = preprocessLabels(v, {}, ctx);
    ASSERT_EQ(pv.materialCount(), 1);
    const IndicatorField asked = indicators(pv, 0.8), quarter = indicators(pv, thin);
    size_t materialDiffers = 0, backgroundDiffers = 0, materialCentres = 0, wrongSide = 0;
    for (int k = 0; k < pv.dims[2]; ++k)
      for (int j = 0; j < pv.dims[1]; ++j)
        for (int i = 0; i < pv.dims[0]; ++i) {
          materialDiffers += asked.value(1, i, j, k) != quarter.value(1, i, j, k);
          backgroundDiffers += asked.value(0, i, j, k) != quarter.value(0, i, j, k);
          if (pv.at(i, j, k) != 1) continue;
          ++materialCentres;
          wrongSide += !(asked.value(1, i, j, k) > asked.value(0, i, j, k));
        }
    EXPECT_EQ(materialCentres, pv.voxelCounts[1]);
    EXPECT_GT(materialCentres, 100u);
    EXPECT_EQ(wrongSide, 0u);
    EXPECT_EQ(materialDiffers, 0u);
    EXPECT_GT(backgroundDiffers, 100u);
  }
}

// The smooth surfaces cut voxel corners and edges: a label of a few hundred voxels (here small
// balls in a larger one, anisotropic voxels as in the knee) loses several percent of its volume.
// The volume-preserving correction gives most of it back and keeps every voxel centre's sign.
TEST(IndicatorFunctions, VolumeCorrectionGivesSmallLabelsTheirVolumeBack) {
  LabelVolume v = test::makeVolume({22, 40, 40}, {0.7, 0.36, 0.36}, [](double x, double y, double z) {
    auto ball = [&](double cx, double cy, double cz, double r) {  // r in mm
      const double dx = (x - cx) * 0.7, dy = (y - cy) * 0.36, dz = (z - cz) * 0.36;
      return dx * dx + dy * dy + dz * dz < r * r;
    };
    if (ball(-3, -7, 0, 1.8) || ball(3, 7, 2, 1.5)) return 2;
    return ball(0, 0, 0, 6.5) ? 1 : 0;
  });
  RunContext ctx;
  const PreprocessedVolume pv = preprocessLabels(v, {}, ctx);
  ASSERT_EQ(pv.materialCount(), 2);
  const double voxel = 0.7 * 0.36 * 0.36;
  const double want = double(pv.voxelCounts[2]) * voxel;
  ASSERT_GT(pv.voxelCounts[2], 200u);
  ASSERT_LT(pv.voxelCounts[2], 1000u);
  const IndicatorField raw = indicators(pv, 0.3, 0, 0), corrected = indicators(pv, 0.3, 0, 4);
  const double errRaw = argmaxVolumes(raw)[2] / want - 1;
  const double errCorrected = argmaxVolumes(corrected)[2] / want - 1;
  EXPECT_LT(errRaw, -0.04);  // the loss the correction is for
  EXPECT_LT(std::fabs(errCorrected), 0.5 * std::fabs(errRaw)) << errRaw << " -> " << errCorrected;
  const double big = double(pv.voxelCounts[1]) * voxel;
  EXPECT_LT(std::fabs(argmaxVolumes(corrected)[1] / big - 1), 0.01);
  const double eps = 0.35 * 0.36;
  size_t badSign = 0;
  for (int m = 0; m < corrected.labelCount(); ++m)
    forEachInputVoxel(pv, [&](int i, int j, int k) {
      const double x = corrected.value(m, i, j, k);
      badSign += pv.at(i, j, k) == m ? !(x >= eps - 1e-6) : !(x <= -eps + 1e-6);
    });
  EXPECT_EQ(badSign, 0u);
}

// A flat interface has nothing to give back: two halves filling the box keep exactly the field
// they have without the correction.
TEST(IndicatorFunctions, VolumeCorrectionLeavesFlatInterfacesAlone) {
  LabelVolume v = test::makeVolume({20, 16, 18}, {0.7, 0.4, 0.5},
                                   [](double x, double, double) { return x < 0 ? 1 : 2; });
  RunContext ctx;
  const PreprocessedVolume pv = preprocessLabels(v, {}, ctx);
  const IndicatorField raw = indicators(pv, 0.3, 0, 0), corrected = indicators(pv, 0.3, 0, 4);
  size_t differ = 0, compared = 0;
  for (int m = 0; m < raw.labelCount(); ++m)
    forEachInputVoxel(pv, [&](int i, int j, int k) {
      ++compared;
      differ += raw.value(m, i, j, k) != corrected.value(m, i, j, k);
    });
  EXPECT_GT(compared, 5000u);
  EXPECT_EQ(differ, 0u);
}

TEST(IndicatorFunctions, SameFieldForAnyThreadCount) {
  LabelVolume v = test::nestedThinShells(24);
  v.spacing = {0.7, 0.36, 0.36};
  RunContext ctx;
  const PreprocessedVolume pv = preprocessLabels(v, {}, ctx);
  const IndicatorField a = indicators(pv, 0.3, 1, 4), b = indicators(pv, 0.3, 3, 4);
  ASSERT_EQ(a.labelCount(), 4);
  size_t differ = 0;
  for (int m = 0; m < a.labelCount(); ++m)
    for (int k = 0; k < pv.dims[2]; ++k)
      for (int j = 0; j < pv.dims[1]; ++j)
        for (int i = 0; i < pv.dims[0]; ++i) differ += a.value(m, i, j, k) != b.value(m, i, j, k);
  EXPECT_EQ(differ, 0u);
}

// evalGradient (what the Newton projections onto interfaces use) gives exactly eval's value and
// gradient's vector, bit for bit: inside the grid, across brick borders (cells whose corners lie
// in two or more 8^3 bricks), beyond the material boxes, near and outside the input's box.
TEST(IndicatorFunctions, EvalGradientIsEvalAndGradientExactly) {
  const PreprocessedVolume pv = preprocessedBalls(40, {0.5, 0.6, 0.7});
  const IndicatorField f = indicators(pv, 0.8, 2);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-3.0, pv.dims[0] + 2.0), y(-3.0, pv.dims[1] + 2.0),
      z(-3.0, pv.dims[2] + 2.0), frac(0.0, 1.0);
  std::vector<Vec3> at;
  for (int n = 0; n < 20000; ++n) at.push_back({x(rng), y(rng), z(rng)});
  for (int n = 0; n < 2000; ++n)  // in cells across a brick border (x = 7.something)
    at.push_back({7 + frac(rng), 8 * frac(rng) * pv.dims[1] / 8, 15 + frac(rng)});
  for (int n = 0; n < 2000; ++n)  // on the input's box faces and just beside them
    at.push_back({-0.5 - pv.offset[0] + 1e-4 * (n % 3 - 1), y(rng), z(rng)});
  size_t differ = 0, boxBranch = 0;
  for (const Vec3& l : at)
    for (int m = 0; m < f.labelCount(); ++m) {
      Vec3 g;
      const double v = f.evalGradient(m, l, g);
      const Vec3 ref = f.gradient(m, l);
      differ += !(v == f.eval(m, l) || (std::isnan(v) && std::isnan(f.eval(m, l))));
      differ += g != ref;
      boxBranch += m > 0 && l[0] < -0.5 - pv.offset[0];
    }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(boxBranch, 0u) << "points outside the input's box were tried";
}

TEST(IndicatorFunctions, CancelStopsTheStage) {
  const PreprocessedVolume pv = preprocessedBalls(16, {1, 1, 1});
  RunContext ctx;
  ctx.cancel();
  expectError(ErrorCode::Canceled, [&] { computeIndicatorFunctions(pv, withSigma(0.3), ctx); });
}

TEST(IndicatorFunctions, StoresTheBandNotTheBoxes) {
  // Beyond the band each f_m is one clamped value: its bricks keep one float. ballsInShell(96) at
  // 1 mm, many small shapes: 0.68 of the dense boxes' bytes (the knee 0.40, colin27 0.45).
  const PreprocessedVolume pv = preprocessedBalls(96, {1, 1, 1});
  const IndicatorField f = indicators(pv, 0.3, 2, 4);
  const double share = double(f.storedBytes()) / double(f.denseBytes());
  std::printf("stored %.3f of the dense boxes' bytes\n", share);
  EXPECT_LT(share, 0.75);
  EXPECT_GT(share, 0.0);
}
