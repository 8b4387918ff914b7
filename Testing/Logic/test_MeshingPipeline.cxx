// SPDX-License-Identifier: GPL-3.0-or-later
// The meshing path on generated label maps: invariants, geometry handling, cancel, determinism.
#include "MeshInvariants.h"
#include "TestShapes.h"

#include <femesher/Pipeline.h>
#include <femesher/stages/Fidelity.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <map>
#include <cmath>
#include <thread>

using namespace femesher;
using namespace femesher::testing;

using test::ballsInShell;

TEST(MeshingPipeline, TwoBallsInAShellAreConformalAndFaithful) {
  const LabelVolume v = ballsInShell(40);
  MeshingParameters p;
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const TetMesh& m = r->mesh;
  expectConformal(m);
  expectWithinLabelExtent(m, v);
  EXPECT_EQ(meshLabels(m), (std::set<int32_t>{1, 2, 3}));
  ASSERT_TRUE(r->hasFidelity);
  for (const auto& mf : r->fidelity.materials) EXPECT_GE(mf.dice, 0.9) << "label " << mf.label;
  EXPECT_TRUE(r->fidelity.missingLabels.empty());
  // Interfaces between the two balls and between balls and shell exist.
  std::set<std::pair<int, int>> pairs;
  for (const auto& t : extractInterfaces(m)) pairs.insert({t.labelA, t.labelB});
  EXPECT_TRUE(pairs.count({1, 2}));
  EXPECT_TRUE(pairs.count({1, 3}));
  EXPECT_TRUE(pairs.count({2, 3}));
  EXPECT_TRUE(pairs.count({3, kExteriorLabel}));
  EXPECT_FALSE(pairs.count({1, kExteriorLabel}));  // the balls are enclosed by the shell
  EXPECT_NE(r->reportJson.find("\"stages\""), std::string::npos);
}

TEST(MeshingPipeline, ObliqueLeftHandedAnisotropicGeometryIsKept) {
  // Rotated by 0.21 rad about z and point-mirrored: det = -1.
  const LabelVolume v = test::obliqueLeftHanded(ballsInShell(32), {0.7, 0.36, 0.36},
                                                {-24.0, 51.8, -57.1}, 0.21, 0, {-1, -1, -1});
  ASSERT_LT(v.directionDeterminant(), 0);
  RunContext ctx;
  auto r = runPipeline(v, MeshingParameters{}, ctx);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  expectConformal(r->mesh);
  expectWithinLabelExtent(r->mesh, v);
  for (const auto& mf : r->fidelity.materials) EXPECT_GE(mf.dice, 0.85) << "label " << mf.label;
}

TEST(MeshingPipeline, LabelMapWithoutBackgroundMeshesTheWholeBox) {
  const LabelVolume v = test::ballsInShellWithoutBackground(24);
  RunContext ctx;
  auto r = runPipeline(v, MeshingParameters{}, ctx);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(meshLabels(r->mesh), (std::set<int32_t>{1, 2, 3, 4}));
  double volume = 0;
  for (size_t t = 0; t < r->mesh.tets.size(); ++t) volume += r->mesh.tetVolume(t);
  // The voxels fill a 24^3 mm box (faces half a voxel beyond the outer centres): the box is
  // exact, so the mesh fills it but for what the surface sampling cuts off along its edges.
  EXPECT_NEAR(volume, 24.0 * 24 * 24, 0.01 * 24 * 24 * 24);
  // Vertices of the outer boundary near the box lie exactly on it (before the box was exact they
  // sat 0.0003-0.2 voxel inside along its rounded edges), and none is outside it. (Some lie well
  // inside, where the shell comes within one voxel of the box face: that thin layer is not
  // resolved everywhere at this element size.)
  size_t offBox = 0, outside = 0;
  for (const auto& tri : extractInterfaces(r->mesh)) {
    if (tri.labelB != kExteriorLabel) continue;
    for (int32_t vi : tri.v) {
      const Vec3& q = r->mesh.points[size_t(vi)];
      double nearest = 1e300;
      for (int a = 0; a < 3; ++a)
        nearest = std::min({nearest, std::fabs(q[a] + 0.5), std::fabs(q[a] - 23.5)});
      offBox += nearest > 1e-6 && nearest < 0.1;
    }
  }
  for (const auto& q : r->mesh.points)
    for (int a = 0; a < 3; ++a) outside += q[a] < -0.5 - 1e-9 || q[a] > 23.5 + 1e-9;
  EXPECT_EQ(offBox, 0u) << "outer boundary vertices just off the box faces";
  EXPECT_EQ(outside, 0u);
  expectConformal(r->mesh);
}

