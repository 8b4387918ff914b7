// SPDX-License-Identifier: GPL-3.0-or-later
// Stages 3 and 7a (SurfaceSampling) on their own, from preprocessed labels and indicator
// functions: one candidate per grid edge that crosses an interface, on the smooth interface; a
// Poisson-disk selection at the (uniform or graded) size; determinism for a seed; cancel.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/SurfaceSampling.h>
#include <gtest/gtest.h>

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

SurfaceSamples sample(const Inputs& in, double h, uint64_t seed = 1,
                      std::function<double(const Vec3&)> sizing = {}) {
  SurfaceSamplingParameters p;
  p.targetEdgeLength = h;
  p.sizing = std::move(sizing);
  p.seed = seed;
  RunContext ctx;
  return sampleInterfaces(*in.field, in.input, p, ctx);
}

/// A grid edge: its lower voxel and its axis.
using Edge = std::pair<std::array<int, 3>, int>;

/// The grid edge a sample lies on (two integer coordinates, one strictly between two).
bool edgeOf(const SurfaceSample& s, Edge& e) {
  int axis = -1;
  for (int a = 0; a < 3; ++a) {
    const double x = s.local[size_t(a)], fl = std::floor(x);
    e.first[size_t(a)] = int(fl);
    if (x != fl) {
      if (axis >= 0) return false;
      axis = a;
    }
  }
  e.second = axis;
  return axis >= 0;
}

/// Distinct labels of the 2x2x2 voxel centres from `p` up.
int cellLabels(const PreprocessedVolume& v, const std::array<int, 3>& p) {
  std::set<int> l;
  for (int c = 0; c < 8; ++c)
    l.insert(v.at(p[0] + (c & 1), p[1] + ((c >> 1) & 1), p[2] + ((c >> 2) & 1)));
  return int(l.size());
}

double distance(const PreprocessedVolume& v, const SurfaceSample& a, const SurfaceSample& b) {
  const Vec3 p = v.localToCanonical(a.local), q = v.localToCanonical(b.local);
  return std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                   (p[2] - q[2]) * (p[2] - q[2]));
}

/// The selection rule with sizes h(i): two selected samples of one interface keep 0.75 x their
/// mean size apart, of two interfaces 0.4 x that; every candidate left out breaks the rule with a
/// selected one. Returns the number of violations.
size_t poissonViolations(const PreprocessedVolume& v, const SurfaceSamples& s,
                         const std::function<double(const SurfaceSample&)>& h) {
  auto limit = [&](const SurfaceSample& a, const SurfaceSample& b) {
    const double r = 0.75 * 0.5 * (h(a) + h(b));
    return a.a == b.a && a.b == b.b ? r : 0.4 * r;
  };
  std::vector<char> chosen(s.all.size(), 0);
  for (uint32_t i : s.selected) chosen[i] = 1;
  size_t bad = 0;
  for (size_t x = 0; x < s.selected.size(); ++x)
    for (size_t y = x + 1; y < s.selected.size(); ++y) {
      const SurfaceSample &a = s.all[s.selected[x]], &b = s.all[s.selected[y]];
      bad += distance(v, a, b) < limit(a, b) * (1 - 1e-9);
    }
  for (size_t i = 0; i < s.all.size(); ++i) {
    if (chosen[i]) continue;
    bool blocked = false;
    for (uint32_t j : s.selected)
      if (distance(v, s.all[i], s.all[j]) < limit(s.all[i], s.all[j]) * (1 + 1e-9)) {
        blocked = true;
        break;
      }
    bad += !blocked;
  }
  return bad;
}

}  // namespace

// Marching cubes finds every grid edge between two labels; each gives one candidate (both sides
// deduplicated), except next to a triple line where a third label owns the point.
TEST(SurfaceSampling, OneCandidatePerGridEdgeAcrossAnInterface) {
  for (const LabelVolume& v : {test::nestedThinShells(24), test::ballsInShell(24)}) {
    const Inputs in = prepare(v);
    const PreprocessedVolume& pv = *in.vol;
    const SurfaceSamples s = sample(in, 2.0);
    std::set<Edge> sampled;
    size_t malformed = 0, wrongLabels = 0, wrongJunctionFlag = 0;
    for (const auto& x : s.all) {
      Edge e;
      if (!edgeOf(x, e)) {
        ++malformed;
        continue;
      }
      sampled.insert(e);
      std::array<int, 3> q = e.first;
      ++q[size_t(e.second)];
      const int la = pv.at(e.first[0], e.first[1], e.first[2]), lb = pv.at(q[0], q[1], q[2]);
      wrongLabels += !(x.a < x.b && x.a == std::min(la, lb) && x.b == std::max(la, lb));
      wrongJunctionFlag += x.junction != (cellLabels(pv, e.first) > 2);
    }
    EXPECT_EQ(malformed, 0u);
    EXPECT_EQ(sampled.size(), s.all.size()) << "an edge sampled twice";
    EXPECT_EQ(wrongLabels, 0u);
    EXPECT_EQ(wrongJunctionFlag, 0u);
    size_t crossing = 0, missing = 0, missingAtJunctions = 0;
    for (int k = 0; k + 1 < pv.dims[2]; ++k)
      for (int j = 0; j + 1 < pv.dims[1]; ++j)
        for (int i = 0; i + 1 < pv.dims[0]; ++i)
          for (int a = 0; a < 3; ++a) {
            std::array<int, 3> q{{i, j, k}};
            ++q[size_t(a)];
            if (pv.at(i, j, k) == pv.at(q[0], q[1], q[2])) continue;
            ++crossing;
            if (sampled.count({{{i, j, k}}, a})) continue;
            ++(cellLabels(pv, {{i, j, k}}) > 2 ? missingAtJunctions : missing);
          }
    EXPECT_GT(crossing, 2000u);
    EXPECT_EQ(missing, 0u);
    EXPECT_LE(double(missingAtJunctions), 0.02 * double(crossing));
    EXPECT_GT(s.isosurfaceTriangles, crossing);
  }
}

