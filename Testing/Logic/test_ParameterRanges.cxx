// SPDX-License-Identifier: GPL-3.0-or-later
// Size-like parameters are checked against the label map before any stage runs (issue 14, item
// 5): the element count a value implies against a ceiling, and a floor of a fraction of the
// smallest voxel spacing. runPipeline is what the panel calls, optimizeMesh what `femesher
// optimize` calls: both refuse at once, with the parameter, its value and the smallest useful value.
#include <femesher/ParameterRanges.h>
#include <femesher/Pipeline.h>
#include <femesher/RunContext.h>

#include "TestShapes.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

using namespace femesher;
using femesher::test::makeVolume;

namespace {

/// A ball of label 1, radius 0.4 n voxels, spacing `s` mm.
LabelVolume ball(int n, double s) {
  LabelVolume v = makeVolume({n, n, n}, {s, s, s}, [n](double x, double y, double z) {
    return std::sqrt(x * x + y * y + z * z) < 0.4 * n ? 1 : 0;
  });
  v.sourcePath = "ball.nrrd";
  return v;
}

/// Refused with InvalidArgument, the message naming every one of `words`.
void expectRefused(const MeshingParameters& p, const LabelVolume& v,
                   std::initializer_list<const char*> words) {
  const Status s = checkSizeParameters(p, v);
  ASSERT_FALSE(s.isOk());
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  for (const char* w : words) EXPECT_NE(s.message().find(w), std::string::npos) << w << ": " << s.message();
}

}  // namespace

TEST(ParameterRanges, EstimateIsVolumeOverRegularTet) {
  // A regular tet of edge 1 has volume 1/(6 sqrt 2): 1 mm^3 at edge 1 holds 8.49 of them.
  EXPECT_NEAR(estimatedTets(1.0, 1.0), 6.0 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(estimatedTets(1000.0, 2.0), 1000.0 * 6.0 * std::sqrt(2.0) / 8.0, 1e-9);
  const VolumeExtent e = volumeExtent(ball(20, 0.5));
  EXPECT_DOUBLE_EQ(e.smallestSpacing, 0.5);
  EXPECT_GT(e.meshedVolume, 0.8 * 4.0 / 3.0 * M_PI * std::pow(4.0, 3));  // radius 8 voxels = 4 mm
  EXPECT_LT(e.meshedVolume, 1.2 * 4.0 / 3.0 * M_PI * std::pow(4.0, 3));
}

TEST(ParameterRanges, DefaultsAndPresetsPass) {
  const LabelVolume v = ball(20, 1.0);
  for (const auto& name : presetNames()) {
    auto p = presetParameters(name);
    ASSERT_TRUE(p);
    EXPECT_TRUE(checkSizeParameters(p.value(), v).isOk()) << name;
  }
}

TEST(ParameterRanges, TinyValuesAreRefusedNamingTheRange) {
  const LabelVolume v = ball(14, 1.0);
  MeshingParameters p;
  p.volume.maxTetVolume = 1e-9;  // the case: ran for more than 300 s
  expectRefused(p, v, {"max_tet_volume", "1e-09", "ball.nrrd", "tets", "smallest useful value",
                       "50 M tets"});
  p = {};
  p.sizing.targetEdgeLength = 1e-9;  // the case: TetGen's child crashed
  expectRefused(p, v, {"target_edge_length", "1e-09", "ball.nrrd", "tets", "smallest useful value"});
  p = {};
  p.sizing.hMax = 1e-6;
  expectRefused(p, v, {"h_max", "1e-06", "smallest useful value"});
  p = {};
  p.sizing.hMin = 0.01;  // below 0.1 x the 1 mm spacing
  expectRefused(p, v, {"h_min", "0.01", "smallest voxel spacing", "h_min >= 0.1"});
  p = {};
  p.boundary.facetDistance = 1e-6;
  expectRefused(p, v, {"facet_distance", "1e-06", ">= 0.02"});
  // The floor, not the count, for a small volume: 0.08 mm edges on a 14^3 ball are about 12 M
  // tets, below the ceiling, but finer than a tenth of a voxel.
  p = {};
  p.sizing.targetEdgeLength = 0.08;
  expectRefused(p, v, {"target_edge_length", "0.1 x the smallest voxel spacing"});
}

TEST(ParameterRanges, ValuesAtTheBoundPass) {
  const LabelVolume v = ball(14, 1.0);
  MeshingParameters p;
  p.sizing.targetEdgeLength = 0.1;  // exactly the floor
  EXPECT_TRUE(checkSizeParameters(p, v).isOk());
  p = {};
  p.volume.maxTetVolume = v.labels.size() * 1.0 / kMaxEstimatedTets * 1.01 + 1e-3;
  EXPECT_TRUE(checkSizeParameters(p, v).isOk());
  p = {};
  p.boundary.facetDistance = 0;  // off
  p.sizing.hMin = 0;
  p.sizing.hMax = 0;
  EXPECT_TRUE(checkSizeParameters(p, v).isOk());
}

TEST(ParameterRanges, AutomaticSizeOfALargeVolumeCountsToo) {
  // 100^3 voxels all material: edge_length_factor 0.5 (its fixed minimum) means about 68 M tets.
  LabelVolume v = makeVolume(100, [](double, double, double) { return 1; });
  v.sourcePath = "block.nrrd";
  MeshingParameters p;
  p.sizing.edgeLengthFactor = 0.5;
  expectRefused(p, v, {"edge_length_factor", "0.5", "M tets", "edge_length_factor >="});
  p.sizing.edgeLengthFactor = 1.0;  // about 8.5 M tets
  EXPECT_TRUE(checkSizeParameters(p, v).isOk());
}

TEST(ParameterRanges, PipelineAndOptimizeRefuseBeforeAnyStage) {
  const LabelVolume v = ball(14, 1.0);
  MeshingParameters p;
  p.volume.maxTetVolume = 1e-9;
  std::vector<std::string> stages;
  RunContext ctx;
  ctx.setProgressCallback([&](const std::string& st, double, double) { stages.push_back(st); });
  const auto t0 = std::chrono::steady_clock::now();
  auto r = runPipeline(v, p, ctx);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.status().code(), ErrorCode::InvalidArgument);
  EXPECT_NE(r.status().message().find("max_tet_volume"), std::string::npos);
  EXPECT_TRUE(stages.empty()) << "a stage ran: " << stages.front();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);

  TetMesh mesh;  // never looked at: the parameters are refused first
  mesh.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.tets = {{0, 1, 2, 3}};
  mesh.tetLabels = {1};
  MeshingParameters q;
  q.sizing.targetEdgeLength = 1e-9;
  RunContext ctx2;
  auto o = optimizeMesh(v, mesh, q, ctx2);
  ASSERT_FALSE(o);
  EXPECT_EQ(o.status().code(), ErrorCode::InvalidArgument);
  EXPECT_NE(o.status().message().find("target_edge_length"), std::string::npos);
}
