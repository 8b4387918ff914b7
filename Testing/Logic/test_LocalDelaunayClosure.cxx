// SPDX-License-Identifier: GPL-3.0-or-later
// Local Delaunay surface, restricted closure and self-intersections (LocalDelaunayClosure.cxx):
// what the local phases leave open is closed with restricted-Delaunay triangles; open edges and
// crossing triangles are counted exactly.
#include <femesher/stages/LocalDelaunay.h>
#include <gtest/gtest.h>

#include <array>
#include <utility>
#include <vector>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

TEST(LocalDelaunayClosure, RestrictedClosureIsALastResortThatCloses) {
  // Crippled local stage (neighbours must have almost the same normal, 3 votes needed, no loop
  // filling): holes are left, and the closure must close them all with restricted-Delaunay
  // triangles it counts; without the closure they stay.
  StageRun r = runStages(fourAtAPoint());
  LocalDelaunayParameters crippled = crippledStars();
  const LocalDelaunayResult open = localDelaunay(r, crippled);
  EXPECT_GT(open.openEdgesAfter, 0u);
  EXPECT_EQ(open.openEdgesAfter, countOpenEdges(open.triangles, open.trianglePairs));
  EXPECT_EQ(open.fromRestricted, 0u);
  crippled.restrictedClosure = true;
  const LocalDelaunayResult closed = localDelaunay(r, crippled);
  EXPECT_EQ(closed.openEdgesAfter, 0u);
  EXPECT_EQ(countOpenEdges(closed.triangles, closed.trianglePairs), 0u);
  EXPECT_EQ(countSelfIntersections(canonicalPositions(r), closed.triangles), 0u);
  EXPECT_GT(closed.fromRestricted, 0u);
  EXPECT_GT(closed.restrictedComponents, 0u);
  EXPECT_EQ(closed.fromStars + closed.fromSingleVote + closed.fromLoopFill + closed.fromRestricted,
            closed.triangles.size());
}

namespace {

using Tri = std::array<int32_t, 3>;
using Pair = std::pair<uint16_t, uint16_t>;

}  // namespace

TEST(LocalDelaunayClosure, OpenEdgesAreCountedPerMaterial) {
  // The four faces of a tetrahedron, outward.
  const std::vector<Tri> tet = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const std::vector<Pair> inMaterial1(4, Pair{0, 1}), between1And2(4, Pair{1, 2});
  EXPECT_EQ(countOpenEdges(tet, inMaterial1), 0u);
  EXPECT_EQ(countOpenEdges(tet, between1And2), 0u);
  const std::vector<Tri> open(tet.begin(), tet.end() - 1);
  // Label 0 (outside) is not counted; each other material of the missing face is.
  EXPECT_EQ(countOpenEdges(open, std::vector<Pair>(3, Pair{0, 1})), 3u);
  EXPECT_EQ(countOpenEdges(open, std::vector<Pair>(3, Pair{1, 2})), 6u);
  // A face used twice by material 1 is closed again.
  std::vector<Tri> twice = tet;
  twice.push_back(tet[0]);
  twice.push_back(tet[0]);
  EXPECT_EQ(countOpenEdges(twice, std::vector<Pair>(6, Pair{0, 1})), 0u);
}

TEST(LocalDelaunayClosure, SelfIntersectionsAreFoundExactly) {
  const std::vector<Vec3> p = {
      {0, 0, 0},       // 0
      {1, 0, 0},       // 1
      {0, 1, 0},       // 2
      {0, 0, 1},       // 3
      {0.5, 0.2, 0},   // 4: inside the triangle 0 1 2's plane, same side of 0-1 as 2
      {0.5, -0.5, 0},  // 5: same plane, other side of 0-1
      {0.3, 0.3, -1},  // 6
      {0.3, 0.3, 1},   // 7: 6-7 pierces triangle 0 1 2
      {2, 0.3, 0.5},   // 8
      {-1, 0, 0},      // 9
      {0, -1, 0},      // 10
  };
  auto count = [&](std::vector<Tri> t) { return countSelfIntersections(p, t); };
  EXPECT_EQ(count({{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}), 0u) << "a tetrahedron";
  EXPECT_EQ(count({{0, 1, 2}, {0, 2, 1}}), 1u) << "the same vertices twice";
  EXPECT_EQ(count({{0, 1, 2}, {6, 7, 8}}), 1u) << "crossing, no shared vertex";
  EXPECT_EQ(count({{0, 1, 2}, {3, 8, 7}}), 0u) << "apart";
  EXPECT_EQ(count({{0, 1, 2}, {1, 0, 4}}), 1u) << "shared edge, folded onto the other";
  EXPECT_EQ(count({{0, 1, 2}, {1, 0, 5}}), 0u) << "shared edge, coplanar, other side";
  EXPECT_EQ(count({{0, 1, 2}, {1, 0, 3}}), 0u) << "shared edge, at an angle";
  EXPECT_EQ(count({{0, 1, 2}, {0, 9, 10}}), 0u) << "shared vertex only";
  EXPECT_EQ(count({{0, 1, 2}, {0, 6, 7}}), 1u) << "shared vertex, opposite edge through it";
}