// Every candidate lies on the smooth interface of its two labels (f_a = f_b, moved along its
// grid edge), and no other label is higher there.
TEST(SurfaceSampling, CandidatesLieOnTheirInterface) {
  LabelVolume v = test::ballsInShell(28);
  v.spacing = {0.7, 0.4, 0.5};
  const Inputs in = prepare(v);
  const IndicatorField& f = *in.field;
  const SurfaceSamples s = sample(in, 1.5);
  ASSERT_GT(s.all.size(), 5000u);
  size_t off = 0, beaten = 0;
  for (const auto& x : s.all) {
    const double fa = f.eval(x.a, x.local), fb = f.eval(x.b, x.local);
    off += std::fabs(fa - fb) > 1e-5;
    for (int m = 0; m < f.labelCount(); ++m)
      if (m != x.a && m != x.b) beaten += f.eval(m, x.local) > std::max(fa, fb) + 1e-9;
  }
  EXPECT_EQ(off, 0u);
  EXPECT_EQ(beaten, 0u);
}

// The selection is a maximal Poisson-disk set at 0.75 x the target edge length, junction-cell
// candidates first; halving the size gives about four times the samples.
TEST(SurfaceSampling, SelectionIsAPoissonDiskAtTheTargetSize) {
  const Inputs in = prepare(test::ballsInShell(32));
  std::map<double, size_t> count;
  for (const double h : {1.5, 3.0}) {
    const SurfaceSamples s = sample(in, h);
    EXPECT_EQ(poissonViolations(*in.vol, s, [h](const SurfaceSample&) { return h; }), 0u)
        << "h = " << h;
    std::set<uint32_t> unique(s.selected.begin(), s.selected.end());
    EXPECT_EQ(unique.size(), s.selected.size());
    bool junctionsFirst = true, seenOther = false;
    for (uint32_t i : s.selected) {
      seenOther |= !s.all[i].junction;
      junctionsFirst &= !(seenOther && s.all[i].junction);
    }
    EXPECT_TRUE(junctionsFirst);
    count[h] = s.selected.size();
  }
  const double ratio = double(count[1.5]) / double(count[3.0]);
  EXPECT_GT(ratio, 3.0);
  EXPECT_LT(ratio, 5.0);
}

// With a sizing function the disk radius follows it: the ball on the left (h = 1.5) gets about
// four times the samples of the same ball on the right (h = 3).
TEST(SurfaceSampling, SpacingFollowsAGradedSize) {
  const Inputs in = prepare(test::twoSpheres());
  const auto h = [](const Vec3& c) { return c[0] < 17.5 ? 1.5 : 3.0; };
  const SurfaceSamples s = sample(in, 1.5, 1, h);
  const PreprocessedVolume& pv = *in.vol;
  EXPECT_EQ(poissonViolations(
                pv, s, [&](const SurfaceSample& x) { return h(pv.localToCanonical(x.local)); }),
            0u);
  size_t left = 0, right = 0;
  for (uint32_t i : s.selected) {
    const SurfaceSample& x = s.all[i];
    if (x.a == 0 && x.b == 1) ++left;
    if (x.a == 0 && x.b == 2) ++right;
  }
  EXPECT_GT(double(left), 3.0 * double(right));
  EXPECT_LT(double(left), 5.0 * double(right));
}

TEST(SurfaceSampling, DeterministicForASeed) {
  const Inputs in = prepare(test::threeSlabs());
  const SurfaceSamples a = sample(in, 2.0, 7), b = sample(in, 2.0, 7), c = sample(in, 2.0, 8);
  EXPECT_EQ(a.selected, b.selected);
  ASSERT_EQ(a.all.size(), c.all.size());  // the candidates do not depend on the seed
  for (size_t i = 0; i < a.all.size(); ++i) ASSERT_EQ(a.all[i].local, c.all[i].local);
  EXPECT_NE(a.selected, c.selected) << "another seed should pick other samples";
  EXPECT_NEAR(double(c.selected.size()), double(a.selected.size()),
              0.1 * double(a.selected.size()));
}

TEST(SurfaceSampling, CancelStopsTheStage) {
  const Inputs in = prepare(test::twoSpheres());
  RunContext ctx;
  ctx.cancel();
  expectError(ErrorCode::Canceled,
              [&] { sampleInterfaces(*in.field, in.input, SurfaceSamplingParameters{}, ctx); });
}
