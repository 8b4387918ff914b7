// SPDX-License-Identifier: GPL-3.0-or-later
// The check after Optimize (MeshCheck.h): planted flat tets are removed on the boundary and fail
// the run inside; tets below min_dihedral_warning are counted and make the status poor_elements.
#include "TestShapes.h"

#include <femesher/MeshCheck.h>
#include <femesher/Pipeline.h>
#include <femesher/Status.h>
#include <femesher/VecMath.h>

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

using namespace femesher;

namespace {

using Tet = std::array<int32_t, 4>;

struct Mesh {
  std::vector<Vec3> points;
  std::vector<Tet> tets;
  std::vector<int32_t> labels;
  void addTet(Tet t, int32_t label) {  // positively oriented
    const Vec3 &a = points[size_t(t[0])], &b = points[size_t(t[1])], &c = points[size_t(t[2])],
               &d = points[size_t(t[3])];
    if (dot(sub(b, a), cross(sub(c, a), sub(d, a))) < 0) std::swap(t[2], t[3]);
    tets.push_back(t);
    labels.push_back(label);
  }
};

/// A flat tet A B C D (a unit square at z = 0) under two tets to the apex E above (faces ABC and
/// ACD); with `below`, two more tets to F below (faces ABD, BCD) enclose it. G is used by no tet.
Mesh plantedFlatTet(bool below) {
  Mesh m;
  m.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 1}, {0.5, 0.5, -1}, {9, 9, 9}};
  m.tets.push_back({0, 1, 2, 3});  // flat: volume 0
  m.labels.push_back(1);
  m.addTet({0, 1, 2, 4}, 1);
  m.addTet({0, 2, 3, 4}, 2);
  if (below) {
    m.addTet({0, 1, 3, 5}, 1);
    m.addTet({1, 2, 3, 5}, 2);
  }
  return m;
}

}  // namespace

TEST(MeshCheck, DegenerateIsRelativeToTheEdgeLength) {
  EXPECT_TRUE(isDegenerateTet({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, 1e-12));
  EXPECT_TRUE(isDegenerateTet({0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}, 1e-12));  // inverted
  // The same tiny tet scaled by 1e-6 is not flat: only the shape counts.
  EXPECT_FALSE(isDegenerateTet({0, 0, 0}, {1e-6, 0, 0}, {0, 1e-6, 0}, {0, 0, 1e-6}, 1e-12));
  EXPECT_TRUE(isDegenerateTet({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 1e-13}, 1e-12));
  EXPECT_FALSE(isDegenerateTet({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 1e-9}, 1e-12));
}

TEST(MeshCheck, FlatTetOnTheOuterBoundaryIsRemovedAndCounted) {
  Mesh m = plantedFlatTet(false);
  const MeshCheckResult r = checkTetMesh(m.points, m.tets, m.labels, MeshCheckParameters{});
  EXPECT_EQ(r.removedDegenerateTets, 1u);
  ASSERT_EQ(m.tets.size(), 2u);
  EXPECT_EQ(m.labels, (std::vector<int32_t>{1, 2}));
  EXPECT_EQ(m.points.size(), 5u);  // F and G are used by no tet any more
  for (const Tet& t : m.tets)
    for (int32_t v : t) EXPECT_LT(size_t(v), m.points.size());
  EXPECT_GT(r.worstMinDihedral, 5.0);
  EXPECT_EQ(r.tetsBelowWarning, 0u);
  EXPECT_FALSE(r.poor());
}

TEST(MeshCheck, FlatTetInsideFailsTheRunSayingWhere) {
  Mesh m = plantedFlatTet(true);
  MeshCheckFrame frame;
  frame.toReport = [](const Vec3& c) { return add(c, {100, 200, 300}); };
  frame.source = "planted.nrrd";
  try {
    checkTetMesh(m.points, m.tets, m.labels, MeshCheckParameters{}, frame);
    FAIL() << "an interior flat tet must fail the run";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::MeshingFailed);
    const std::string msg = e.what();
    EXPECT_NE(msg.find("1 tet(s) of zero or negative volume"), std::string::npos) << msg;
    EXPECT_NE(msg.find("(100.50, 200.50, 300.00)"), std::string::npos) << msg;
    EXPECT_NE(msg.find("planted.nrrd"), std::string::npos) << msg;
    EXPECT_NE(msg.find("target_edge_length"), std::string::npos) << msg;
  }
  EXPECT_EQ(m.tets.size(), 5u);  // untouched
}

