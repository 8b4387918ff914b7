// SPDX-License-Identifier: GPL-3.0-or-later
// Stage 6 (Junctions) on its own, from preprocessed labels, indicator functions and a constant
// size: located points tie three (four) indicators, junction cells are counted, the quadruple
// point of four materials is found, points along a triple line keep the size apart; locating a
// single point, thread independence, cancel.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "MeshInvariants.h"
#include "TestShapes.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

using Inputs = test::IndicatorInputs;

/// The stage's inputs: `v` preprocessed, its indicator functions with sigma 0.3.
Inputs prepare(const LabelVolume& v) { return test::computeIndicatorInputs(v, 0.3); }

JunctionParameters junctionParameters(double spacingFactor = 1.0, int relaxIterations = 10) {
  JunctionParameters p;
  p.spacingFactor = spacingFactor;
  p.relaxIterations = relaxIterations;
  return p;
}

Junctions find(const Inputs& in, double h, double spacingFactor = 1.0, int threads = 0,
               int relaxIterations = 10) {
  RunContext ctx;
  ctx.setThreads(threads);
  return findJunctions(
      *in.field, [h](const Vec3&) { return h; }, junctionParameters(spacingFactor, relaxIterations),
      ctx);
}

/// Largest |f_l0 - f_li| over the point's labels, and by how much another label beats the lowest
/// of them (<= 0 when they lead).
void tie(const IndicatorField& f, const JunctionPoint& p, double& spread, double& beaten) {
  const double f0 = f.eval(p.labels[0], p.local);
  double lo = f0;
  spread = 0;
  for (int i = 1; i < p.count; ++i) {
    const double x = f.eval(p.labels[size_t(i)], p.local);
    lo = std::min(lo, x);
    spread = std::max(spread, std::fabs(f0 - x));
  }
  beaten = -1e300;
  for (int m = 0; m < f.labelCount(); ++m)
    if (std::find(p.labels.begin(), p.labels.begin() + p.count, uint16_t(m)) ==
        p.labels.begin() + p.count)
      beaten = std::max(beaten, f.eval(m, p.local) - lo);
}

/// Dual cells (2x2x2 voxel centres) holding at least `n` labels.
size_t cellsWithLabels(const PreprocessedVolume& v, int n) {
  size_t cells = 0;
  for (int k = 0; k + 1 < v.dims[2]; ++k)
    for (int j = 0; j + 1 < v.dims[1]; ++j)
      for (int i = 0; i + 1 < v.dims[0]; ++i) {
        std::set<int> l;
        for (int c = 0; c < 8; ++c)
          l.insert(v.at(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)));
        cells += int(l.size()) >= n;
      }
  return cells;
}

double distance(const PreprocessedVolume& v, const Vec3& a, const Vec3& b) {
  const Vec3 p = v.localToCanonical(a), q = v.localToCanonical(b);
  return std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                   (p[2] - q[2]) * (p[2] - q[2]));
}

}  // namespace

// Every located point (candidates and the sampled particles) ties its three or four indicator
// functions (each within 1e-4 x the smallest spacing of the first), and no other label is higher
// there (by more than ten times that).
TEST(Junctions, LocatedPointsTieTheirIndicators) {
  for (LabelVolume v : {test::threeSlabs(), test::fourAtAPoint(), test::ballsInShell(24)}) {
    v.spacing = {0.8, 0.6, 0.7};
    const Inputs in = prepare(v);
    const Junctions j = find(in, 1.5);
    ASSERT_GT(j.candidates.size(), 20u);
    ASSERT_FALSE(j.particles.empty());
    const double tol = 1e-4 * 0.6;
    size_t loose = 0, overtaken = 0;
    for (const auto* set : {&j.candidates, &j.particles})
      for (const auto& p : *set) {
        double spread, beaten;
        tie(*in.field, p, spread, beaten);
        loose += spread > tol * 1.01;
        overtaken += beaten > 10 * tol * 1.01;
        ASSERT_TRUE(std::is_sorted(p.labels.begin(), p.labels.begin() + p.count));
      }
    EXPECT_EQ(loose, 0u);
    EXPECT_EQ(overtaken, 0u);
  }
}

