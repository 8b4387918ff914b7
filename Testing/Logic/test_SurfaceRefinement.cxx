// SPDX-License-Identifier: GPL-3.0-or-later
// Refinements of a labelled Delaunay triangulation (SurfaceRefinement.h), each on its own:
// facet distance, voxel centres, junction edges.
#include <femesher/stages/LabelledDelaunay.h>
#include <femesher/stages/SurfaceRefinement.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <vector>

#include "BoundaryStageInputs.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

/// A labelled triangulation of r's particles, put on the input's box as buildBoundaryMesh does.
std::unique_ptr<LabelledDelaunay> labelled(const StageRun& r, RunContext& ctx) {
  std::vector<Vec3> c;
  for (const Vec3& l : r.points) c.push_back(r.vol.localToCanonical(r.field->snapToBox(l)));
  auto ld = std::make_unique<LabelledDelaunay>(r.vol.materialCount());
  ld->insert(c);
  ld->label(*r.field, ctx);
  return ld;
}

BoundarySurface surfaceOf(const LabelledDelaunay& ld) {
  BoundarySurface s;
  ld.interfaceTriangles(s.points, s.triangles, s.trianglePairs);
  return s;
}

double smallestSpacing(const PreprocessedVolume& vol) {
  return std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
}

}  // namespace

TEST(SurfaceRefinement, FacetDistancePointsLieOnTheirInterface) {
  const StageRun r = runStages(twoSpheres(), 3.0, [](const Vec3&) { return 3.0; });
  RunContext ctx;
  auto ld = labelled(r, ctx);
  const size_t before = ld->vertexCount();
  const size_t inserted = refineFacetDistance(*r.field, *ld, 0.5 * smallestSpacing(r.vol), ctx);
  EXPECT_GT(inserted, 0u);
  EXPECT_EQ(ld->vertexCount(), before + inserted);
  // The surface's new vertices are interface points: the two largest indicators tie there.
  std::set<Vec3> input;
  for (const Vec3& l : r.points) input.insert(r.vol.localToCanonical(r.field->snapToBox(l)));
  const BoundarySurface s = surfaceOf(*ld);
  EXPECT_EQ(countOpenEdges(s.triangles, s.trianglePairs), 0u);
  size_t fresh = 0, off = 0;
  for (const Vec3& p : s.points) {
    if (input.count(p)) continue;
    ++fresh;
    const Vec3 l = r.vol.canonicalToLocal(p);
    std::vector<double> f;
    for (int m = 0; m < r.field->labelCount(); ++m) f.push_back(r.field->eval(m, l));
    std::sort(f.rbegin(), f.rend());
    off += f[0] - f[1] > 1e-3;
  }
  EXPECT_GT(fresh, inserted / 2);
  EXPECT_EQ(off, 0u) << "of " << fresh << " new surface vertices";
}

TEST(SurfaceRefinement, LooserFacetDistanceInsertsFewerPoints) {
  const StageRun r = runStages(twoSpheres(), 3.0, [](const Vec3&) { return 3.0; });
  RunContext ctx;
  const double smin = smallestSpacing(r.vol);
  auto fine = labelled(r, ctx), coarse = labelled(r, ctx);
  const size_t nFine = refineFacetDistance(*r.field, *fine, 0.1 * smin, ctx);
  const size_t nCoarse = refineFacetDistance(*r.field, *coarse, 0.25 * smin, ctx);
  std::printf("facet distance 0.1 voxel: %zu points, 0.25 voxel: %zu points\n", nFine, nCoarse);
  EXPECT_GT(nCoarse, 0u);
  EXPECT_LT(nCoarse, nFine);
}

TEST(SurfaceRefinement, VoxelCentresEndUpInTheirLabel) {
  const StageRun r = runStages(twoSpheres(), 3.0, [](const Vec3&) { return 3.0; });
  RunContext ctx;
  auto ld = labelled(r, ctx);
  size_t boundary = 0;
  const size_t wrongBefore = misplacedBoundaryCentres(r.vol, *ld, &boundary);
  const size_t n0 = ld->vertexCount();
  const size_t inserted = refineVoxelCentres(*r.field, *ld, ctx);
  const size_t wrongAfter = misplacedBoundaryCentres(r.vol, *ld);
  std::printf("%zu boundary centres, %zu misplaced before, %zu after, %zu points\n", boundary,
              wrongBefore, wrongAfter, inserted);
  EXPECT_EQ(ld->vertexCount(), n0 + inserted);
  ASSERT_GT(wrongBefore, 0u);
  EXPECT_LT(wrongAfter * 4, wrongBefore);
  EXPECT_EQ(countOpenEdges(surfaceOf(*ld).triangles, surfaceOf(*ld).trianglePairs), 0u);
}

TEST(SurfaceRefinement, JunctionEdgesPutTheJunctionParticlesOnTripleEdges) {
  for (const LabelVolume& v : {threeSlabs(), fourAtAPoint()}) {
    const StageRun r = runStages(v, 3.0, [](const Vec3&) { return 3.0; });
    RunContext ctx;
    auto ld = labelled(r, ctx);
    const size_t total = r.junctions.particles.size();
    ASSERT_GT(total, 0u);
    const size_t okBefore = junctionParticlesOnTripleEdges(surfaceOf(*ld), r);
    const JunctionRefinement jr = refineJunctionEdges(*r.field, *ld, r.junctions, ctx);
    const size_t okAfter = junctionParticlesOnTripleEdges(surfaceOf(*ld), r);
    std::printf("%zu junction particles, on triple edges %zu before, %zu after (%zu points)\n",
                total, okBefore, okAfter, jr.inserted);
    // The stage's count of particles still off agrees with the surface it leaves.
    EXPECT_EQ(jr.stillOff, total - okAfter);
    EXPECT_GE(okAfter, okBefore);
    EXPECT_EQ(jr.inserted > 0, okBefore < total);
    EXPECT_EQ(countOpenEdges(surfaceOf(*ld).triangles, surfaceOf(*ld).trianglePairs), 0u);
  }
}

TEST(SurfaceRefinement, SameResultForAnyThreadCount) {
  const StageRun r = runStages(threeSlabs(), 3.0, [](const Vec3&) { return 3.0; });
  BoundarySurface s[2];
  for (int k = 0; k < 2; ++k) {
    RunContext ctx;
    ctx.setThreads(k == 0 ? 1 : 3);
    auto ld = labelled(r, ctx);
    refineFacetDistance(*r.field, *ld, 0.5 * smallestSpacing(r.vol), ctx);
    refineVoxelCentres(*r.field, *ld, ctx);
    refineJunctionEdges(*r.field, *ld, r.junctions, ctx);
    s[k] = surfaceOf(*ld);
  }
  EXPECT_EQ(s[0].points, s[1].points);
  EXPECT_EQ(s[0].triangles, s[1].triangles);
  EXPECT_EQ(s[0].trianglePairs, s[1].trianglePairs);
}
