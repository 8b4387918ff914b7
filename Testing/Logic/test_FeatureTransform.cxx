// SPDX-License-Identifier: GPL-3.0-or-later
// Exact Euclidean feature transform: squared distances equal a brute-force nearest-feature search.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/FeatureTransform.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

using namespace femesher;

namespace {

std::vector<uint8_t> randomMask(const Grid3& g, double density, uint32_t seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution pick(density);
  std::vector<uint8_t> m(g.size());
  for (auto& b : m) b = pick(rng) ? 1 : 0;
  return m;
}

std::vector<double> bruteForce(const Grid3& g, const std::vector<uint8_t>& feature) {
  std::vector<size_t> feats;
  for (size_t v = 0; v < feature.size(); ++v)
    if (feature[v]) feats.push_back(v);
  std::vector<double> d(g.size(), std::numeric_limits<double>::infinity());
  for (size_t v = 0; v < g.size(); ++v)
    for (size_t f : feats) d[v] = std::min(d[v], g.squaredDistance(v, f));
  return d;
}

/// Number of voxels whose FT distance differs from brute force (by more than `relTol`).
size_t mismatches(const Grid3& g, const std::vector<uint8_t>& feature, double relTol) {
  const auto ft = featureTransform(g, feature, 2);
  const auto ref = bruteForce(g, feature);
  size_t bad = 0;
  for (size_t v = 0; v < g.size(); ++v) {
    if (ft[v] != kNoFeature && !feature[ft[v]]) {
      ++bad;  // must point at a feature
      continue;
    }
    const double d = featureSquaredDistance(g, v, ft[v]);
    if (relTol == 0 ? d != ref[v] : std::abs(d - ref[v]) > relTol * ref[v]) ++bad;
  }
  return bad;
}

Grid3 grid(int nx, int ny, int nz, double sx = 1, double sy = 1, double sz = 1) {
  Grid3 g;
  g.dims = {{nx, ny, nz}};
  g.spacing = {{sx, sy, sz}};
  return g;
}

}  // namespace

TEST(FeatureTransform, EqualsBruteForceIsotropic) {
  uint32_t seed = 1;
  for (const auto& g : {grid(13, 7, 9), grid(16, 16, 16), grid(1, 20, 15), grid(10, 1, 1),
                        grid(1, 1, 1), grid(5, 6, 1), grid(1, 1, 17)})
    for (double density : {0.003, 0.05, 0.4, 0.95}) {
      const auto m = randomMask(g, density, seed++);
      EXPECT_EQ(mismatches(g, m, 0.0), 0u)
          << g.dims[0] << "x" << g.dims[1] << "x" << g.dims[2] << " density " << density;
    }
}

TEST(FeatureTransform, EqualsBruteForceAnisotropicDyadic) {
  // Squares of these spacings are exact binary fractions: bit-for-bit equality.
  uint32_t seed = 100;
  for (const auto& g : {grid(13, 7, 9, 0.5, 1.25, 0.75), grid(9, 14, 11, 2.0, 0.5, 0.5),
                        grid(1, 12, 9, 0.75, 0.5, 1.5), grid(20, 3, 1, 0.25, 1.0, 1.0)})
    for (double density : {0.005, 0.05, 0.4, 0.9}) {
      const auto m = randomMask(g, density, seed++);
      EXPECT_EQ(mismatches(g, m, 0.0), 0u)
          << g.dims[0] << "x" << g.dims[1] << "x" << g.dims[2] << " density " << density;
    }
}

TEST(FeatureTransform, EqualsBruteForceAnisotropicCT) {
  // CT-like spacing 0.7/0.36/0.36: equal up to the last bit of a rounded sum (see the header).
  uint32_t seed = 200;
  size_t exactMismatch = 0, total = 0;
  for (const auto& g : {grid(12, 15, 14, 0.7, 0.36, 0.36), grid(17, 9, 6, 0.36, 0.36, 0.7),
                        grid(1, 21, 13, 0.7, 0.36, 0.36)})
    for (double density : {0.005, 0.05, 0.4, 0.9}) {
      const auto m = randomMask(g, density, seed++);
      EXPECT_EQ(mismatches(g, m, 1e-14), 0u)
          << g.dims[0] << "x" << g.dims[1] << "x" << g.dims[2] << " density " << density;
      exactMismatch += mismatches(g, m, 0.0);
      total += g.size();
    }
  // Last-bit differences need a mathematical tie that rounds differently: rare.
  EXPECT_LE(exactMismatch, total / 1000);
}

TEST(FeatureTransform, NoFeatureAndAllFeatures) {
  const Grid3 g = grid(7, 5, 3, 0.7, 0.36, 0.36);
  const auto none = featureTransform(g, std::vector<uint8_t>(g.size(), 0));
  for (uint32_t f : none) EXPECT_EQ(f, kNoFeature);
  const auto d = featureSquaredDistances(g, none);
  for (double x : d) EXPECT_TRUE(std::isinf(x));
  const auto all = featureTransform(g, std::vector<uint8_t>(g.size(), 1));
  for (size_t v = 0; v < g.size(); ++v) EXPECT_EQ(all[v], v);
  EXPECT_TRUE(featureTransform(grid(0, 0, 0), {}).empty());
}

TEST(FeatureTransform, SingleFeatureGivesExactDistanceEverywhere) {
  const Grid3 g = grid(11, 8, 6, 0.7, 0.36, 0.5);
  std::vector<uint8_t> m(g.size(), 0);
  const size_t f = g.index(3, 5, 2);
  m[f] = 1;
  const auto ft = featureTransform(g, m);
  for (size_t v = 0; v < g.size(); ++v) ASSERT_EQ(ft[v], f);
  const auto dist = featureDistances(g, ft);
  EXPECT_NEAR(dist[g.index(0, 0, 0)], std::sqrt(9 * 0.49 + 25 * 0.36 * 0.36 + 4 * 0.25), 1e-6);
}

TEST(FeatureTransform, IndependentOfThreadCount) {
  const Grid3 g = grid(23, 19, 17, 0.7, 0.36, 0.36);
  const auto m = randomMask(g, 0.02, 7);
  EXPECT_EQ(featureTransform(g, m, 1), featureTransform(g, m, 3));
}

TEST(FeatureTransform, BadInputAndCancel) {
  const Grid3 g = grid(4, 4, 4);
  EXPECT_THROW(featureTransform(g, std::vector<uint8_t>(5, 0)), Error);
  RunContext ctx;
  ctx.cancel();
  try {
    featureTransform(g, std::vector<uint8_t>(g.size(), 0), 1, &ctx);
    FAIL() << "expected Canceled";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Canceled);
  }
}
