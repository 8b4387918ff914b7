// SPDX-License-Identifier: GPL-3.0-or-later
// Junctions, particle system, boundary meshing and LDT on analytic multi-material shapes.
#include "MeshInvariants.h"

#include <femesher/Pipeline.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/LocalDelaunay.h>
#include <femesher/stages/ParticleSystem.h>
#include <femesher/stages/SurfaceSampling.h>

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <set>

using namespace femesher;
using namespace femesher::testing;

namespace {

LabelVolume makeVolume(int n, const std::function<int(double, double, double)>& label) {
  LabelVolume v;
  v.dims = {n, n, n};
  v.labels.resize(size_t(n) * n * n);
  const double c = (n - 1) / 2.0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) v.labels[v.index(i, j, k)] = label(i - c, j - c, k - c);
  return v;
}

/// Two touching balls.
LabelVolume twoSpheres() {
  return makeVolume(36, [](double x, double y, double z) {
    if ((x + 7) * (x + 7) + y * y + z * z < 64) return 1;
    if ((x - 7) * (x - 7) + y * y + z * z < 64 && x >= 0) return 2;
    return 0;
  });
}

/// Three slabs meeting on a line (the z axis), inside a ball.
LabelVolume threeSlabs() {
  return makeVolume(36, [](double x, double y, double z) {
    if (x * x + y * y + z * z >= 15 * 15) return 0;
    const double a = std::atan2(y, x);
    return a < -1.0 ? 1 : (a < 1.2 ? 2 : 3);
  });
}

/// Four materials meeting at a point (octant-like sectors inside a ball).
LabelVolume fourAtAPoint() {
  return makeVolume(36, [](double x, double y, double z) {
    if (x * x + y * y + z * z >= 15 * 15) return 0;
    if (z < 0.3) return x < 0.2 ? 1 : 2;
    return y < -0.4 ? 3 : 4;
  });
}

struct StageRun {
  PreprocessedVolume vol;
  std::unique_ptr<IndicatorField> field;
  SurfaceSamples samples;
  Junctions junctions;
  ParticleSystemResult ps;
  BoundarySurface surface;
};

StageRun runStages(const LabelVolume& v, double h, const SizingFunction& sizing) {
  StageRun r;
  RunContext ctx;
  r.vol = preprocessLabels(v, {}, ctx);
  r.field = std::make_unique<IndicatorField>(computeIndicatorFunctions(r.vol, {}, ctx));
  SurfaceSamplingParameters sp;
  sp.targetEdgeLength = h;
  sp.sizing = sizing;
  r.samples = sampleInterfaces(*r.field, v, sp, ctx);
  r.junctions = findJunctions(*r.field, sizing, {}, ctx);
  r.ps = runParticleSystem(*r.field, r.samples, r.junctions, sizing, v, {}, ctx);
  std::vector<Vec3> pts;
  for (const auto& p : r.ps.particles) pts.push_back(p.local);
  r.surface = buildBoundaryMesh(*r.field, pts, r.samples, ctx);
  return r;
}

/// Fraction of junction particles that are vertices of an edge shared by triangles of >= 3
/// materials.
double junctionsOnTripleEdges(const StageRun& r) {
  std::map<Vec3, int> vid;
  for (size_t i = 0; i < r.surface.points.size(); ++i) vid[r.surface.points[i]] = int(i);
  std::map<std::pair<int, int>, std::set<int>> edgeMaterials;
  for (size_t t = 0; t < r.surface.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      int a = r.surface.triangles[t][e], b = r.surface.triangles[t][(e + 1) % 3];
      if (a > b) std::swap(a, b);
      edgeMaterials[{a, b}].insert(r.surface.trianglePairs[t].first);
      edgeMaterials[{a, b}].insert(r.surface.trianglePairs[t].second);
    }
  std::map<int, size_t> best;
  for (const auto& [e, m] : edgeMaterials) {
    best[e.first] = std::max(best[e.first], m.size());
    best[e.second] = std::max(best[e.second], m.size());
  }
  size_t ok = 0, total = 0;
  for (const auto& p : r.ps.particles) {
    if (p.junction < 0) continue;
    ++total;
    auto it = vid.find(r.vol.localToCanonical(p.local));
    if (it != vid.end() && best[it->second] >= 3) ++ok;
  }
  return total ? double(ok) / double(total) : 0.0;
}

}  // namespace

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
  EXPECT_GE(junctionsOnTripleEdges(r), 0.9);
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
  EXPECT_GE(junctionsOnTripleEdges(r), 0.9);
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

TEST(BoundaryMesh, RestrictedDelaunaySurfaceIsWatertight) {
  for (const LabelVolume& v : {twoSpheres(), threeSlabs(), fourAtAPoint()}) {
    const SizingFunction s = [](const Vec3&) { return 2.0; };
    StageRun r = runStages(v, 2.0, s);
    EXPECT_EQ(countOpenEdges(r.surface.triangles, r.surface.trianglePairs), 0u);
  }
}

TEST(LocalDelaunay, ReportsHolesAndMeshesEveryPatch) {
  const LabelVolume v = threeSlabs();
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(v, 2.0, s);
  RunContext ctx;
  const LocalDelaunayResult ldt =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, *r.surface.delaunay, ctx);
  std::set<std::pair<uint16_t, uint16_t>> patches(ldt.trianglePairs.begin(), ldt.trianglePairs.end());
  for (auto p : {std::pair<uint16_t, uint16_t>{1, 2}, {1, 3}, {2, 3}, {0, 1}, {0, 2}, {0, 3}})
    EXPECT_TRUE(patches.count(p)) << p.first << "-" << p.second;
  // The count is what the run report shows; it must agree with an independent recount.
  EXPECT_EQ(ldt.openEdgesAfter, countOpenEdges(ldt.triangles, ldt.trianglePairs));
  EXPECT_LE(ldt.openEdgesAfter, ldt.openEdgesBefore);
  EXPECT_GT(ldt.triangles.size(), r.surface.triangles.size() / 2);
}

TEST(MeshingPipeline, LdtSurfaceMesherRuns) {
  const LabelVolume v = twoSpheres();
  MeshingParameters p;
  p.surfaceMesher = "ldt";
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  expectConformal(r->mesh);
  EXPECT_EQ(meshLabels(r->mesh), (std::set<int32_t>{1, 2}));
  EXPECT_NE(r->reportJson.find("ldt_holes_filled"), std::string::npos);
}

TEST(BoundaryMesh, SameInputSameSurface) {
  const LabelVolume v = threeSlabs();
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun a = runStages(v, 2.0, s);
  std::vector<Vec3> pts;
  for (const auto& p : a.ps.particles) pts.push_back(p.local);
  RunContext ctx;
  const BoundarySurface s1 = buildBoundaryMesh(*a.field, pts, a.samples, ctx);
  const BoundarySurface s2 = buildBoundaryMesh(*a.field, pts, a.samples, ctx);
  EXPECT_EQ(s1.points, s2.points);
  EXPECT_EQ(s1.triangles, s2.triangles);
  RunContext c2;
  const IndicatorField f2 = computeIndicatorFunctions(a.vol, {}, c2);
  size_t diff = 0;
  for (int m = 0; m < f2.labelCount(); ++m)
    for (int k = 0; k < a.vol.dims[2]; ++k)
      for (int j = 0; j < a.vol.dims[1]; ++j)
        for (int i = 0; i < a.vol.dims[0]; ++i) diff += f2.value(m, i, j, k) != a.field->value(m, i, j, k);
  EXPECT_EQ(diff, 0u);
}