TEST(MeshCheck, SliverBelowTheWarningIsCountedAndListed) {
  Mesh m;
  m.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.3, 0.3, -0.02}};
  m.addTet({0, 1, 2, 3}, 1);  // corner tet: smallest dihedral 54.7 deg
  m.addTet({0, 1, 2, 4}, 2);  // sliver under it
  MeshCheckParameters p;
  MeshCheckResult r = checkTetMesh(m.points, m.tets, m.labels, p);
  EXPECT_EQ(r.removedDegenerateTets, 0u);
  EXPECT_EQ(r.tetsBelowWarning, 1u);
  EXPECT_TRUE(r.poor());
  ASSERT_EQ(r.worst.size(), 1u);
  EXPECT_EQ(r.worst[0].label, 2);
  EXPECT_LT(r.worst[0].minDihedral, 5.0);
  EXPECT_GT(r.worst[0].minDihedral, 0.5);
  EXPECT_DOUBLE_EQ(r.worstMinDihedral, r.worst[0].minDihedral);
  EXPECT_NEAR(r.worst[0].centroid[2], -0.005, 1e-12);
  EXPECT_NE(meshCheckSummary(r).find("1 tet(s) below min_dihedral_warning (5 deg): status "
                                     "poor_elements"), std::string::npos) << meshCheckSummary(r);
  p.minDihedralWarning = 0;  // off
  r = checkTetMesh(m.points, m.tets, m.labels, p);
  EXPECT_FALSE(r.poor());
  EXPECT_TRUE(r.worst.empty());
  EXPECT_NE(meshCheckSummary(r).find("status ok"), std::string::npos);
}

TEST(MeshCheck, RunReportStatusFollowsTheWarning) {
  const LabelVolume v = test::ballsInShell(20);
  for (double warning : {0.0, 89.0}) {
    MeshingParameters p;
    p.optimize.minDihedralWarning = warning;
    p.run.computeFidelity = false;
    RunContext ctx;
    auto r = runPipeline(v, p, ctx);
    ASSERT_TRUE(r.isOk()) << r.status().message();
    const auto report = nlohmann::json::parse(r->reportJson);
    const auto& check = report["mesh_check"];
    EXPECT_DOUBLE_EQ(check["min_dihedral_warning"].get<double>(), warning);
    EXPECT_NEAR(check["worst_min_dihedral"].get<double>(),
                r->quality.all.find("min_dihedral")->min, 1e-6);
    if (warning == 0) {
      EXPECT_EQ(report["status"], "ok");
      EXPECT_EQ(check["tets_below_warning"], 0);
    } else {  // every tet is below 89 degrees (a regular tet has 70.5)
      EXPECT_EQ(report["status"], "poor_elements");
      EXPECT_EQ(check["tets_below_warning"].get<size_t>(), r->mesh.tets.size());
      ASSERT_EQ(check["worst_tets"].size(), 5u);
      EXPECT_TRUE(check["worst_tets"][0]["label"].get<int>() >= 1);
      EXPECT_FALSE(check["worst_tets"][0]["material"].get<std::string>().empty());
      bool warned = false;
      for (const auto& w : r->warnings) warned |= w.rfind("Poor elements:", 0) == 0;
      EXPECT_TRUE(warned);
    }
  }
}
