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
  BoundaryMeshParameters unrefined;
  unrefined.facetDistance = 0;
  r.surface = buildBoundaryMesh(*r.field, pts, r.samples, nullptr, unrefined, ctx);
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

std::vector<Vec3> canonicalPositions(const StageRun& r) {
  std::vector<Vec3> pos;
  for (const auto& p : r.ps.particles) pos.push_back(r.vol.localToCanonical(p.local));
  return pos;
}

}  // namespace

TEST(LocalDelaunay, WatertightValidAndMostlyLocalOnAnalyticShapes) {
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  const std::vector<std::pair<const char*, LabelVolume>> shapes = {
      {"two spheres", twoSpheres()},
      {"three slabs", threeSlabs()},
      {"four at a point", fourAtAPoint()}};
  for (const auto& [name, v] : shapes) {
    StageRun r = runStages(v, 2.0, s);
    RunContext ctx;
    const LocalDelaunayResult ldt =
        buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, ctx);
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

TEST(LocalDelaunay, ThreeSlabsMeetOnConsistentRims) {
  // The triple line (z axis) must be an edge chain shared by all three patches between the slabs:
  // every link edge used by exactly one triangle of each of (1,2), (1,3), (2,3).
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(threeSlabs(), 2.0, s);
  RunContext ctx;
  const LocalDelaunayResult ldt =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, ctx);
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

TEST(LocalDelaunay, RestrictedClosureIsALastResortThatCloses) {
  // Crippled local stage (neighbours must have almost the same normal, 3 votes needed, no loop
  // filling): holes are left, and the closure must close them all with restricted-Delaunay
  // triangles it counts; without the closure they stay.
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(fourAtAPoint(), 2.0, s);
  LocalDelaunayParameters crippled;
  crippled.normalAgreement = 0.97;
  crippled.minVotes = 3;
  crippled.fillLoops = false;
  crippled.restrictedClosure = false;
  RunContext c1, c2;
  const LocalDelaunayResult open =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, c1, crippled);
  EXPECT_GT(open.openEdgesAfter, 0u);
  EXPECT_EQ(open.openEdgesAfter, countOpenEdges(open.triangles, open.trianglePairs));
  EXPECT_EQ(open.fromRestricted, 0u);
  crippled.restrictedClosure = true;
  const LocalDelaunayResult closed =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, c2, crippled);
  EXPECT_EQ(closed.openEdgesAfter, 0u);
  EXPECT_EQ(countOpenEdges(closed.triangles, closed.trianglePairs), 0u);
  EXPECT_EQ(countSelfIntersections(canonicalPositions(r), closed.triangles), 0u);
  EXPECT_GT(closed.fromRestricted, 0u);
  EXPECT_GT(closed.restrictedComponents, 0u);
  EXPECT_EQ(closed.fromStars + closed.fromSingleVote + closed.fromLoopFill + closed.fromRestricted,
            closed.triangles.size());
}

TEST(LocalDelaunay, SameResultForAnyThreadCount) {
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun r = runStages(fourAtAPoint(), 2.0, s);
  RunContext c1, c4;
  c1.setThreads(1);
  c4.setThreads(4);
  const LocalDelaunayResult a =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, c1);
  const LocalDelaunayResult b =
      buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, c4);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.trianglePairs, b.trianglePairs);
  EXPECT_EQ(a.fromRestricted, b.fromRestricted);
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
  EXPECT_NE(r->reportJson.find("\"surface_mesher_used\": \"ldt\""), std::string::npos);
  std::map<std::string, double> counts(r->counts.begin(), r->counts.end());
  EXPECT_EQ(counts["ldt_open_edges"], 0.0);
  EXPECT_EQ(counts["ldt_self_intersections"], 0.0);
  EXPECT_EQ(counts["ldt_used"], 1.0);
}

TEST(BoundaryMesh, SameInputSameSurface) {
  const LabelVolume v = threeSlabs();
  const SizingFunction s = [](const Vec3&) { return 2.0; };
  StageRun a = runStages(v, 2.0, s);
  std::vector<Vec3> pts;
  for (const auto& p : a.ps.particles) pts.push_back(p.local);
  RunContext ctx;
  BoundaryMeshParameters unrefined;
  unrefined.facetDistance = 0;
  const BoundarySurface s1 = buildBoundaryMesh(*a.field, pts, a.samples, nullptr, unrefined, ctx);
  const BoundarySurface s2 = buildBoundaryMesh(*a.field, pts, a.samples, nullptr, unrefined, ctx);
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
