// SPDX-License-Identifier: GPL-3.0-or-later
// The code that connects the stages (MeshingRun): stage order and skipping, what `femesher sizing`
// writes against what the mesh run used, material exclusion end to end.
#include "MeshInvariants.h"

#include <femesher/MeshingRun.h>
#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/StageTable.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/io/MeshIO.h>

#include <itkImage.h>
#include <itkImageFileReader.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

using namespace femesher;
using namespace femesher::testing;

namespace {

/// The phantom in an oblique, left-handed frame with a far origin: every frame conversion shows.
LabelVolume obliquePhantom() {
  LabelVolume v = makePhantom();
  const double c = std::cos(0.4), s = std::sin(0.4);
  v.direction = {c, -s, 0, s, c, 0, 0, 0, -1};
  v.origin = {-31.5, 12.25, 80.0};
  return v;
}

double total(const std::map<int32_t, double>& volumes) {
  double t = 0;
  for (const auto& [label, v] : volumes) t += v;
  return t;
}

/// The phantom meshed with `key` = `value` on top of `base`.
PipelineResult meshWith(const LabelVolume& v, MeshingParameters p, const std::string& key,
                        const std::string& value) {
  EXPECT_TRUE(setParameter(p, key, value).isOk()) << key;
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  return r.isOk() ? std::move(r.value()) : PipelineResult{};
}

}  // namespace

TEST(MeshingRun, StagesRunInTableOrderAndStopWhereAsked) {
  const LabelVolume v = makePhantom();
  RunContext ctx;
  MeshingParameters p;
  MeshingRun run(v, p, ctx);
  run.runThrough(StageId::SizingField);
  const auto& s = run.state();
  ASSERT_EQ(s.timings.size(), 4u);
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(s.timings[i].name, stageTable()[i].key);
  ASSERT_TRUE(s.sizingField);
  EXPECT_GT(s.medialVoxels, 0u);
  EXPECT_TRUE(s.samples.all.empty());  // SurfaceSampling has not run
  // The sizing function reads the field in the working grid's own frame.
  const Vec3 centre = s.grid.localToCanonical({s.grid.dims[0] / 2.0, s.grid.dims[1] / 2.0,
                                               s.grid.dims[2] / 2.0});
  EXPECT_FLOAT_EQ(float(s.sizing(centre)), s.sizingField->at(s.grid.canonicalToGridMm(centre)));
  run.runThrough(StageId::Junctions);
  EXPECT_EQ(run.state().timings.size(), 6u);
  EXPECT_FALSE(run.state().samples.selected.empty());

  // Uniform sizing skips the medial axis and the sizing field; the size is the edge length.
  MeshingParameters u;
  u.sizing.mode = SizingMode::Uniform;
  RunContext ctx2;
  MeshingRun uniform(v, u, ctx2);
  uniform.runThrough(StageId::SurfaceSampling);
  ASSERT_EQ(uniform.state().timings.size(), 3u);
  EXPECT_EQ(uniform.state().timings[2].name, "SurfaceSampling");
  EXPECT_FALSE(uniform.state().sizingField);
  EXPECT_DOUBLE_EQ(uniform.state().sizing({1, 2, 3}), uniform.state().edgeLength);
  EXPECT_DOUBLE_EQ(uniform.state().edgeLength, uniformEdgeLength(v, u.sizing));
}

TEST(MeshingRun, InvalidParametersAreRefusedBeforeAnyStage) {
  const LabelVolume v = makePhantom();
  RunContext ctx;
  MeshingParameters p;
  p.volume.maxRadiusEdgeRatio = 0.5;
  try {
    MeshingRun run(v, p, ctx);
    FAIL() << "accepted max_radius_edge_ratio 0.5";
  } catch (const Error& e) {
    EXPECT_EQ(e.status().code(), ErrorCode::InvalidArgument);
  }
  auto r = runPipeline(v, p, ctx);
  EXPECT_EQ(r.status().code(), ErrorCode::InvalidArgument);
}

