// SPDX-License-Identifier: GPL-3.0-or-later
// Local Delaunay surface, hole loops (LocalDelaunayHoles.cxx): the holes the stars leave are
// traced into loops and filled without new vertices, keeping every patch an oriented manifold.
#include <femesher/stages/LocalDelaunay.h>
#include <gtest/gtest.h>

#include <cstdio>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

TEST(LocalDelaunayHoles, LoopFillingClosesHolesWithoutNewVertices) {
  // A crippled star phase (neighbours must have almost the same normal, 3 votes needed) leaves
  // holes; no restricted closure, so what is left open stays open.
  StageRun r = runStages(fourAtAPoint());
  LocalDelaunayParameters p = crippledStars();
  const LocalDelaunayResult before = localDelaunay(r, p);
  p.fillLoops = true;
  const LocalDelaunayResult after = localDelaunay(r, p);
  std::printf("open edges %zu; %zu loops, %zu filled with %zu triangles, %zu open edges left\n",
              after.openEdgesBefore, after.holeLoops, after.holesFilled, after.fromLoopFill,
              after.openEdgesAfterFill);
  // Without filling: nothing traced, the selection's open edges stay.
  ASSERT_GT(before.openEdgesBefore, 0u);
  EXPECT_EQ(before.holeLoops + before.holesFilled + before.fromLoopFill, 0u);
  EXPECT_EQ(before.openEdgesAfterFill, before.openEdgesBefore);
  // With filling: the same selection, then loops closed by triangles on the particles alone.
  EXPECT_EQ(after.openEdgesBefore, before.openEdgesBefore);
  EXPECT_GT(after.holeLoops, 0u);
  EXPECT_GT(after.holesFilled, 0u);
  EXPECT_LE(after.holesFilled, after.holeLoops);
  EXPECT_GE(after.fromLoopFill, after.holesFilled);
  EXPECT_LT(after.openEdgesAfterFill, after.openEdgesBefore);
  EXPECT_EQ(after.openEdgesAfter, after.openEdgesAfterFill);
  EXPECT_EQ(after.openEdgesAfter, countOpenEdges(after.triangles, after.trianglePairs));
  EXPECT_EQ(after.triangles.size(), before.triangles.size() + after.fromLoopFill);
  EXPECT_EQ(after.fromRestricted, 0u);
  expectOrientedManifoldPatches(after, r.ps.particles.size(), "after loop filling");
}