TEST(Junctions, JunctionCellsAreCounted) {
  for (const LabelVolume& v :
       {test::threeSlabs(), test::fourAtAPoint(), test::nestedThinShells(24)}) {
    const Inputs in = prepare(v);
    const Junctions j = find(in, 2.0);
    EXPECT_EQ(j.tripleCells, cellsWithLabels(*in.vol, 3));
    EXPECT_EQ(j.quadrupleCells, cellsWithLabels(*in.vol, 4));
    size_t quads = 0;
    for (const auto& p : j.particles) quads += p.count == 4;
    EXPECT_EQ(j.quadruplePoints, quads);
  }
}

// Nested shells never bring three materials together: no junction at all.
TEST(Junctions, NoneWhereOnlyTwoMaterialsMeet) {
  const Inputs in = prepare(test::nestedThinShells(24));
  ASSERT_EQ(cellsWithLabels(*in.vol, 3), 0u);
  const Junctions j = find(in, 2.0);
  EXPECT_TRUE(j.candidates.empty());
  EXPECT_TRUE(j.particles.empty());
}

// The four materials of fourAtAPoint meet at one point near (0.2, -0.4, 0.3) (centred): it is
// kept as the one quadruple particle of 1-2-3-4, and keeps its neighbourhood free.
TEST(Junctions, QuadruplePointOfFourMaterialsIsFound) {
  const Inputs in = prepare(test::fourAtAPoint());
  const PreprocessedVolume& pv = *in.vol;
  const double h = 2.0;
  const Junctions j = find(in, h);
  std::vector<JunctionPoint> quads;
  for (const auto& p : j.particles)
    if (p.count == 4 && p.labels == std::array<uint16_t, 4>{{1, 2, 3, 4}}) quads.push_back(p);
  ASSERT_EQ(quads.size(), 1u);
  const Vec3 c = pv.localToCanonical(quads[0].local);
  EXPECT_NEAR(c[0], 17.5 + 0.2, 0.75);
  EXPECT_NEAR(c[1], 17.5 - 0.4, 0.75);
  EXPECT_NEAR(c[2], 17.5 + 0.3, 0.75);
  for (const auto& p : j.particles)
    if (p.local != quads[0].local)
      EXPECT_GE(distance(pv, p.local, quads[0].local), 0.75 * h * (1 - 1e-9));
}

// Along the triple line of three slabs (the z axis) the particles keep the size apart: no two
// closer than 0.75 h, no gap wider than 1.5 h, and twice the size gives about half as many. (The
// candidates are one voxel apart on this line, so the spacing is a whole number of voxels.)
TEST(Junctions, SpacingAlongATripleLineFollowsTheSize) {
  const Inputs in = prepare(test::threeSlabs());
  const PreprocessedVolume& pv = *in.vol;
  std::map<double, size_t> count;
  for (const double h : {1.2, 2.4}) {
    const Junctions j = find(in, h);
    std::vector<Vec3> line;
    for (const auto& p : j.particles)
      if (p.count == 3 && p.labels == std::array<uint16_t, 4>{{1, 2, 3, 0}})
        line.push_back(p.local);
    ASSERT_GT(line.size(), 5u);
    std::sort(line.begin(), line.end(), [](const Vec3& a, const Vec3& b) { return a[2] < b[2]; });
    double closest = 1e300, widest = 0;
    for (size_t i = 1; i < line.size(); ++i) {
      const double d = distance(pv, line[i - 1], line[i]);
      closest = std::min(closest, d);
      widest = std::max(widest, d);
    }
    EXPECT_GE(closest, 0.75 * h * (1 - 1e-9)) << "h = " << h;
    EXPECT_LE(widest, 1.5 * h) << "h = " << h;
    count[h] = line.size();
  }
  EXPECT_NEAR(double(count[1.2]) / double(count[2.4]), 2.0, 0.2);
  // The spacing factor scales the size the same way.
  EXPECT_EQ(find(in, 3.0).particles.size(), find(in, 1.5, 2.0).particles.size());
}

