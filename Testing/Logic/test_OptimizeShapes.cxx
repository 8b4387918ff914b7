// SPDX-License-Identifier: GPL-3.0-or-later
// Issue 12, item 5: the Optimize stage on the generated shapes the issue names (touching spheres,
// three slabs on a line, four materials at a point, a one-voxel plate, a thin rod, materials cut
// by the volume box, nested thin shells), each through the whole pipeline at default settings with
// Optimize on and off: the mesh stays conformal, no tet has zero or negative volume, every
// material is still there with its volume within 0.5 %,
// the worst angle only rises and stays above its measured floor, and the run is
// the same twice for the same seed and thread count.

#include "MeshInvariants.h"
#include "TestShapes.h"
#include "TetMeasures.h"

#include <femesher/Pipeline.h>
#include <femesher/RunContext.h>
#include <femesher/stages/Optimize.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

using namespace femesher;
using namespace femesher::testing;
using femesher::test::minOver;

namespace {

struct Shape {
  std::string name;
  LabelVolume volume;
  /// Regression floor for the optimised worst angle (degrees), a little below what was measured
  /// on 2026-11-25 (2 threads; the runs do not depend on the machine).
  double minWorst = 0;
  /// Largest relative change of a material's volume (issue 12: 0.5 %).
  double maxVolumeChange = 5e-3;
  /// The run's facet_angle (degrees; 0 = the default, off).
  double facetAngle = 0;
};

std::ostream& operator<<(std::ostream& os, const Shape& s) { return os << s.name; }

std::vector<Shape> shapes() {
  using namespace femesher::test;
  // Measured worst angle without -> with Optimize (2026-11-27, with the rounds after coarsening
  // repeated while they help, and the specks peeling cuts off counted in the volume budget):
  // spheres 0.03 -> 15.0, slabs 0.06 -> 15.0, four at a point 0.04 -> 15.0, plate 0.06 -> 14.9,
  // plate with facet_angle 10 0.02 -> 14.8, rod 0.01 -> 11.3, cut by the box 1.3 -> 15.0, shells
  // 0.06 -> 15.0 (with the rounds once: 11.1, 15.0, 5.5 for the plate, with facet_angle and the
  // rod). Largest volume change 0.42 % (spheres); the plate 0.35 % (before the specks counted:
  // 0.69 %, the flat tets at its rim went with the specks behind them, outside the budget).
  // 2026-11-27 (session 20: the particle system converges, the hull ascent and three-ring
  // insertion in the inserting rounds): plate 11.7, rod 9.3, the others 15.0. On the plate and the
  // rod the worst tet swings by degrees with any change upstream (main's code of session 19 over
  // the seeds 1-8: plate 9.6-14.9, rod 7.3-11.3, seed 1 the best of both), so their single-seed
  // floors are only regression markers; OverEightSeeds below judges them by their spread.
  return {{"two_touching_spheres", twoSpheres(), 14.5},
          {"three_slabs_on_a_line", threeSlabs(), 14.5},
          {"four_materials_at_a_point", fourAtAPoint(), 14.5},
          {"one_voxel_plate", oneVoxelPlate(), 11.5},
          {"one_voxel_plate_facet_angle_10", oneVoxelPlate(), 14.5, 5e-3, 10.0},
          {"thin_rod", thinRod(), 9.0},
          {"materials_cut_by_the_box", ballsInShellWithoutBackground(24), 14.5},
          {"nested_thin_shells", nestedThinShells(), 14.0}};
}

PipelineResult mesh(const Shape& s, bool optimize) {
  const LabelVolume& v = s.volume;
  MeshingParameters p;
  p.boundary.facetShape.minAngleDegrees = s.facetAngle;
  p.run.threads = 2;
  p.run.computeFidelity = false;
  if (!optimize) p.optimize.targetMinDihedral = 0;  // TetGen's mesh as it is
  RunContext ctx;
  auto r = runPipeline(v, p, ctx);
  EXPECT_TRUE(r.isOk()) << r.status().message();
  return r.isOk() ? std::move(r).value() : PipelineResult{};
}

class OptimizeShapes : public ::testing::TestWithParam<Shape> {};

}  // namespace

