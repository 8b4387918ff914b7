// SPDX-License-Identifier: GPL-3.0-or-later
// Local Delaunay surface, patches and triple lines (LocalDelaunayPatches.cxx): every triangle
// belongs to a patch of its corners, and the triple lines become edge chains of the three patches
// meeting there.
#include <femesher/stages/LocalDelaunay.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <utility>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

TEST(LocalDelaunayPatches, ThreeSlabsMeetOnConsistentRims) {
  // The triple line (z axis) must be an edge chain shared by all three patches between the slabs:
  // every link edge used by exactly one triangle of each of (1,2), (1,3), (2,3).
  StageRun r = runStages(threeSlabs());
  const LocalDelaunayResult ldt = localDelaunay(r);
  EXPECT_GT(ldt.lineLinks, 8u);
  std::map<std::pair<int32_t, int32_t>, std::map<std::pair<uint16_t, uint16_t>, int>> use;
  for (size_t t = 0; t < ldt.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      int32_t a = ldt.triangles[t][e], b = ldt.triangles[t][(e + 1) % 3];
      if (a > b) std::swap(a, b);
      ++use[{a, b}][ldt.trianglePairs[t]];
    }
  size_t interiorLineEdges = 0, consistent = 0;
  for (const auto& [e, byPatch] : use) {
    const Particle &pa = r.ps.particles[size_t(e.first)], &pb = r.ps.particles[size_t(e.second)];
    if (pa.junction < 0 || pb.junction < 0) continue;
    const JunctionPoint &ja = r.junctions.particles[size_t(pa.junction)],
                        &jb = r.junctions.particles[size_t(pb.junction)];
    if (ja.count != 3 || jb.count != 3 || ja.labels[0] != 1 || jb.labels[0] != 1) continue;
    ++interiorLineEdges;
    consistent += byPatch.size() == 3 && byPatch.count({1, 2}) && byPatch.count({1, 3}) &&
                  byPatch.count({2, 3}) && byPatch.at({1, 2}) == 1 && byPatch.at({1, 3}) == 1 &&
                  byPatch.at({2, 3}) == 1;
  }
  EXPECT_GT(interiorLineEdges, 8u);
  EXPECT_EQ(consistent, interiorLineEdges);
}

TEST(LocalDelaunayPatches, EveryTriangleIsOnAPatchOfItsCorners) {
  for (const auto& [name, v] : namedShapes()) {
    StageRun r = runStages(v);
    const LocalDelaunayResult ldt = localDelaunay(r);
    ASSERT_FALSE(ldt.triangles.empty());
    size_t off = 0;
    for (size_t t = 0; t < ldt.triangles.size(); ++t) {
      const auto [a, b] = ldt.trianglePairs[t];
      EXPECT_LT(a, b);
      for (int32_t x : ldt.triangles[t]) {
        const Particle& p = r.ps.particles[size_t(x)];
        const bool on = p.junction < 0 ? (p.a == a && p.b == b)
                                       : r.junctions.particles[size_t(p.junction)].contains(a, b);
        off += !on;
      }
    }
    EXPECT_EQ(off, 0u) << name << ": corners not on their triangle's patch";
  }
}

TEST(LocalDelaunayPatches, TripleLineLinksChainTheJunctionParticles) {
  StageRun r = runStages(threeSlabs());
  const LocalDelaunayResult ldt = localDelaunay(r);
  size_t triple = 0, quadruple = 0;
  for (const auto& j : r.junctions.particles) (j.count == 4 ? quadruple : triple)++;
  std::printf("%zu triple and %zu quadruple junction particles: %zu links, %zu open ends\n", triple,
              quadruple, ldt.lineLinks, ldt.lineEnds);
  // Four triple lines run between the two quadruple points where the axis leaves the ball: the
  // axis (1,2,3) and the three arcs where the slabs meet the ball's surface (0,a,b). Chained,
  // each line of k triple particles has k + 1 links, and no particle lacks a link.
  ASSERT_EQ(quadruple, 2u);
  EXPECT_EQ(ldt.lineLinks, triple + 4);
  EXPECT_EQ(ldt.lineEnds, 0u);
}