// The triple line of two touching spheres and the background is a circle (radius about 4.3 mm)
// about the x axis, off the grid's directions. Sampled, its particles keep 0.75 h apart; the 1-D
// relaxation then moves them along the circle (on so short a line it does not even the gaps out:
// measured for h = 2, 1.59-2.24 mm apart before, 1.28-2.29 after), so after it they are
// 0.6-1.6 h apart and their number follows the circumference over h.
TEST(Junctions, SpacingAlongACurvedTripleLineFollowsTheSize) {
  const Inputs in = prepare(test::twoSpheres());
  const PreprocessedVolume& pv = *in.vol;
  for (const int relax : {0, 10})
    for (const double h : {1.5, 2.0, 3.0}) {
      SCOPED_TRACE("h = " + std::to_string(h) + ", relaxation iterations " + std::to_string(relax));
      std::vector<std::pair<double, Vec3>> ring;  // by the angle about the x axis
      double perimeter = 0;
      for (const auto& p : find(in, h, 1.0, 0, relax).particles) {
        if (p.count != 3 || p.labels != std::array<uint16_t, 4>{{0, 1, 2, 0}}) continue;
        const Vec3 c = pv.localToCanonical(p.local);
        ring.push_back({std::atan2(c[2] - 17.5, c[1] - 17.5), p.local});
        perimeter += 2 * M_PI * std::hypot(c[2] - 17.5, c[1] - 17.5);
      }
      ASSERT_GE(ring.size(), 6u);
      perimeter /= double(ring.size());
      std::sort(ring.begin(), ring.end(),
                [](const auto& a, const auto& b) { return a.first < b.first; });
      double closest = 1e300, widest = 0;
      for (size_t i = 0; i < ring.size(); ++i) {
        const double d = distance(pv, ring[i].second, ring[(i + 1) % ring.size()].second);
        closest = std::min(closest, d);
        widest = std::max(widest, d);
      }
      EXPECT_GE(closest, (relax ? 0.6 : 0.75) * h * (1 - 1e-9));
      EXPECT_LE(widest, 1.6 * h);
      EXPECT_GT(perimeter / double(ring.size()), 0.75 * h);
      EXPECT_LT(perimeter / double(ring.size()), 1.25 * h);
    }
}

// locateJunctionPoint moves a point near the z axis of three slabs onto it (f_1 = f_2 = f_3);
// asked for a label triple that does not meet there, it fails.
TEST(Junctions, LocateMovesAPointOntoItsJunction) {
  const Inputs in = prepare(test::threeSlabs());
  const PreprocessedVolume& pv = *in.vol;
  const Vec3 axis = pv.canonicalToLocal({17.5, 17.5, 17.5});
  const uint16_t slabs[3] = {1, 2, 3};
  Vec3 x{axis[0] + 0.4, axis[1] - 0.3, axis[2] + 0.2};
  ASSERT_TRUE(locateJunctionPoint(*in.field, slabs, 3, x));
  const double f1 = in.field->eval(1, x), f2 = in.field->eval(2, x), f3 = in.field->eval(3, x);
  EXPECT_NEAR(f1, f2, 1e-4);
  EXPECT_NEAR(f1, f3, 1e-4);
  EXPECT_LT(std::hypot(x[0] - axis[0], x[1] - axis[1]), 1.0);
  const uint16_t withBackground[3] = {0, 1, 2};
  Vec3 y{axis[0] + 0.4, axis[1] - 0.3, axis[2] + 0.2};
  EXPECT_FALSE(locateJunctionPoint(*in.field, withBackground, 3, y));
}

TEST(Junctions, SameResultForAnyThreadCount) {
  const Inputs in = prepare(test::fourAtAPoint());
  const Junctions a = find(in, 2.0, 1.0, 1), b = find(in, 2.0, 1.0, 3);
  ASSERT_EQ(a.particles.size(), b.particles.size());
  for (size_t i = 0; i < a.particles.size(); ++i) {
    EXPECT_EQ(a.particles[i].local, b.particles[i].local);
    EXPECT_EQ(a.particles[i].labels, b.particles[i].labels);
  }
  EXPECT_EQ(a.candidates.size(), b.candidates.size());
}

TEST(Junctions, CancelStopsTheStage) {
  const Inputs in = prepare(test::threeSlabs());
  RunContext ctx;
  ctx.cancel();
  expectError(ErrorCode::Canceled, [&] {
    findJunctions(
        *in.field, [](const Vec3&) { return 2.0; }, junctionParameters(), ctx);
  });
}