TEST_P(OptimizeShapes, ConformalVolumesKeptWorstAngleOnlyRisesDeterministic) {
  const Shape& s = GetParam();
  const PipelineResult off = mesh(s, false), on = mesh(s, true);
  ASSERT_FALSE(off.mesh.tets.empty());
  ASSERT_FALSE(on.mesh.tets.empty());
  expectConformal(on.mesh);
  EXPECT_EQ(meshLabels(on.mesh), meshLabels(off.mesh)) << "a material appeared or vanished";

  double smallest = 1e300;
  for (size_t t = 0; t < on.mesh.tets.size(); ++t) smallest = std::min(smallest, on.mesh.tetVolume(t));
  EXPECT_GT(smallest, 0.0) << "a tet of zero or negative volume";

  const auto vOff = labelVolumes(off.mesh), vOn = labelVolumes(on.mesh);
  double largestChange = 0;
  for (const auto& [label, vol] : vOff) {
    ASSERT_TRUE(vOn.count(label)) << "label " << label;
    largestChange = std::max(largestChange, std::fabs(vOn.at(label) - vol) / vol);
    EXPECT_NEAR(vOn.at(label), vol, s.maxVolumeChange * vol) << "label " << label << ": volume changed";
  }

  const double worstOff = minOver(off.mesh.points, off.mesh.tets);
  const double worstOn = minOver(on.mesh.points, on.mesh.tets);
  EXPECT_GE(worstOn, worstOff) << "the optimised mesh's worst tet is flatter";
  EXPECT_GE(worstOn, s.minWorst) << "flatter than before";

  const PipelineResult again = mesh(s, true);
  EXPECT_EQ(again.mesh.points, on.mesh.points) << "not deterministic";
  EXPECT_EQ(again.mesh.tets, on.mesh.tets) << "not deterministic";
  EXPECT_EQ(again.mesh.tetLabels, on.mesh.tetLabels) << "not deterministic";

  std::printf(
      "[optimize-shapes] %s: %zu -> %zu tets, worst %.2f -> %.2f deg, largest volume change "
      "%.3f %%\n",
      s.name.c_str(), off.mesh.tets.size(), on.mesh.tets.size(), worstOff, worstOn,
      100 * largestChange);
}

INSTANTIATE_TEST_SUITE_P(GeneratedShapes, OptimizeShapes, ::testing::ValuesIn(shapes()),
                         [](const ::testing::TestParamInfo<Shape>& info) { return info.param.name; });

// The plate and the rod are where a thin part leaves nothing but surface vertices, and their worst
// tet depends on the sampling's details: judged over eight seeds (mean and worst of the eight).
// Measured 2026-11-27: plate mean 13.71, worst 11.6 (session 19's code: 13.44, 9.6); rod mean
// 11.25, worst 8.7 (session 19's code: 9.40, 7.3). 2026-11-28, after vertex insertion into a
// cavity that is not a ball and a 3-to-2 flip onto a triangle already in the mesh were refused
// (both had left triangles of three tets on thin parts: the rod's seed 3 was not conformal) and
// the vertex moves of 16 tets at a time come after their connectivity operations: plate mean
// 13.43, worst 7.33 (seed 2; the others 11.3-15.0); rod mean 11.40, worst 9.27.
TEST(OptimizeShapesOverEightSeeds, ThinPlateAndRodWorstAngles) {
  using namespace femesher::test;
  struct Case {
    const char* name;
    LabelVolume volume;
    double minMean, minWorst;
  };
  const Case cases[] = {{"one_voxel_plate", oneVoxelPlate(), 13.2, 7.0},
                        {"thin_rod", thinRod(), 10.8, 8.4}};
  for (const Case& c : cases) {
    double sum = 0, worst = 180;
    std::string all;
    for (uint64_t seed = 1; seed <= 8; ++seed) {
      MeshingParameters p;
      p.run.threads = 2;
      p.run.computeFidelity = false;
      p.run.seed = seed;
      RunContext ctx;
      auto r = runPipeline(c.volume, p, ctx);
      ASSERT_TRUE(r.isOk()) << c.name << " seed " << seed << ": " << r.status().message();
      const double w = minOver(r->mesh.points, r->mesh.tets);
      sum += w;
      worst = std::min(worst, w);
      all += " " + std::to_string(w).substr(0, 5);
    }
    EXPECT_GE(sum / 8, c.minMean) << c.name << ": worst angles" << all;
    EXPECT_GE(worst, c.minWorst) << c.name << ": worst angles" << all;
    std::printf("[optimize-shapes] %s over seeds 1-8: mean %.2f, worst %.2f deg (%s )\n", c.name,
                sum / 8, worst, all.c_str());
  }
}