TEST(MeshingRun, PropertiesForAbsentLabelsAreRefusedBeforeAnyStage) {
  LabelVolume v = makePhantom();
  v.sourcePath = "phantom.nrrd";
  RunContext ctx;
  MeshingParameters p;
  ASSERT_TRUE(setParameter(p, "material.5.E", "110000").isOk());
  ASSERT_TRUE(setParameter(p, "material.12.E", "5").isOk());
  auto r = runPipeline(v, p, ctx);
  ASSERT_EQ(r.status().code(), ErrorCode::InvalidArgument);
  EXPECT_NE(r.status().message().find("'phantom.nrrd' has no label 12"), std::string::npos)
      << r.status().message();
  EXPECT_NE(r.status().message().find("labels 1, 2, 3, 4, 5"), std::string::npos);
  EXPECT_TRUE(ctx.warnings().empty());  // refused before the first stage
  // Background 0 is not a material either.
  MeshingParameters q;
  ASSERT_TRUE(setParameter(q, "material.0.name", "air").isOk());
  EXPECT_THROW(MeshingRun(v, q, ctx), Error);
}

TEST(MeshingRun, CliSizingWritesTheFieldTheMeshRunUses) {
  const std::string dir = std::string(FEMESHER_TEST_TMP_DIR) + "/meshing_run";
  std::filesystem::create_directories(dir);
  const std::string in = dir + "/oblique_phantom.nrrd", out = dir + "/sizing.nrrd";
  ASSERT_TRUE(writeLabelMap(obliquePhantom(), in).isOk());
  auto volume = readLabelMap(in);
  ASSERT_TRUE(volume.isOk());
  MeshingParameters p;
  p.sizing.scale = 0.9;  // a non-default value must reach both
  p.run.computeFidelity = false;
  RunContext ctx;
  auto mesh = runPipeline(volume.value(), p, ctx);
  ASSERT_TRUE(mesh.isOk()) << mesh.status().message();
  ASSERT_TRUE(mesh->sizingField);

  std::filesystem::remove(out);
  const std::string cmd = std::string(FEMESHER_CLI) + " sizing " + in + " -o " + out +
                          " --set sizing_scale=0.9 2>/dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  using Image = itk::Image<float, 3>;
  auto reader = itk::ImageFileReader<Image>::New();
  reader->SetFileName(out);
  reader->Update();
  const Image* img = reader->GetOutput();
  const auto size = img->GetLargestPossibleRegion().GetSize();
  const LabelVolume& g = mesh->sizingGeometry;
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(int(size[a]), g.dims[a]);
    EXPECT_NEAR(img->GetSpacing()[a], g.spacing[a], 1e-9);
    EXPECT_NEAR(img->GetOrigin()[a], g.origin[a], 1e-6);
    for (int b = 0; b < 3; ++b)
      EXPECT_NEAR(img->GetDirection()[a][b], g.direction[size_t(3 * a + b)], 1e-9);
  }
  // The working grid's voxel (0,0,0) sits where the input's voxel `offset` is.
  // The run keeps its field packed (bricks of one value where it is constant).
  EXPECT_TRUE(mesh->sizingField->h.empty());
  const std::vector<float> used = mesh->sizingField->values();
  ASSERT_EQ(used.size(), size_t(size[0] * size[1] * size[2]));
  const float* values = img->GetBufferPointer();
  size_t differing = 0;
  for (size_t i = 0; i < used.size(); ++i) differing += values[i] != used[i];
  EXPECT_EQ(differing, 0u) << "femesher sizing wrote another field than the mesh run used";

  // `femesher medial-axis` writes the axes of that run, on the same grid.
  const std::string axesPath = dir + "/axes.nrrd";
  std::filesystem::remove(axesPath);
  const std::string ma = std::string(FEMESHER_CLI) + " medial-axis " + in + " -o " + axesPath +
                         " 2>/dev/null";
  ASSERT_EQ(std::system(ma.c_str()), 0) << ma;
  auto axes = readLabelMap(axesPath);
  ASSERT_TRUE(axes.isOk()) << axes.status().message();
  EXPECT_EQ(axes->dims, g.dims);
  const size_t medial = size_t(std::count_if(axes->labels.begin(), axes->labels.end(),
                                             [](int32_t l) { return l != -1; }));
  double reported = -1;
  for (const auto& [k, x] : mesh->counts)
    if (k == "medial_axis_voxels") reported = x;
  EXPECT_EQ(double(medial), reported);
}

