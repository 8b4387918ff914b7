// SPDX-License-Identifier: GPL-3.0-or-later
// The labelled Delaunay triangulation (LabelledDelaunay.h): labels, adjacency, the interface
// triangles and their orientation, enclosed cavities, repair points and forced labels.
#include <femesher/stages/LabelledDelaunay.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <vector>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

/// The particles of `r` in the canonical frame.
std::vector<Vec3> canonicalPoints(const StageRun& r) {
  std::vector<Vec3> c;
  for (const Vec3& l : r.points) c.push_back(r.vol.localToCanonical(l));
  return c;
}

/// A labelled triangulation of r's particles.
std::unique_ptr<LabelledDelaunay> labelled(const StageRun& r, int threads = 0) {
  auto ld = std::make_unique<LabelledDelaunay>(r.vol.materialCount());
  ld->insert(canonicalPoints(r));
  RunContext ctx;
  ctx.setThreads(threads);
  ld->label(*r.field, ctx);
  return ld;
}

}  // namespace

TEST(LabelledDelaunay, TetsCarryTheMaterialAroundThem) {
  const StageRun r = runStages(twoSpheres());
  const auto ld = labelled(r);
  EXPECT_EQ(ld->vertexCount(), r.points.size());
  const std::vector<size_t> perLabel = ld->tetsPerLabel();
  ASSERT_EQ(perLabel.size(), 3u);
  EXPECT_EQ(std::accumulate(perLabel.begin(), perLabel.end(), size_t(0)), ld->tetCount());
  EXPECT_GT(perLabel[1], 0u);
  EXPECT_GT(perLabel[2], 0u);
  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 4>> tets;
  std::vector<int32_t> labels;
  ld->exportTets(points, tets, labels);
  EXPECT_EQ(tets.size(), perLabel[1] + perLabel[2]);
  EXPECT_EQ(std::count(labels.begin(), labels.end(), 0), 0);
  // Voxel centres well inside a material (its indicator >= 1.5 mm, i.e. 1.5 voxels from every
  // other material) lie in a tet of that material.
  size_t inside = 0, wrong = 0;
  for (int k = 0; k < r.vol.dims[2]; ++k)
    for (int j = 0; j < r.vol.dims[1]; ++j)
      for (int i = 0; i < r.vol.dims[0]; ++i) {
        const int l = r.vol.at(i, j, k);
        if (l == 0 || r.field->value(l, i, j, k) < 1.5f) continue;
        ++inside;
        wrong += ld->labelAt(r.vol.localToCanonical({double(i), double(j), double(k)})) != l;
      }
  EXPECT_GT(inside, 1000u);
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(ld->labelAt({-100, -100, -100}), 0) << "outside the hull";
}

TEST(LabelledDelaunay, InterfaceTrianglesAreSortedAndOrientedFromFirstIntoSecond) {
  const StageRun r = runStages(threeSlabs());
  const auto ld = labelled(r);
  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 3>> tris;
  std::vector<std::pair<uint16_t, uint16_t>> pairs;
  ld->interfaceTriangles(points, tris, pairs);
  ASSERT_GT(tris.size(), 100u);
  EXPECT_TRUE(std::is_sorted(points.begin(), points.end()));
  EXPECT_EQ(std::adjacent_find(points.begin(), points.end()), points.end());
  size_t unordered = 0, wrongSide = 0;
  for (size_t t = 0; t < tris.size(); ++t) {
    EXPECT_LT(pairs[t].first, pairs[t].second);
    if (t > 0) {
      std::array<int32_t, 3> s0 = tris[t - 1], s1 = tris[t];
      std::sort(s0.begin(), s0.end());
      std::sort(s1.begin(), s1.end());
      unordered += std::make_pair(pairs[t], s1) < std::make_pair(pairs[t - 1], s0);
    }
    // Just off the centroid along the normal: the tets on either side.
    const Vec3 &a = points[size_t(tris[t][0])], &b = points[size_t(tris[t][1])],
               &c = points[size_t(tris[t][2])];
    const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const Vec3 n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const double eps = 1e-4 * std::sqrt(nl);
    Vec3 in, out;
    for (int k = 0; k < 3; ++k) {
      const double g = (a[k] + b[k] + c[k]) / 3;
      in[k] = g - eps * n[k] / nl;
      out[k] = g + eps * n[k] / nl;
    }
    wrongSide += ld->labelAt(in) != pairs[t].first || ld->labelAt(out) != pairs[t].second;
  }
  EXPECT_EQ(unordered, 0u);
  // A triangle next to a flat tet may miss it by the offset; a wrong orientation would fail half.
  EXPECT_LE(wrongSide, tris.size() / 100) << "of " << tris.size();
  EXPECT_EQ(countOpenEdges(tris, pairs), 0u);
}

