// SPDX-License-Identifier: GPL-3.0-or-later
// Morton order of points and the spatial renumbering of a tet mesh (stages/SpatialOrder).
#include <femesher/stages/internal/SpatialOrder.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <vector>

using namespace femesher;

namespace {

double signedVolume(const std::vector<Vec3>& p, const std::array<int32_t, 4>& t) {
  const Vec3 &a = p[size_t(t[0])], &b = p[size_t(t[1])], &c = p[size_t(t[2])], &d = p[size_t(t[3])];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
         u[2] * (v[0] * w[1] - v[1] * w[0]);
}

double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}

/// A 6 x 6 x 6 grid of unit cubes, five tets each (alternating so faces match), shuffled, with a
/// label per tet from its position.
struct ShuffledGrid {
  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> labels;
  ShuffledGrid() {
    const int n = 6;
    auto id = [&](int x, int y, int z) { return int32_t((z * (n + 1) + y) * (n + 1) + x); };
    for (int z = 0; z <= n; ++z)
      for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) points.push_back({double(x), double(y), double(z)});
    for (int z = 0; z < n; ++z)
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
          int32_t c[8];
          for (int k = 0; k < 8; ++k) c[k] = id(x + (k & 1), y + ((k >> 1) & 1), z + (k >> 2));
          const bool even = (x + y + z) % 2 == 0;
          const std::array<std::array<int, 4>, 5> five =
              even ? std::array<std::array<int, 4>, 5>{{{0, 1, 2, 4}, {1, 3, 2, 7}, {1, 4, 5, 7},
                                                        {2, 7, 6, 4}, {1, 2, 4, 7}}}
                   : std::array<std::array<int, 4>, 5>{{{0, 1, 3, 5}, {0, 3, 2, 6}, {0, 5, 4, 6},
                                                        {3, 5, 7, 6}, {0, 3, 5, 6}}};
          for (const auto& f : five) {
            std::array<int32_t, 4> t{c[f[0]], c[f[1]], c[f[2]], c[f[3]]};
            if (signedVolume(points, t) < 0) std::swap(t[2], t[3]);
            tets.push_back(t);
            labels.push_back(1 + (x < n / 2) + 2 * (z < n / 2));
          }
        }
    // Shuffle points (renumbering the tets) and tets.
    std::mt19937 rng(7);
    std::vector<int32_t> perm(points.size());
    for (size_t i = 0; i < perm.size(); ++i) perm[i] = int32_t(i);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<Vec3> shuffled(points.size());
    for (size_t i = 0; i < perm.size(); ++i) shuffled[size_t(perm[i])] = points[i];
    points = shuffled;
    for (auto& t : tets)
      for (auto& v : t) v = perm[size_t(v)];
    std::vector<size_t> order(tets.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    std::vector<std::array<int32_t, 4>> t2;
    std::vector<int32_t> l2;
    for (size_t i : order) t2.push_back(tets[i]), l2.push_back(labels[i]);
    tets = t2;
    labels = l2;
  }
  /// Mean distance between consecutive points of the numbering.
  double meanStep() const {
    double s = 0;
    for (size_t i = 1; i < points.size(); ++i) s += distance(points[i - 1], points[i]);
    return s / double(points.size() - 1);
  }
  /// Every tet as its sorted corner coordinates, with its label.
  std::multiset<std::pair<std::array<Vec3, 4>, int32_t>> geometry() const {
    std::multiset<std::pair<std::array<Vec3, 4>, int32_t>> g;
    for (size_t t = 0; t < tets.size(); ++t) {
      std::array<Vec3, 4> c;
      for (int k = 0; k < 4; ++k) c[size_t(k)] = points[size_t(tets[t][size_t(k)])];
      std::sort(c.begin(), c.end());
      g.insert({c, labels[t]});
    }
    return g;
  }
};

}  // namespace

TEST(SpatialOrder, MortonOrderIsAPermutationThatKeepsNeighboursClose) {
  ShuffledGrid g;
  const auto order = internal::mortonOrder(g.points, 1.0);
  ASSERT_EQ(order.size(), g.points.size());
  std::vector<uint32_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], i);
  // Consecutive points in Z-order are mostly grid neighbours: far closer than in a shuffle
  // (mean step of a random order on a 7^3 grid is about 3.6).
  double step = 0;
  for (size_t i = 1; i < order.size(); ++i)
    step += distance(g.points[order[i - 1]], g.points[order[i]]);
  step /= double(order.size() - 1);
  EXPECT_GT(g.meanStep(), 3.0);
  EXPECT_LT(step, 1.6);
  // The first point is the grid's lower corner (code 0).
  EXPECT_EQ(g.points[order[0]], (Vec3{0, 0, 0}));
}

TEST(SpatialOrder, RenumberingKeepsEveryTetItsLabelAndItsOrientation) {
  ShuffledGrid g;
  const auto before = g.geometry();
  const double stepBefore = g.meanStep();
  internal::spatiallyRenumber(g.points, g.tets, g.labels);
  EXPECT_EQ(g.geometry(), before);
  for (const auto& t : g.tets) EXPECT_GT(signedVolume(g.points, t), 0);
  EXPECT_LT(g.meanStep(), 0.5 * stepBefore);
  // Tets follow their centroids' order: consecutive tets are near each other.
  double tetStep = 0;
  for (size_t t = 1; t < g.tets.size(); ++t)
    tetStep += distance(g.points[size_t(g.tets[t - 1][0])], g.points[size_t(g.tets[t][0])]);
  tetStep /= double(g.tets.size() - 1);
  EXPECT_LT(tetStep, 2.0);
}