TEST(MeshingPipeline, TinyLabelsArePresentOrReported) {
  LabelVolume v = ballsInShell(30);
  // A 2x2x2 label inside ball 1 and a 1-voxel label in the shell.
  for (int k = 10; k < 12; ++k)
    for (int j = 14; j < 16; ++j)
      for (int i = 8; i < 10; ++i) v.labels[v.index(i, j, k)] = 8;
  v.labels[v.index(15, 15, 2)] = 9;
  MeshingParameters p;
  p.preprocess.minVoxels = 1;
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const auto labels = meshLabels(r->mesh);
  EXPECT_TRUE(labels.count(8));
  EXPECT_TRUE(labels.count(9));
  expectConformal(r->mesh);
}

TEST(MeshingPipeline, SameSeedSameMesh) {
  const LabelVolume v = ballsInShell(28);
  MeshingParameters p;
  p.run.threads = 2;
  RunContext c1, c2;
  auto a = runPipeline(v, p, c1);
  auto b = runPipeline(v, p, c2);
  ASSERT_TRUE(a.isOk() && b.isOk());
  for (size_t i = 0; i < a->counts.size(); ++i)
    EXPECT_EQ(a->counts[i].second, b->counts[i].second) << a->counts[i].first;
  EXPECT_EQ(a->mesh.tets, b->mesh.tets);
  EXPECT_EQ(a->mesh.points, b->mesh.points);
}

TEST(MeshingPipeline, CancelFromAnotherThreadStopsWithinASecond) {
  const LabelVolume v = ballsInShell(96);
  RunContext ctx;
  std::atomic<bool> started{false};
  ctx.setProgressCallback([&](const std::string&, double, double) { started = true; });
  Result<PipelineResult> r(ErrorCode::Internal, "not run");
  std::chrono::steady_clock::time_point canceledAt, returnedAt;
  std::thread worker([&] {
    r = runPipeline(v, MeshingParameters{}, ctx);
    returnedAt = std::chrono::steady_clock::now();
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  canceledAt = std::chrono::steady_clock::now();
  ctx.cancel();
  worker.join();
  ASSERT_FALSE(r.isOk());
  EXPECT_EQ(r.status().code(), ErrorCode::Canceled);
  // No wall-clock assertion (shared machines); the latency is recorded for the log.
  RecordProperty("cancel_latency_ms",
                 int(std::chrono::duration<double, std::milli>(returnedAt - canceledAt).count()));
}

TEST(MeshingPipeline, ProgressIsMonotone) {
  const LabelVolume v = ballsInShell(24);
  RunContext ctx;
  std::vector<double> totals;
  ctx.setProgressCallback([&](const std::string&, double, double t) { totals.push_back(t); });
  auto r = runPipeline(v, MeshingParameters{}, ctx);
  ASSERT_TRUE(r.isOk());
  ASSERT_GT(totals.size(), 5u);
  for (size_t i = 1; i < totals.size(); ++i) EXPECT_GE(totals[i], totals[i - 1] - 1e-12);
  EXPECT_NEAR(totals.back(), 1.0, 1e-9);
}
