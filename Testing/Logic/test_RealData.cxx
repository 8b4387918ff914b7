// SPDX-License-Identifier: GPL-3.0-or-later
// `femesher mesh` on every real label map in FEMESHER_DATA_DIR and on the phantom, with the
// foundation's acceptance invariants: labels present, conformal, no inverted tets, interfaces
// between different materials, voxel-centre agreement >= 0.85 (0.9) and volume Dice >= 0.85 for
// labels of >= 1,000 voxels, points within one voxel of the labels' physical extent.
#include "MeshInvariants.h"
#include "TetMeasures.h"

#include <femesher/Parameters.h>
#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/SurfaceSampling.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>

using namespace femesher;
using namespace femesher::testing;

namespace {

/// Volume Dice floor for labels of >= 1,000 voxels on every real volume. Measured 2026-11-24 with
/// the volume-preserving indicator functions: smallest 0.883 (frogtissue), knee 0.888 (its
/// lesions; 0.863 before the correction, which this floor would fail).
constexpr double kMinVolumeDice = 0.875;

struct Case {
  std::string file;
  int64_t minVoxels;
  double minDice = 0.85;  ///< voxel-centre agreement, for labels of >= 1,000 voxels
  /// Regression floor for the worst tet's smallest dihedral angle (degrees; issue 12). Measured
  /// 2026-11-24 on the written meshes (Testing/Benchmarks/judge_real_volumes.py) after the edge
  /// splits, two inserting rounds and TetGen's radius-edge bound 3, floors a little below:
  /// knee 9.20, phantom 13.4, mickey 14.81, spheres_argmax 12.73 (15.0 with the bound 2),
  /// example_seg 5.57, frogtissue 9.76, example_seg_dicom 6.78, digimouse 6.93, colin27 6.97.
  /// Runs are the same for every thread count, so the floors hold on any machine.
  /// 2026-11-25: TetGen's dihedral bound 3 (was 12) moved frogtissue to 9.55, mickey to 13.6 and
  /// the phantom to 12.8 and left the others where they were. Then the optimizer's off-interface
  /// moves (Optimize.h): knee 12.71, frogtissue 10.26, digimouse 10.58, example_seg_dicom 10.35,
  /// example_seg 6.32, mickey 14.9; colin27, spheres_argmax and the phantom unchanged.
  /// Session 12's particle spacing rule: colin27 8.28, digimouse 11.37, example_seg_dicom 11.11.
  /// 2026-11-25 (session 13): peeling flat caps on the volume's box (Optimize.h) leaves every
  /// default run's worst angle where it was except example_seg_dicom, 11.11 -> 10.60 (a cap of
  /// label 87 elsewhere, reached by the changed order of operations), floor 10.5.
  /// Session 14: long edge collapses within the facet distance, four inserting rounds and one
  /// 0.5 % volume budget per material: frogtissue 9.97 -> 11.00, example_seg_dicom 10.60 -> 12.84,
  /// example_seg 6.34 -> 6.83, phantom 14.6 -> 15.0; the others unchanged.
  /// Session 16: triple-line vertices may leave a line without a direction (a thin wedge between
  /// nearly parallel sheets), and triangles whose interface cannot be found are measured to the
  /// triple line: colin27 8.28 -> 10.41, example_seg 6.83 -> 11.29, knee 12.03 -> 13.83,
  /// digimouse 11.45 -> 11.85, frogtissue 11.00 -> 11.14; the others unchanged. Then junction
  /// points moving up to 0.95 facet distance in the last resort: frogtissue 11.14 -> 13.48.
  double minWorstAngle = 0;
  /// Ceiling on the number of tets (issue 13: fewer elements), a few per cent above the count
  /// measured 2026-11-25 with TetGen's dihedral bound 3: knee 506,594, colin27 2,773,833,
  /// digimouse 717,310, frogtissue 820,007, example_seg 63,050, example_seg_dicom 165,472,
  /// mickey 34,566, spheres_argmax 8,197 (with the bound 12: 11-26 % more). 0 = no ceiling.
  /// 2026-11-27 (session 19), the particle system's convergence: its population band keeps more
  /// particles, example_seg_dicom 164,962 -> 170,582 tets (ceiling 170,400 -> 175,700), the
  /// others -0.3 to +2.9 %, within their ceilings. Session 20 (the box's normal on its edges
  /// and corners): spheres_argmax 8,354 -> 8,461 (ceiling 8,450 -> 8,650).
  size_t maxTets = 0;
};

/// Issue 12: fewer than 0.5 % of the tets below 15 degrees on every real volume.
constexpr double kMaxShareBelow15 = 0.005;

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.file; }

