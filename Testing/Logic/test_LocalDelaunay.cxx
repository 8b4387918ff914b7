// SPDX-License-Identifier: GPL-3.0-or-later
// The local Delaunay surface (LocalDelaunay.h) on analytic multi-material shapes: watertight,
// valid, made of the local triangulations, independent of the thread count.
#include <femesher/stages/LocalDelaunay.h>
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

/// Shares of an LDT surface's triangles whose label pair matches the materials found just off
/// the triangle (centroid -/+ 0.5 voxel along the normal, which points from first into second).
double sidesMatchShare(const StageRun& r, const LocalDelaunayResult& ldt) {
  size_t ok = 0;
  for (size_t t = 0; t < ldt.triangles.size(); ++t) {
    Vec3 c{0, 0, 0};
    std::array<Vec3, 3> p;
    for (int k = 0; k < 3; ++k) {
      p[k] = r.vol.localToCanonical(r.ps.particles[size_t(ldt.triangles[t][k])].local);
      for (int a = 0; a < 3; ++a) c[a] += p[k][a] / 3;
    }
    const Vec3 u{p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const Vec3 v{p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    Vec3 n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (l == 0) continue;
    auto labelAt = [&](double s) {
      const Vec3 q{c[0] + s * n[0] / l, c[1] + s * n[1] / l, c[2] + s * n[2] / l};
      return r.field->argmax(r.vol.canonicalToLocal(q));
    };
    ok +=
        labelAt(-0.5) == ldt.trianglePairs[t].first && labelAt(0.5) == ldt.trianglePairs[t].second;
  }
  return ldt.triangles.empty() ? 0.0 : double(ok) / double(ldt.triangles.size());
}

}  // namespace

TEST(LocalDelaunay, WatertightValidAndMostlyLocalOnAnalyticShapes) {
  for (const auto& [name, v] : namedShapes()) {
    StageRun r = runStages(v);
    const LocalDelaunayResult ldt = localDelaunay(r);
    // Zero holes, counted by the stage and recounted independently.
    EXPECT_EQ(ldt.openEdgesAfter, 0u) << name;
    EXPECT_EQ(countOpenEdges(ldt.triangles, ldt.trianglePairs), 0u) << name;
    // A valid PLC: no two triangles cross (exact test), none repeated.
    EXPECT_EQ(ldt.selfIntersectionsAfter, 0u) << name;
    EXPECT_EQ(countSelfIntersections(canonicalPositions(r), ldt.triangles), 0u) << name;
    // Every patch of the restricted Delaunay surface is there, with the right materials on its
    // two sides.
    std::set<std::pair<uint16_t, uint16_t>> want(r.surface.trianglePairs.begin(),
                                                 r.surface.trianglePairs.end());
    std::set<std::pair<uint16_t, uint16_t>> got(ldt.trianglePairs.begin(), ldt.trianglePairs.end());
    EXPECT_EQ(got, want) << name;
    EXPECT_GE(sidesMatchShare(r, ldt), 0.97) << name;
    // Provenance adds up, and the local triangulation made the surface (the restricted-Delaunay
    // closure is a last resort).
    EXPECT_EQ(ldt.fromStars + ldt.fromSingleVote + ldt.fromLoopFill + ldt.fromRestricted,
              ldt.triangles.size())
        << name;
    EXPECT_GE(double(ldt.fromStars), 0.95 * double(ldt.triangles.size())) << name;
    EXPECT_LE(double(ldt.fromRestricted), 0.01 * double(ldt.triangles.size())) << name;
    EXPECT_GT(ldt.triangles.size(), r.surface.triangles.size() / 2) << name;
  }
}

TEST(LocalDelaunay, SameResultForAnyThreadCount) {
  StageRun r = runStages(fourAtAPoint());
  const LocalDelaunayResult a = localDelaunay(r, {}, 1);
  const LocalDelaunayResult b = localDelaunay(r, {}, 4);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.trianglePairs, b.trianglePairs);
  EXPECT_EQ(a.fromRestricted, b.fromRestricted);
}

TEST(LocalDelaunay, EmptyWithoutARestrictedTriangulation) {
  StageRun r = runStages(twoSpheres());
  BoundarySurface none = r.surface;
  none.delaunay.reset();
  RunContext ctx;
  const LocalDelaunayResult ldt =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, none,
                                LocalDelaunayParameters{}, ctx);
  EXPECT_TRUE(ldt.triangles.empty());
  EXPECT_EQ(ldt.starTriangles, 0u);
  EXPECT_EQ(ldt.lineLinks, 0u);
}
