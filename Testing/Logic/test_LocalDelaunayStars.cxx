// SPDX-License-Identifier: GPL-3.0-or-later
// Local Delaunay surface, stars, candidates and selection (LocalDelaunayStars.cxx): the selected
// star triangles keep every patch an oriented 2-manifold.
#include <femesher/stages/LocalDelaunay.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <utility>
#include <vector>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

/// Only the stars and the selection (steps 2-3): no loop filling, no closure.
LocalDelaunayParameters selectionOnly() {
  LocalDelaunayParameters p;
  p.fillLoops = false;
  p.restrictedClosure = false;
  return p;
}

}  // namespace

TEST(LocalDelaunayStars, SelectionKeepsEveryPatchAnOrientedManifold) {
  for (const auto& [name, v] : namedShapes()) {
    StageRun r = runStages(v);
    const LocalDelaunayResult ldt = localDelaunay(r, selectionOnly());
    std::printf(
        "%s: %zu star candidates, %zu taken (%zu single vote), %zu rejected, %zu open "
        "edges\n",
        name, ldt.starTriangles, ldt.triangles.size(), ldt.fromSingleVote, ldt.nonManifoldRemoved,
        ldt.openEdgesAfter);
    ASSERT_GT(ldt.triangles.size(), r.surface.triangles.size() / 2) << name;
    expectOrientedManifoldPatches(ldt, r.ps.particles.size(), name);
    // Every triangle came from the stars; nothing later ran.
    EXPECT_EQ(ldt.fromStars + ldt.fromSingleVote, ldt.triangles.size()) << name;
    EXPECT_EQ(ldt.fromLoopFill + ldt.fromRestricted, 0u) << name;
    EXPECT_EQ(ldt.holeLoops, 0u) << name;
    EXPECT_LE(ldt.triangles.size(), ldt.starTriangles) << name;
    EXPECT_EQ(ldt.openEdgesAfter, ldt.openEdgesBefore) << name;
    EXPECT_EQ(ldt.openEdgesAfter, countOpenEdges(ldt.triangles, ldt.trianglePairs)) << name;
  }
}

TEST(LocalDelaunayStars, FewerVotesNeededTakesMoreStarTriangles) {
  StageRun r = runStages(fourAtAPoint());
  LocalDelaunayParameters two = selectionOnly(), three = selectionOnly();
  two.minVotes = 2;
  three.minVotes = 3;
  const LocalDelaunayResult a = localDelaunay(r, two);
  const LocalDelaunayResult b = localDelaunay(r, three);
  std::printf("min votes 2: %zu stars + %zu single vote, %zu open; 3: %zu + %zu, %zu open\n",
              a.fromStars, a.fromSingleVote, a.openEdgesAfter, b.fromStars, b.fromSingleVote,
              b.openEdgesAfter);
  EXPECT_EQ(a.starTriangles, b.starTriangles);  // the same stars
  EXPECT_GT(a.fromStars, b.fromStars);
  EXPECT_LE(a.openEdgesAfter, b.openEdgesAfter);
}
