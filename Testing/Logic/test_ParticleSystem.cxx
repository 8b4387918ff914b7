// SPDX-License-Identifier: GPL-3.0-or-later
// Junctions and the particle system on analytic multi-material shapes.
#include "BoundaryStageInputs.h"
#include "MeshInvariants.h"

#include <femesher/Pipeline.h>

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

using namespace femesher;
using namespace femesher::testing;

TEST(Junctions, ThreeSlabsGiveOneTripleLineAlongTheAxis) {
  const LabelVolume v = threeSlabs();
  const SizingFunction h = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(v, 2.0, h);
  std::set<std::array<uint16_t, 4>> lines;
  size_t onAxis = 0, interior = 0;
  for (const auto& j : r.junctions.particles) {
    if (j.count == 4) continue;  // where the axis meets the ball surface (with the outside)
    lines.insert(j.labels);
    const Vec3 c = r.vol.localToCanonical(j.local);
    // The three materials (1,2,3; compact ids equal here) meet on the z axis, inside the ball.
    if (j.labels[0] != 0) {
      ++interior;
      const double dx = c[0] - 17.5, dy = c[1] - 17.5;
      if (std::sqrt(dx * dx + dy * dy) < 1.0) ++onAxis;
    }
  }
  EXPECT_GT(interior, 8u);
  EXPECT_EQ(onAxis, interior) << "interior triple-line particles off the axis";
  EXPECT_TRUE(lines.count({{1, 2, 3, 0}}));
  EXPECT_GE(junctionShare(r.surface, r), 0.9);
}

TEST(Junctions, FourMaterialsMeetAtAQuadruplePoint) {
  const LabelVolume v = fourAtAPoint();
  const SizingFunction h = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(v, 2.0, h);
  size_t quads = 0;
  for (const auto& j : r.junctions.particles)
    if (j.count == 4 && j.labels[0] == 1) {
      ++quads;
      const Vec3 c = r.vol.localToCanonical(j.local);
      EXPECT_NEAR(c[0], 17.5, 1.5);
      EXPECT_NEAR(c[1], 17.5, 1.5);
      EXPECT_NEAR(c[2], 17.5, 1.5);
    }
  EXPECT_GE(quads, 1u);
  EXPECT_GE(junctionShare(r.surface, r), 0.9);
}

TEST(ParticleSystem, SpacingFollowsAUniformSizingField) {
  const LabelVolume v = twoSpheres();
  for (double h : {1.5, 3.0}) {
    const SizingFunction s = [h](const Vec3&) { return h; };
    StageRun r = runStages(v, h, s);
    // Stated tolerance: mean nearest-neighbour distance within [0.7, 1.2] x h.
    EXPECT_GT(r.ps.meanSpacingRatio, 0.7) << "h = " << h;
    EXPECT_LT(r.ps.meanSpacingRatio, 1.2) << "h = " << h;
    EXPECT_GT(r.ps.iterations, 0);
  }
}

TEST(ParticleSystem, SpacingFollowsAGradedSizingField) {
  const LabelVolume v = twoSpheres();
  // Fine on the left ball (x < centre), coarse on the right.
  const SizingFunction s = [](const Vec3& c) { return c[0] < 17.5 ? 1.5 : 3.0; };
  StageRun r = runStages(v, 1.5, s);
  EXPECT_GT(r.ps.meanSpacingRatio, 0.7);
  EXPECT_LT(r.ps.meanSpacingRatio, 1.2);
  size_t left = 0, right = 0;
  for (const auto& p : r.ps.particles) {
    const Vec3 c = r.vol.localToCanonical(p.local);
    if (p.junction >= 0 || std::fabs(c[0] - 17.5) < 4) continue;
    (c[0] < 17.5 ? left : right)++;
  }
  // Same area, spacing ratio 2 -> about 4x the particles.
  EXPECT_GT(double(left), 2.5 * double(right));
}

TEST(ParticleSystem, ParticlesStayOnTheirInterface) {
  const LabelVolume v = twoSpheres();
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(v, 2.0, s);
  size_t off = 0;
  for (const auto& p : r.ps.particles) {
    if (p.junction >= 0) continue;
    const double F = r.field->eval(p.a, p.local) - r.field->eval(p.b, p.local);
    if (std::fabs(F) > 1e-3) ++off;
  }
  EXPECT_EQ(off, 0u);
}

TEST(ParticleSystem, DeterministicForAGivenSeed) {
  const LabelVolume v = threeSlabs();
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun a = runStages(v, 2.0, s), b = runStages(v, 2.0, s);
  ASSERT_EQ(a.ps.particles.size(), b.ps.particles.size());
  for (size_t i = 0; i < a.ps.particles.size(); ++i)
    EXPECT_EQ(a.ps.particles[i].local, b.ps.particles[i].local);
  ASSERT_EQ(a.surface.points.size(), b.surface.points.size());
  ASSERT_EQ(a.surface.delaunayTets, b.surface.delaunayTets);
  for (size_t i = 0; i < a.surface.points.size(); ++i)
    if (a.surface.points[i] != b.surface.points[i]) {
      ADD_FAILURE() << "first difference at point " << i;
      break;
    }
  EXPECT_EQ(a.surface.points, b.surface.points);
  EXPECT_EQ(a.surface.triangles, b.surface.triangles);
}

TEST(MeshingPipeline, LdtSurfaceMesherRuns) {
  const LabelVolume v = twoSpheres();
  MeshingParameters p;
  p.boundary.mesher = SurfaceMesher::LocalDelaunay;
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  expectConformal(r->mesh);
  EXPECT_EQ(meshLabels(r->mesh), (std::set<int32_t>{1, 2}));
  EXPECT_NE(r->reportJson.find("ldt_holes_filled"), std::string::npos);
  EXPECT_NE(r->reportJson.find("\"surface_mesher_used\": \"ldt\""), std::string::npos);
  std::map<std::string, double> counts(r->counts.begin(), r->counts.end());
  EXPECT_EQ(counts["ldt_open_edges"], 0.0);
  EXPECT_EQ(counts["ldt_self_intersections"], 0.0);
  EXPECT_EQ(counts["ldt_used"], 1.0);
}