TEST(LabelledDelaunay, AdjacencyJoinsInputPointsOnly) {
  // A cube's corners and its centre: the centre is joined to all eight corners.
  std::vector<Vec3> pts;
  for (int c = 0; c < 8; ++c) pts.push_back({double(c & 1), double((c >> 1) & 1), double(c >> 2)});
  pts.push_back({0.5, 0.5, 0.5});
  LabelledDelaunay ld(1);
  ld.insert(pts);
  ld.insertRepairPoints({{0.5, 0.5, 2}, {0.5, 0.5, 0.5}});  // one new vertex, one already there
  EXPECT_EQ(ld.vertexCount(), 10u);
  std::vector<uint32_t> off, nb;
  ld.adjacency(100, off, nb);
  ASSERT_EQ(off.size(), 101u);
  EXPECT_EQ(off[8 + 1] - off[8], 8u);
  std::set<uint32_t> centre(nb.begin() + off[8], nb.begin() + off[9]);
  EXPECT_EQ(centre, (std::set<uint32_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  for (uint32_t x : nb) EXPECT_LT(x, 9u) << "a repair point in the adjacency";
  EXPECT_EQ(off[100], off[9]) << "indices without a point have no neighbours";
  // Symmetric.
  for (uint32_t i = 0; i < 9; ++i)
    for (uint32_t k = off[i]; k < off[i + 1]; ++k) {
      const uint32_t j = nb[k];
      EXPECT_NE(std::find(nb.begin() + off[j], nb.begin() + off[j + 1], i),
                nb.begin() + off[j + 1]);
    }
  // A smaller n keeps the points below it only.
  ld.adjacency(8, off, nb);
  for (uint32_t x : nb) EXPECT_LT(x, 8u);
}

TEST(LabelledDelaunay, ForcedLabelsAndLabelsAtPoints) {
  const StageRun r = runStages(twoSpheres());
  auto ld = labelled(r);
  EXPECT_FALSE(ld->forceLabelAt({-100, -100, -100}, 2));
  const Vec3 centre1{10.5, 17.5, 17.5};  // ball 1's centre (canonical = input index here)
  ASSERT_EQ(ld->labelAt(centre1), 1);
  const size_t twos = ld->tetsPerLabel()[2];
  EXPECT_TRUE(ld->forceLabelAt(centre1, 2));
  EXPECT_EQ(ld->labelAt(centre1), 2);
  EXPECT_EQ(ld->tetsPerLabel()[2], twos + 1);
}

TEST(LabelledDelaunay, EnclosedCavitiesGetHolePoints) {
  // A ball (1) inside a shell (2), and a shell (3) with an empty core, side by side.
  const LabelVolume v = makeVolume(40, [](double x, double y, double z) {
    const double r1 = std::sqrt((x + 9) * (x + 9) + y * y + z * z);
    const double r2 = std::sqrt((x - 9) * (x - 9) + y * y + z * z);
    if (r1 < 4.5) return 1;
    if (r1 < 8.5) return 2;
    if (r2 < 8.5 && r2 >= 4.5) return 3;
    return 0;
  });
  const StageRun r = runStages(v, 1.5, [](const Vec3&) { return 1.5; });
  const auto ld = labelled(r);
  const std::vector<std::vector<Vec3>> holes = ld->enclosedHolePoints();
  ASSERT_EQ(holes.size(), 4u);
  EXPECT_TRUE(holes[0].empty());
  EXPECT_TRUE(holes[1].empty()) << "the inner ball encloses nothing";
  // Every hole point is inside a region that is not the label's (the ball, the empty core, or a
  // pocket of flat tets labelled otherwise inside the shells).
  for (int m = 0; m < 4; ++m)
    for (const Vec3& h : holes[size_t(m)]) EXPECT_NE(ld->labelAt(h), m) << "label " << m;
  // The shell (2) encloses the ball; the hollow shell (3) its empty core (centre (28.5, 19.5,
  // 19.5) mm, radius 4.5).
  EXPECT_TRUE(std::any_of(holes[2].begin(), holes[2].end(),
                          [&](const Vec3& h) { return ld->labelAt(h) == 1; }));
  EXPECT_TRUE(std::any_of(holes[3].begin(), holes[3].end(), [&](const Vec3& h) {
    const double dx = h[0] - 28.5, dy = h[1] - 19.5, dz = h[2] - 19.5;
    return ld->labelAt(h) == 0 && dx * dx + dy * dy + dz * dz < 4.5 * 4.5;
  }));
  // The labels are back after the search.
  const auto again = labelled(r);
  EXPECT_EQ(ld->tetsPerLabel(), again->tetsPerLabel());
}

TEST(LabelledDelaunay, SameTrianglesForAnyThreadCount) {
  const StageRun r = runStages(fourAtAPoint());
  const auto a = labelled(r, 1), b = labelled(r, 3);
  std::vector<Vec3> pa, pb;
  std::vector<std::array<int32_t, 3>> ta, tb;
  std::vector<std::pair<uint16_t, uint16_t>> la, lb;
  a->interfaceTriangles(pa, ta, la);
  b->interfaceTriangles(pb, tb, lb);
  EXPECT_EQ(pa, pb);
  EXPECT_EQ(ta, tb);
  EXPECT_EQ(la, lb);
}