void checkVolume(const LabelVolume& v, const MeshingParameters& p, const std::string& name,
                 double minDice = 0.85, PipelineResult* out = nullptr,
                 double minVolumeDice = kMinVolumeDice, double minWorstAngle = 0) {
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  ASSERT_TRUE(r.isOk()) << name << ": " << r.status().message();
  if (out) *out = r.value();
  const TetMesh& m = r->mesh;
  ASSERT_GT(m.tets.size(), 0u);
  expectConformal(m);
  expectWithinLabelExtent(m, v);

  std::map<int32_t, size_t> voxels;
  for (int32_t l : v.labels) ++voxels[l];
  const bool noBackground = !voxels.count(0);
  const auto present = meshLabels(m);
  for (const auto& [label, count] : voxels) {
    if (label == 0) continue;
    if (int64_t(count) >= p.preprocess.minVoxels)
      EXPECT_TRUE(present.count(label)) << name << ": label " << label << " (" << count
                                        << " voxels) is missing from the mesh";
  }
  ASSERT_TRUE(r->hasFidelity);
  std::string summary;
  for (const auto& mf : r->fidelity.materials) {
    if (mf.voxels >= 1000) {
      // The voxel-centre agreement (what the surface refinement aims at) and, honestly, the
      // volume Dice (today's floor on thin labels: the knee's lesions, 0.888).
      EXPECT_GE(mf.voxelCentreDice, minDice)
          << name << ": label " << mf.label << " (" << mf.voxels << " voxels)";
      EXPECT_GE(mf.dice, minVolumeDice)
          << name << ": label " << mf.label << " (" << mf.voxels << " voxels), volume Dice";
    }
    char buf[96];
    std::snprintf(buf, sizeof buf, " %d:%.3f", mf.label, mf.dice);
    summary += buf;
  }
  if (minDice >= 0.9) {
    // The particle path's target (issue 4): boundary distance mesh -> labels <= 1 voxel at p99.
    EXPECT_LE(r->fidelity.meshToLabels.p99, 1.0) << name;
  }
  size_t below10 = 0;
  const auto* md = r->quality.all.find("min_dihedral");
  ASSERT_NE(md, nullptr);
  below10 = md->badCount;
  if (minWorstAngle > 0) {  // the default-parameter runs with a quality floor
    EXPECT_GE(md->min, minWorstAngle) << name << ": the worst tet is flatter than before";
    EXPECT_LT(double(r->quality.minDihedralBelow15), kMaxShareBelow15 * double(m.tets.size()))
        << name << ": too many tets below 15 degrees";
  }
  double seconds = r->totalSeconds;
  std::printf("[real-data] %s: %zu tets, %zu vertices, %.1f s, min dihedral < 10deg: %.2f%%, "
              "Dice%s%s\n",
              name.c_str(), m.tets.size(), m.points.size(), seconds,
              100.0 * double(below10) / double(m.tets.size()), summary.c_str(),
              noBackground ? " (no background)" : "");
  for (const auto& t : r->timings) std::printf("[real-data]   %-20s %7.2f s\n", t.name.c_str(), t.seconds);
}

/// Reads the shared label map `file` into `out`; false when it is missing (a failure in CI) or
/// unreadable (a failure).
bool readShared(const std::string& file, LabelVolume& out) {
  const std::string path = dataFile(file);
  if (!std::filesystem::exists(path)) {
    if (inCI()) ADD_FAILURE() << "missing data file " << path;
    return false;
  }
  auto v = readLabelMap(path);
  if (!v.isOk()) {
    ADD_FAILURE() << v.status().message();
    return false;
  }
  out = std::move(v).value();
  return true;
}