TEST(MeshingRun, ExcludedMaterialsMergeOrLeaveACavity) {
  const LabelVolume v = makePhantom();
  MeshingParameters base;
  base.run.computeFidelity = false;
  const auto v0 = labelVolumes(meshWith(v, base, "min_voxels", "10").mesh);
  ASSERT_TRUE(v0.count(3));

  // Marrow (3) merged: gone from the mesh, its volume joins its neighbours, total kept.
  const PipelineResult merged = meshWith(v, base, "material.3.exclude", "merge");
  const auto v1 = labelVolumes(merged.mesh);
  EXPECT_FALSE(v1.count(3));
  EXPECT_NEAR(total(v1), total(v0), 0.01 * total(v0));
  EXPECT_EQ(merged.excludedLabels, std::vector<int32_t>{3});
  bool named = false;
  for (const auto& w : merged.warnings)
    named |= w.find("merged into its neighbours") != std::string::npos &&
             w.find("label 2") != std::string::npos;
  EXPECT_TRUE(named) << "the warning must name the material the marrow joined";
  expectConformal(merged.mesh);

  // Marrow as background: a cavity of about its volume.
  const auto v2 = labelVolumes(meshWith(v, base, "material.3.exclude", "background").mesh);
  EXPECT_FALSE(v2.count(3));
  EXPECT_NEAR(total(v0) - total(v2), v0.at(3), 0.05 * v0.at(3));

  // Everything excluded: a clear error, not an empty mesh.
  MeshingParameters none = base;
  for (int l = 1; l <= 5; ++l)
    ASSERT_TRUE(setParameter(none, "material." + std::to_string(l) + ".exclude", "background").isOk());
  RunContext c3;
  auto empty = runPipeline(v, none, c3);
  EXPECT_EQ(empty.status().code(), ErrorCode::EmptyLabelMap);
  EXPECT_NE(empty.status().message().find("excluded"), std::string::npos);
}

// `femesher optimize`: TetGen's mesh of the phantom (Optimize off), written and read back, then
// improved on its own: the worst angle only rises, fewer tets below the target, conformal,
// material volumes kept; a mesh from another label map is refused.
TEST(MeshingRun, OptimizeImprovesAnExistingMesh) {
  const std::string dir = std::string(FEMESHER_TEST_TMP_DIR) + "/meshing_run";
  std::filesystem::create_directories(dir);
  const LabelVolume v = obliquePhantom();
  MeshingParameters raw;
  raw.optimize.targetMinDihedral = 0;
  raw.run.computeFidelity = false;
  RunContext c0;
  auto tetgen = runPipeline(v, raw, c0);
  ASSERT_TRUE(tetgen.isOk()) << tetgen.status().message();
  const std::string path = dir + "/unoptimized.vtu";
  ASSERT_TRUE(writeMesh(tetgen->mesh, path, ExportOptions{}).isOk());
  auto back = readMesh(path);
  ASSERT_TRUE(back.isOk()) << back.status().message();

  MeshingParameters p;
  p.run.computeFidelity = false;
  RunContext c1;
  auto improved = optimizeMesh(v, back.value(), p, c1);
  ASSERT_TRUE(improved.isOk()) << improved.status().message();
  const QualityReport& before = tetgen->quality;
  const QualityReport& after = improved->quality;
  EXPECT_GE(after.all.find("min_dihedral")->min, before.all.find("min_dihedral")->min);
  EXPECT_LT(after.minDihedralBelow15, before.minDihedralBelow15);
  expectConformal(improved->mesh);
  const auto v0 = labelVolumes(tetgen->mesh), v1 = labelVolumes(improved->mesh);
  ASSERT_EQ(v0.size(), v1.size());
  for (const auto& [label, x] : v0) EXPECT_NEAR(v1.at(label), x, 0.005 * x) << "label " << label;
  // The same improvement as the Optimize stage of a full run: the file's round trip through the
  // oblique physical frame moves points by round-off, which tips a few borderline peels and flips.
  RunContext c2;
  MeshingParameters full = p;
  auto direct = runPipeline(v, full, c2);
  ASSERT_TRUE(direct.isOk());
  EXPECT_NEAR(double(direct->mesh.tets.size()), double(improved->mesh.tets.size()),
              2e-3 * double(direct->mesh.tets.size()));
  EXPECT_NEAR(direct->quality.minDihedralBelow15, after.minDihedralBelow15,
              0.2 * double(direct->quality.minDihedralBelow15) + 5);

  // Another label map: refused with a message naming it.
  LabelVolume other = makePhantom();
  other.origin = {500, 500, 500};
  other.sourcePath = "elsewhere.nrrd";
  RunContext c3;
  auto wrong = optimizeMesh(other, back.value(), p, c3);
  EXPECT_EQ(wrong.status().code(), ErrorCode::InvalidArgument);
  EXPECT_NE(wrong.status().message().find("elsewhere.nrrd"), std::string::npos);
}

// What the later stages no longer read goes when its last reader is done: the labelled Delaunay
// with the volume mesh (handed to VolumeMesh, which releases it before TetGen runs), and, for a
// caller that keeps no curving data, the indicator functions with Optimize and the canonical
// volume mesh once the physical one is made (unless element_order 2 curves with them at export).
// Same mesh and same figures as a run that keeps them.
TEST(MeshingRun, ReleasesTheDelaunayAndTheFieldOnceNothingReadsThem) {
  const LabelVolume v = makePhantom();
  MeshingParameters p;
  RunContext keepCtx, freeCtx;
  MeshingRun keep(v, p, keepCtx), freed(v, p, freeCtx);
  freed.dropCurvingInputs(true);
  keep.runThrough(StageId::BoundaryMesh);
  ASSERT_TRUE(keep.state().surface.surface.delaunay);
  keep.runThrough(StageId::Fidelity);
  freed.runThrough(StageId::Optimize);
  EXPECT_FALSE(freed.state().surface.surface.delaunay);
  EXPECT_FALSE(freed.state().field);
  freed.runThrough(StageId::Fidelity);
  EXPECT_TRUE(keep.state().field) << "kept without dropCurvingInputs";
  EXPECT_TRUE(freed.state().volumeMesh.tets.empty() && freed.state().volumeMesh.points.empty());
  EXPECT_FALSE(keep.state().volumeMesh.tets.empty());
  EXPECT_EQ(freed.state().mesh.points, keep.state().mesh.points);
  EXPECT_EQ(freed.state().mesh.tets, keep.state().mesh.tets);
  EXPECT_EQ(freed.state().mesh.tetLabels, keep.state().mesh.tetLabels);
  const auto& a = freed.state().fidelity.materials;
  const auto& b = keep.state().fidelity.materials;
  ASSERT_EQ(a.size(), b.size());
  for (size_t m = 0; m < a.size(); ++m) EXPECT_EQ(a[m].dice, b[m].dice) << a[m].label;
  EXPECT_EQ(freed.state().fidelity.meshToLabels.p99, keep.state().fidelity.meshToLabels.p99);

  // element_order 2 curves with the field after the last stage: it stays.
  MeshingParameters q = p;
  q.elementOrder = 2;
  RunContext qCtx;
  MeshingRun quadratic(v, q, qCtx);
  quadratic.dropCurvingInputs(true);
  quadratic.runThrough(StageId::Fidelity);
  EXPECT_TRUE(quadratic.state().field);
  quadratic.prepareExport();
  ASSERT_TRUE(quadratic.state().midEdgeNodes);
  EXPECT_FALSE(quadratic.state().midEdgeNodes->empty());
}