class RealData : public ::testing::TestWithParam<Case> {};

}  // namespace

TEST_P(RealData, MeshesWithAllLabelsConformalAndFaithful) {
  const Case& c = GetParam();
  LabelVolume v;
  if (!readShared(c.file, v)) GTEST_SKIP() << "missing or unreadable " << c.file;
  MeshingParameters p;
  p.preprocess.minVoxels = c.minVoxels;
  PipelineResult r;
  checkVolume(v, p, c.file, c.minDice, &r, kMinVolumeDice, c.minWorstAngle);
  // Issue 13: the particle system reaches its criterion within its default budget (20).
  std::map<std::string, double> counts(r.counts.begin(), r.counts.end());
  EXPECT_EQ(counts["particle_converged"], 1.0)
      << c.file << ": the particle system stopped at its cap (" << counts["particle_iterations"]
      << " iterations)";
  if (c.maxTets > 0)
    EXPECT_LE(r.mesh.tets.size(), c.maxTets) << c.file << ": more tets than before";
}

// CGAL's 2 x 2 x 2 test images (min_voxels 1: at the default 10 no label is left and the run
// fails with a clear error): a mesh of 11-28 tets. Removing a flat tet on the box must not count
// the rest of so light a mesh as a speck it cuts off (2026-11-27: 12323 and 20012323 kept tets
// of 0.38 and 0.20 degrees; now 5.7 and 7.6).
TEST(RealDataTiny, CgalCellsKeepNoTetBelowTheWarningAngle) {
  for (const char* file : {"420.nrrd", "40420.nrrd", "12323.nrrd", "20012323.nrrd"}) {
    LabelVolume v;
    if (!readShared(file, v)) GTEST_SKIP() << "missing or unreadable " << file;
    MeshingParameters p;
    p.preprocess.minVoxels = 1;
    p.run.computeFidelity = false;
    RunContext ctx;
    auto r = runPipeline(v, p, ctx);
    ASSERT_TRUE(r.isOk()) << file << ": " << r.status().message();
    const TetMesh& m = r.value().mesh;
    ASSERT_FALSE(m.tets.empty()) << file;
    EXPECT_GE(femesher::test::minOver(m.points, m.tets), p.optimize.minDihedralWarning) << file;
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, RealData,
    ::testing::Values(Case{"420.nrrd", 1}, Case{"40420.nrrd", 1}, Case{"12323.nrrd", 1},
                      Case{"20012323.nrrd", 1}, Case{"mickey.nrrd", 10, 0.90, 14.9, 35600},
                      Case{"spheres_argmax.nrrd", 10, 0.90, 14.9, 8650},
                      Case{"colin27_v3.nrrd", 10, 0.90, 10.3, 2857000},
                      Case{"digimouse.nrrd", 10, 0.85, 11.8, 739000},
                      Case{"frogtissue.nrrd", 10, 0.85, 13.4, 845000},
                      Case{"example_seg.nii.gz", 10, 0.85, 11.2, 64950},
                      Case{"example_seg_dicom.nii.gz", 10, 0.85, 12.7, 175700},
                      Case{"9135902_00m_WB01.nii.gz", 10, 0.90, 13.7, 521800}),
    [](const ::testing::TestParamInfo<Case>& info) {
      std::string n = info.param.file;
      for (auto& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return n;
    });

TEST(RealDataPhantom, BuiltInPhantomMeshes) {
  const LabelVolume v = makePhantom();
  checkVolume(v, MeshingParameters{}, "phantom", 0.90, nullptr, kMinVolumeDice, 14.5);
}

// Issue 13: the presets mean something. On the phantom, coarse, default and fine span at least
// 4x in tets (measured 2026-11-25 with TetGen's dihedral bound 3 and fine's facet distance 0.3:
// 7.8k, 25.4k, 37.1k; on the knee 224k, 507k, 944k; 2026-11-24: 8.2k, 29.5k, 41.3k), each mesh
// keeps the invariants above, and the boundary follows the labels more closely from coarse to fine
// (mesh -> labels p99 0.55, 0.45, 0.36 voxel), coarse still within one voxel.
TEST(RealDataPhantom, PresetsSpanFourTimesInTetsAndOrderTheBoundaryAccuracy) {
  const LabelVolume v = makePhantom();
  std::map<std::string, PipelineResult> r;
  for (const std::string name : {"coarse", "default", "fine"}) {
    auto p = presetParameters(name);
    ASSERT_TRUE(p.isOk());
    checkVolume(v, p.value(), "phantom " + name, 0.85, &r[name]);
    if (::testing::Test::HasFatalFailure()) return;
  }
  const double coarse = double(r["coarse"].mesh.tets.size()),
               normal = double(r["default"].mesh.tets.size()),
               fine = double(r["fine"].mesh.tets.size());
  EXPECT_LT(coarse, normal);
  EXPECT_LT(normal, fine);
  EXPECT_GE(fine, 4 * coarse);
  EXPECT_LE(r["coarse"].fidelity.meshToLabels.p99, 1.0);
  EXPECT_LT(r["fine"].fidelity.meshToLabels.p99, r["default"].fidelity.meshToLabels.p99);
  EXPECT_LT(r["default"].fidelity.meshToLabels.p99, r["coarse"].fidelity.meshToLabels.p99);
}

// The local Delaunay surface mesher (surface_mesher=ldt) on real data: no hole left, the LDT
// surface really used (no fall-back to the restricted Delaunay surface), a valid PLC, the same mesh
// invariants as above, and the restricted-Delaunay closure kept to a small share of triangles.
// A missing data file is a failure here.
namespace {

/// `mayFallBack`: the local Delaunay surface may leave holes (then the run's documented fall-back
/// is checked instead).
void checkLdt(const LabelVolume& v, const std::string& name, bool mayFallBack = false) {
  MeshingParameters p;
  p.boundary.mesher = SurfaceMesher::LocalDelaunay;
  PipelineResult r;
  // The local Delaunay surface is made of the particles alone (no refinement points): by volume
  // it is less faithful on the knee's lesions (label 7: 0.83 against 0.86 by default).
  checkVolume(v, p, name, 0.90, &r, 0.80);
  if (::testing::Test::HasFatalFailure()) return;
  std::map<std::string, double> c(r.counts.begin(), r.counts.end());
  if (mayFallBack && c["ldt_used"] == 0.0) {
    // The documented fall-back: the restricted Delaunay surface, watertight, with a warning.
    EXPECT_GT(c["ldt_open_edges"] + c["ldt_self_intersections"], 0.0) << name;
    EXPECT_NE(r.reportJson.find("\"surface_mesher_used\": \"delaunay (ldt surface not watertight)\""),
              std::string::npos)
        << name;
    EXPECT_NE(r.reportJson.find("restricted Delaunay surface (watertight) is used instead"),
              std::string::npos)
        << name << ": no warning";
    EXPECT_EQ(c["surface_open_edges"], 0.0) << name;
    std::printf("[real-data] %s ldt: %.0f open edges left, fell back to the restricted Delaunay "
                "surface\n",
                name.c_str(), c["ldt_open_edges"]);
    return;
  }
  EXPECT_EQ(c["ldt_open_edges"], 0.0) << name;
  EXPECT_EQ(c["ldt_used"], 1.0) << name;
  EXPECT_NE(r.reportJson.find("\"surface_mesher_used\": \"ldt\""), std::string::npos) << name;
  EXPECT_EQ(c["ldt_self_intersections"], 0.0) << name;
  EXPECT_EQ(c["surface_open_edges"], 0.0) << name;
  EXPECT_EQ(c["surface_triangles"], c["ldt_triangles"]) << name;
  const double total = c["ldt_triangles"];
  EXPECT_EQ(c["ldt_triangles_from_stars"] + c["ldt_triangles_from_single_vote"] +
                c["ldt_triangles_from_loop_fill"] + c["ldt_triangles_from_restricted"],
            total)
      << name;
  EXPECT_LE(c["ldt_triangles_from_restricted"], 0.05 * total) << name;
  EXPECT_GE(c["ldt_triangles_from_stars"], 0.9 * total) << name;
  std::printf(
      "[real-data] %s ldt: %.0f triangles (%.0f stars, %.0f single vote, %.0f loop fill, "
      "%.0f restricted); open edges before filling %.0f\n",
      name.c_str(), total, c["ldt_triangles_from_stars"], c["ldt_triangles_from_single_vote"],
      c["ldt_triangles_from_loop_fill"], c["ldt_triangles_from_restricted"],
      c["ldt_open_edges_before_filling"]);
}

class RealDataLdt : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(RealDataLdt, LocalDelaunaySurfaceIsWatertightAndUsed) {
  const std::string path = dataFile(GetParam());
  ASSERT_TRUE(std::filesystem::exists(path)) << "missing data file " << path;
  auto v = readLabelMap(path);
  ASSERT_TRUE(v.isOk()) << v.status().message();
  // spheres_argmax: its hole filling leaves open edges for some particle seeds (2026-11-27, seeds
  // 1-6: with session 19's particle system at 3, 4, 5; with the converging one at 1, 2, 3, 5;
  // 7-24 edges each), so there the fall-back is what is checked when it happens.
  checkLdt(v.value(), GetParam(), GetParam() == "spheres_argmax.nrrd");
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealDataLdt,
                         ::testing::Values("mickey.nrrd", "spheres_argmax.nrrd",
                                           "9135902_00m_WB01.nii.gz"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string n = info.param;
                           for (auto& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

TEST(RealDataLdtPhantom, BuiltInPhantomLocalDelaunaySurface) { checkLdt(makePhantom(), "phantom"); }

// The surface refinement once depended on which of a facet's two Delaunay cells CGAL reported it
// from (heap addresses), so the same knee gave a slightly different surface from run to run. The
// boundary mesh (with facet-distance, voxel-centre and junction refinement) is built twice here,
// the second time with a differently laid-out heap, and must come out identical.
TEST(RealDataDeterminism, KneeBoundaryMeshIndependentOfHeapLayout) {
  const std::string path = dataFile("9135902_00m_WB01.nii.gz");
  ASSERT_TRUE(std::filesystem::exists(path)) << "missing data file " << path;
  auto v = readLabelMap(path);
  ASSERT_TRUE(v.isOk()) << v.status().message();
  RunContext ctx;
  ctx.setThreads(2);
  const PreprocessedVolume vol = preprocessLabels(v.value(), {}, ctx);
  const IndicatorField field = computeIndicatorFunctions(vol, {}, ctx);
  const double h = 3 * (vol.spacing[0] + vol.spacing[1] + vol.spacing[2]) / 3;
  const SizingFunction sizing = [h](const Vec3&) { return h; };
  SurfaceSamplingParameters sp;
  sp.targetEdgeLength = h;
  const SurfaceSamples samples = sampleInterfaces(field, v.value(), sp, ctx);
  const Junctions junctions = findJunctions(field, sizing, {}, ctx);
  std::vector<Vec3> points;
  for (const auto& j : junctions.particles) points.push_back(j.local);
  for (uint32_t i : samples.selected) points.push_back(samples.all[i].local);
  BoundaryMeshParameters bp;
  bp.facetDistance = 0.5;  // voxels
  const BoundarySurface a = buildBoundaryMesh(field, points, samples, &junctions, bp, ctx);
  std::vector<std::unique_ptr<char[]>> junk;
  for (size_t i = 0; i < 20000; ++i) junk.emplace_back(new char[16 + (i * 7919) % 150000]);
  for (size_t i = 0; i < junk.size(); i += 3) junk[i].reset();
  const BoundarySurface b = buildBoundaryMesh(field, points, samples, &junctions, bp, ctx);
  EXPECT_GT(a.refinementPoints + a.voxelCentrePoints, 0u);
  EXPECT_EQ(a.refinementPoints, b.refinementPoints);
  EXPECT_EQ(a.voxelCentrePoints, b.voxelCentrePoints);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.triangles, b.triangles);
}

// Issue 4: the triple lines appear as mesh edges. Share of the junction particles (triple-line
// points and quadruple points, sampled by the Junctions stage) that are vertices of an edge shared
// by the interface triangles of three or more materials, in the surface handed to TetGen (run
// report count junction_particles_on_triple_edges), with default parameters. No particle is
// excluded from the measure.
// Measured before the wedge refinement in BoundaryMesh.cxx (points on the interfaces bounding a
// material missing around a junction particle, and on the line next to it): phantom 1.000,
// mickey 1.000, spheres_argmax 0.994 (159 of 160), knee 0.966 (2362 of 2444), colin27 0.934
// (14126 of 15128); after: 1.000, 1.000, 1.000, 0.9996 (2443 of 2444), 1.000 (15128). The knee's
// last one has its wedge points inserted but the background wedge there stays too short along
// the line. With the junction refinement switched off, the knee (0.957) and spheres_argmax
// (0.994) fail this test; phantom and mickey (1.000) pass without it.
namespace {

constexpr double kMinJunctionShare = 0.998;
// Since the volume-preserving correction of the indicator functions (IndicatorFunctions.h):
// phantom, mickey and the knee 1.000, colin27 0.9994, spheres_argmax 0.988 (164 of 166). The two
// spheres_argmax particles miss a material around them whose wedge the refinement cannot reach:
// every wedge point it finds is within a quarter voxel of a vertex already there, at every radius
// (FEMESHER_DEBUG shows "2 with a material missing around them, 0 points inserted"). Its floor is
// that figure, not 0.998, until the refinement handles it.
// 2026-11-27 (session 20, the particle system that converges): spheres_argmax 0.982 (163 of 166)
// for seed 1, 0.988 for seeds 2-5 (session 19's system: 0.988, 0.994 for seed 2); floor 0.98.
double minJunctionShare(const std::string& name) {
  return name == "spheres_argmax.nrrd" ? 0.98 : kMinJunctionShare;
}

void checkJunctionEdges(const LabelVolume& v, const std::string& name) {
  RunContext ctx;
  MeshingParameters p;
  p.run.computeFidelity = false;
  auto r = runPipeline(v, p, ctx);
  ASSERT_TRUE(r.isOk()) << name << ": " << r.status().message();
  std::map<std::string, double> c(r->counts.begin(), r->counts.end());
  ASSERT_TRUE(c.count("junction_particles_on_triple_edges")) << name;
  ASSERT_GT(c["junction_particles"], 0.0) << name << ": no junctions found";
  EXPECT_GE(c["junction_particles_on_triple_edges"], minJunctionShare(name))
      << name << ": " << c["junction_particles"] << " junction particles";
  std::printf(
      "[real-data] %s: %.0f junction particles, %.4f on triple edges, %.0f refinement "
      "points, %zu tets\n",
      name.c_str(), c["junction_particles"], c["junction_particles_on_triple_edges"],
      c["junction_refinement_points"], r->mesh.tets.size());
}

class RealDataJunctions : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(RealDataJunctions, TripleLinesAreMeshEdges) {
  LabelVolume v;
  if (!readShared(GetParam(), v)) GTEST_SKIP() << "missing or unreadable " << GetParam();
  checkJunctionEdges(v, GetParam());
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealDataJunctions,
                         ::testing::Values("mickey.nrrd", "spheres_argmax.nrrd",
                                           "9135902_00m_WB01.nii.gz", "colin27_v3.nrrd"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string n = info.param;
                           for (auto& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

TEST(RealDataJunctionsPhantom, BuiltInPhantomTripleLinesAreMeshEdges) {
  checkJunctionEdges(makePhantom(), "phantom");
}
