// SPDX-License-Identifier: GPL-3.0-or-later
// Stage 10 (Optimize): sliver removal keeps every interface between materials exactly, never
// lowers the worst angle, peels only thin boundary tets, smooths interior vertices.
#include "MeshInvariants.h"
#include "TetMeasures.h"
#include "TestShapes.h"

#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/RunContext.h>
#include <femesher/stages/Optimize.h>
#include <femesher/stages/internal/OptimizeEditor.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

using namespace femesher;
using namespace femesher::testing;
using femesher::test::labelVolumes;
using femesher::test::minOver;
using femesher::test::Tets;

namespace {

size_t countBelow(const std::vector<Vec3>& p, const Tets& t, double deg) {
  size_t n = 0;
  for (const auto& T : t) n += tetMinDihedral(p[T[0]], p[T[1]], p[T[2]], p[T[3]]) < deg;
  return n;
}

/// Interface triangles between two materials, as sorted coordinate triples with their labels.
std::set<std::vector<double>> materialInterfaces(const TetMesh& m) {
  std::set<std::vector<double>> out;
  for (const auto& tri : extractInterfaces(m)) {
    if (tri.labelB == kExteriorLabel) continue;
    std::vector<std::array<double, 3>> v;
    for (int k = 0; k < 3; ++k) v.push_back(m.points[size_t(tri.v[k])]);
    std::sort(v.begin(), v.end());
    std::vector<double> key{double(std::min(tri.labelA, tri.labelB)),
                            double(std::max(tri.labelA, tri.labelB))};
    for (const auto& p : v) key.insert(key.end(), p.begin(), p.end());
    out.insert(key);
  }
  return out;
}

std::map<int32_t, double> volumes(const TetMesh& m) {
  std::map<int32_t, double> v;
  for (size_t t = 0; t < m.tets.size(); ++t) v[m.tetLabels[t]] += m.tetVolume(t);
  return v;
}

}  // namespace

TEST(Optimize, ShortestVectorOfTheGradientsHullRaisesEveryOne) {
  using femesher::optimize_detail::shortestInHull;
  auto near = [](const Vec3& a, const Vec3& b) { return norm(sub(a, b)) < 1e-6; };
  // One gradient: itself.
  EXPECT_TRUE(near(shortestInHull({Vec3{0, 2, 0}}), Vec3{0, 2, 0}));
  // Two orthogonal ones: the midpoint of the segment, which raises both.
  EXPECT_TRUE(near(shortestInHull({Vec3{1, 0, 0}, Vec3{0, 1, 0}}), Vec3{0.5, 0.5, 0}));
  // A fan whose shortest point is a vertex: (1, 0, 0) is nearer than any other point of the hull.
  EXPECT_TRUE(near(shortestInHull({Vec3{1, 1, 0}, Vec3{1, 0, 0}, Vec3{1, -1, 0}, Vec3{3, 0, 1}}),
                   Vec3{1, 0, 0}));
  // Gradients that pull against each other (a max-min optimum): no direction raises all.
  EXPECT_LT(norm(shortestInHull({Vec3{1, 0, 0}, Vec3{-1, 1, 0}, Vec3{-1, -1, 0}})), 1e-6);
  // Whatever the set, the result x satisfies g . x >= |x|^2 for every g (first-order ascent).
  const std::vector<Vec3> g{{2, 1, 0}, {0.5, 3, 1}, {1, -1, 2}, {1.5, 0.2, -0.3}};
  const Vec3 x = shortestInHull(g);
  ASSERT_GT(norm(x), 0.1);
  for (const Vec3& gi : g) EXPECT_GE(dot(gi, x), dot(x, x) * (1 - 1e-6));
}

TEST(Optimize, MinDihedralOfRegularFlatAndInvertedTets) {
  const Vec3 a{1, 1, 1}, b{1, -1, -1}, c{-1, 1, -1}, d{-1, -1, 1};
  const double regular = tetMinDihedral(a, b, c, d) > 0 ? tetMinDihedral(a, b, c, d)
                                                        : tetMinDihedral(a, c, b, d);
  EXPECT_NEAR(regular, std::acos(1.0 / 3.0) * 180 / M_PI, 1e-9);
  // The other orientation is inverted.
  EXPECT_EQ(std::min(tetMinDihedral(a, b, c, d), tetMinDihedral(a, c, b, d)), -1);
  // A sliver: four points almost on a plane (square with a tiny lift on the diagonal).
  const double sliver = tetMinDihedral({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 1e-3});
  const double sliver2 = tetMinDihedral({0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 1e-3});
  EXPECT_LT(std::max(sliver, sliver2), 0.2);
  EXPECT_EQ(tetMinDihedral({0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}), -1);  // flat
}

namespace {

/// Swaps two vertices of T when it is not positively oriented in p.
void orientPositively(const std::vector<Vec3>& p, std::array<int32_t, 4>& T) {
  if (tetMinDihedral(p[size_t(T[0])], p[size_t(T[1])], p[size_t(T[2])], p[size_t(T[3])]) < 0)
    std::swap(T[0], T[1]);
}

/// Adds a regular tet of edge 2 L sqrt(2) (volume 8 L^3 / 3) centred at (x, x, x), its own piece,
/// of `label`.
void addBulkTet(std::vector<Vec3>& p, Tets& t, std::vector<int32_t>& labels, double x,
                int32_t label, double L = 20) {
  const int32_t first = int32_t(p.size());
  for (const Vec3& q : {Vec3{x + L, x + L, x + L}, Vec3{x + L, x - L, x - L},
                        Vec3{x - L, x + L, x - L}, Vec3{x - L, x - L, x + L}})
    p.push_back(q);
  std::array<int32_t, 4> T{first, first + 1, first + 2, first + 3};
  orientPositively(p, T);
  t.push_back(T);
  labels.push_back(label);
}

/// A corner tet (0, 1, 2, 3) and a cap (1, 2, 3, 4) on its slanted face, lifted by `lift` along
/// the face normal; with `bulk`, a large regular tet of the same material far away (its own
/// piece), so that the cap is a small share of the material's volume.
struct CornerWithCap {
  std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Tets t = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  std::vector<int32_t> labels = {1, 1};
  CornerWithCap(double lift, bool bulk) {
    const double s = 1.0 / 3.0, n = 1.0 / std::sqrt(3.0);
    p.push_back({s + lift * n, s + lift * n, s + lift * n});
    if (tetMinDihedral(p[1], p[2], p[3], p[4]) < 0) std::swap(t[1][0], t[1][1]);
    if (bulk) addBulk(100, 1);
  }
  /// Three tets of `label` over the cap's three outer faces (their apex 1 out along the normal):
  /// all four of the cap's faces then have a tet on the other side.
  void closeIn(int32_t label) {
    const double s = 1.0 / 3.0, n = 1.0 / std::sqrt(3.0);
    p.push_back({s + n, s + n, s + n});
    const int32_t apex = int32_t(p.size() - 1);
    for (const auto& e : {std::array<int32_t, 2>{1, 2}, std::array<int32_t, 2>{2, 3},
                          std::array<int32_t, 2>{3, 1}}) {
      std::array<int32_t, 4> T{e[0], e[1], 4, apex};
      orientPositively(p, T);
      t.push_back(T);
      labels.push_back(label);
    }
  }
  void addBulk(double x, int32_t label) { addBulkTet(p, t, labels, x, label); }
};

}  // namespace

TEST(Optimize, PeelsAFlatBoundaryCapOnlyWhenThinnerThanTheTolerance) {
  for (const double lift : {0.01, 0.2}) {
    CornerWithCap m(lift, true);
    ASSERT_GT(minOver(m.p, m.t), 0);
    RunContext ctx;
    OptimizeParameters op;
    op.peelDistance = 0.05;
    op.targetMinDihedral = 20;
    op.minFragmentVoxels = 0;
    const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, ctx);
    if (lift < op.peelDistance) {
      EXPECT_EQ(r.peeledTets, 1u);
      EXPECT_EQ(m.t.size(), 2u);
      EXPECT_EQ(m.p.size(), 8u) << "the cap's apex is dropped with it";
    } else {
      EXPECT_EQ(r.peeledTets, 0u);
      EXPECT_EQ(m.t.size(), 3u);
    }
  }
}

TEST(Optimize, PeelingStaysWithinTheMaterialsVolumeBudget) {
  // Without the far bulk the cap is 2 % of its material's volume: more than peeling may take.
  CornerWithCap m(0.01, false);
  RunContext ctx;
  OptimizeParameters op;
  op.peelDistance = 0.05;
  op.targetMinDihedral = 20;
  op.minFragmentVoxels = 0;
  const double before = labelVolumes(m.p, m.t, m.labels).at(1);
  const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, ctx);
  EXPECT_EQ(r.peeledTets, 0u);
  EXPECT_NEAR(labelVolumes(m.p, m.t, m.labels).at(1), before, 1e-12) << "flips keep the volume";
}

TEST(Optimize, KeepsAQuarterOfThePeelingBudgetForTetsBelowTheWarningAngle) {
  // The cap is 0.35 % of its material's volume: within the peeling budget (0.4 %), beyond the
  // three quarters of it that tets at or above min_dihedral_warning may use. The corner tet below
  // it is another material, so no flip can remove it instead.
  for (const double warning : {0.0, 5.0, 40.0}) {
    CornerWithCap m(0.1, false);
    m.labels[0] = 2;
    const double cap = std::sqrt(3.0) / 2 * 0.1 / 3;
    const double rest = cap / 0.0035 - cap;
    addBulkTet(m.p, m.t, m.labels, 100, 1, std::cbrt(3 * rest / 8));
    addBulkTet(m.p, m.t, m.labels, -100, 2);
    const double capAngle = tetMinDihedral(m.p[1], m.p[2], m.p[3], m.p[4]) > 0
                                ? tetMinDihedral(m.p[1], m.p[2], m.p[3], m.p[4])
                                : tetMinDihedral(m.p[2], m.p[1], m.p[3], m.p[4]);
    ASSERT_GT(capAngle, 5);
    ASSERT_LT(capAngle, 30);
    RunContext ctx;
    OptimizeParameters op;
    op.peelDistance = 1;
    op.targetMinDihedral = 30;
    op.minFragmentVoxels = 0;
    op.minDihedralWarning = warning;
    const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, ctx);
    // No warning (0): one budget for all; the cap below the warning (40): the whole budget.
    EXPECT_EQ(r.peeledTets, warning == 5.0 ? 0u : 1u) << "warning " << warning;
  }
}

TEST(Optimize, RemovesFloatingFragmentsButNeverAMaterialsLastPiece) {
  // Material 1: the bulk tet and the corner + cap (a separate piece of 0.17 mm^3); material 2: a
  // lone tiny tet, its only piece.
  CornerWithCap m(0.3, true);
  const size_t first2 = m.p.size();
  for (const Vec3& q : {Vec3{-50, -50, -50}, Vec3{-49.5, -50, -50}, Vec3{-50, -49.5, -50},
                        Vec3{-50, -50, -49.5}})
    m.p.push_back(q);
  std::array<int32_t, 4> T{int32_t(first2), int32_t(first2 + 1), int32_t(first2 + 2),
                           int32_t(first2 + 3)};
  orientPositively(m.p, T);
  m.t.push_back(T);
  m.labels.push_back(2);
  RunContext ctx;
  OptimizeParameters op;
  op.targetMinDihedral = 0;  // the improvement itself is off; fragments go all the same
  op.minFragmentVoxels = 1;
  op.voxelVolume = 0.5;  // 0.5 mm^3: the corner piece and the lone tet are lighter
  const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, ctx);
  EXPECT_EQ(r.fragments, 1u);
  EXPECT_EQ(r.fragmentTets, 2u);
  EXPECT_NEAR(r.fragmentVolume, 1.0 / 6 + std::sqrt(3.0) / 2 * 0.3 / 3, 1e-9);
  ASSERT_EQ(m.t.size(), 2u);
  EXPECT_EQ(std::vector<int32_t>(m.labels), (std::vector<int32_t>{1, 2}))
      << "the bulk of material 1 and material 2's only piece stay";
  EXPECT_EQ(m.p.size(), 8u) << "the fragment's points are dropped";
  // Off: nothing is removed.
  CornerWithCap again(0.3, true);
  op.minFragmentVoxels = 0;
  const auto r0 = optimizeTetMesh(again.p, again.t, again.labels, op, ctx);
  EXPECT_EQ(r0.fragments, 0u);
  EXPECT_EQ(again.t.size(), 3u);
}

// Many floating pieces (more than the search's chunks of tets): the pieces lighter than the limit
// go, the same ones on one thread as on three.
TEST(Optimize, RemovesTheSameFragmentsOnAnyThreadCount) {
  auto build = [](std::vector<Vec3>& p, std::vector<std::array<int32_t, 4>>& t,
                  std::vector<int32_t>& labels) {
    // 300 pieces of two tets sharing a face, edge a in 0.3 .. 1.5 mm (a = 0.9: a piece heavier
    // than the limit whose tets are each lighter, in every few tets); plus a heavy piece per
    // material so that no material loses its last piece.
    for (int n = 0; n < 302; ++n) {
      const double a = n >= 300 ? 4.0 : 0.3 + 1.2 * (n % 7) / 6.0;
      const Vec3 o{10.0 * (n % 20), 10.0 * (n / 20), 0};
      const int32_t b = int32_t(p.size());
      for (const Vec3& d : {Vec3{0, 0, 0}, Vec3{a, 0, 0}, Vec3{0, a, 0}, Vec3{0, 0, a},
                            Vec3{a, a, a}})
        p.push_back({o[0] + d[0], o[1] + d[1], o[2] + d[2]});
      std::array<int32_t, 4> T1{b, b + 1, b + 2, b + 3}, T2{b + 1, b + 2, b + 3, b + 4};
      orientPositively(p, T1);
      orientPositively(p, T2);
      t.push_back(T1);
      t.push_back(T2);
      labels.push_back(1 + n % 2);
      labels.push_back(1 + n % 2);
    }
  };
  OptimizeParameters op;
  op.targetMinDihedral = 0;
  op.minFragmentVoxels = 1;
  op.voxelVolume = 0.2;  // two tets of edge a: a^3 / 6 + a^3 / 3 = a^3 / 2 mm^3; light below a^3 < 0.4
  std::vector<Vec3> p1, p3;
  std::vector<std::array<int32_t, 4>> t1, t3;
  std::vector<int32_t> l1, l3;
  build(p1, t1, l1);
  build(p3, t3, l3);
  RunContext one, three;
  one.setThreads(1);
  three.setThreads(3);
  const auto r1 = optimizeTetMesh(p1, t1, l1, op, one);
  const auto r3 = optimizeTetMesh(p3, t3, l3, op, three);
  size_t light = 0;
  for (int n = 0; n < 300; ++n) {
    const double a = 0.3 + 1.2 * (n % 7) / 6.0;
    light += a * a * a / 2 < 0.2;
  }
  EXPECT_GT(light, 30u);
  EXPECT_EQ(r1.fragments, light);
  EXPECT_EQ(r1.fragmentTets, 2 * light);
  EXPECT_EQ(r3.fragments, r1.fragments);
  EXPECT_EQ(r3.fragmentVolume, r1.fragmentVolume);
  EXPECT_EQ(t3, t1);
  EXPECT_EQ(p3, p1);
  EXPECT_EQ(l3, l1);
}

// A floating piece holding a tet below the target goes up to ten times the fragment limit (no
// operation can mend a piece whose every face is outer); a well-shaped piece that heavy stays.
TEST(Optimize, RemovesAHeavierFloatingPieceOnlyWhenItHoldsABadTet) {
  auto build = [](double size, double lift) {
    // Material 1: a bulk tet; far away a lone tet of material 1 on the triangle (0,0,0),
    // (size,0,0), (0,size,0) with its apex `lift` above the triangle's centroid (size^2 lift / 6
    // mm^3).
    std::vector<Vec3> p;
    Tets t;
    std::vector<int32_t> labels;
    addBulkTet(p, t, labels, 100, 1);
    for (const Vec3& q : {Vec3{0, 0, 0}, Vec3{size, 0, 0}, Vec3{0, size, 0},
                          Vec3{size / 3, size / 3, lift}})
      p.push_back(q);
    std::array<int32_t, 4> T{4, 5, 6, 7};
    orientPositively(p, T);
    t.push_back(T);
    labels.push_back(1);
    return std::make_tuple(p, t, labels);
  };
  RunContext ctx;
  OptimizeParameters op;
  op.targetMinDihedral = 15;
  op.peelDistance = 0;  // peeling would take the flat tet itself
  op.minFragmentVoxels = 1;
  op.voxelVolume = 0.5;  // pieces lighter than 0.5 mm^3 go; pieces with a bad tet up to 5 mm^3
  {
    auto [p, t, labels] = build(6, 0.3);  // 1.8 mm^3, flat
    ASSERT_LT(minOver(p, {t[1]}), 15);
    const auto r = optimizeTetMesh(p, t, labels, op, ctx);
    EXPECT_EQ(r.fragments, 1u);
    EXPECT_NEAR(r.fragmentVolume, 36 * 0.3 / 6, 1e-9);
    EXPECT_EQ(t.size(), 1u);
  }
  {
    auto [p, t, labels] = build(4, 1.8);  // 4.8 mm^3, well shaped
    ASSERT_GE(minOver(p, {t[1]}), 15);
    const auto r = optimizeTetMesh(p, t, labels, op, ctx);
    EXPECT_EQ(r.fragments, 0u) << "a good piece heavier than the plain limit stays";
    EXPECT_EQ(t.size(), 2u);
  }
  {
    auto [p, t, labels] = build(12, 0.3);  // 7.2 mm^3, flat: heavier than the limit for bad pieces
    ASSERT_LT(minOver(p, {t[1]}), 15);
    const auto r = optimizeTetMesh(p, t, labels, op, ctx);
    EXPECT_EQ(r.fragments, 0u);
    EXPECT_EQ(t.size(), 2u);
  }
  {
    auto [p, t, labels] = build(6, 0.3);  // the bad 1.8 mm^3 piece, the improvement off
    op.targetMinDihedral = 0;
    const auto r = optimizeTetMesh(p, t, labels, op, ctx);
    EXPECT_EQ(r.fragments, 0u) << "without a target only the plain limit applies";
    EXPECT_EQ(t.size(), 2u);
  }
}

TEST(Optimize, RelabelsAFlatTetInsideAnotherMaterialAndThenRemovesIt) {
  // The cap (material 2) sits on the corner tet's slanted face; three tets of material 1 close it
  // in: all four of its faces are on material 1. A far bulk tet of material 2 keeps it alive.
  auto closedIn = [] {
    CornerWithCap m(0.01, true);
    m.labels = {1, 2, 2};
    m.addBulk(-100, 1);  // both materials large: the relabelling is within their volume budget
    m.closeIn(1);
    return m;
  };
  OptimizeInterfaces in;
  in.projectOntoInterface = [](int, int, Vec3&) { return true; };
  RunContext ctx;
  OptimizeParameters op;
  op.targetMinDihedral = 20;
  op.minFragmentVoxels = 0;
  // The cap is 0.01 thick: thinner than the tolerance (0.05), or than the facet distance (1), it
  // joins material 1; thicker than both it stays.
  for (const auto& [tolerance, facetDistance] :
       std::vector<std::pair<double, double>>{{0.05, 1}, {0.001, 1}, {0.001, 0.005}}) {
    SCOPED_TRACE("tolerance " + std::to_string(tolerance) + ", facet distance " +
                 std::to_string(facetDistance));
    in.facetDistance = facetDistance;
    CornerWithCap m = closedIn();
    ASSERT_GT(minOver(m.p, m.t), 0);
    const double before = minOver(m.p, m.t);
    ASSERT_LT(before, 2);
    const auto volumeBefore = labelVolumes(m.p, m.t, m.labels);
    op.peelDistance = tolerance;
    const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, in, ctx);
    if (tolerance < 0.01 && facetDistance < 0.01) {  // it stays in material 2
      EXPECT_EQ(r.relabelledTets, 0u);
      EXPECT_EQ(m.labels[1], 2);
      continue;
    }
    EXPECT_EQ(r.relabelledTets, 1u);
    EXPECT_GE(r.edgeRemovals + r.faceFlips + r.smoothedVertices, 1u)
        << "inside material 1, the flat tet is flipped or smoothed away";
    EXPECT_GT(minOver(m.p, m.t), before);
    const auto volumeAfter = labelVolumes(m.p, m.t, m.labels);
    EXPECT_NEAR(volumeAfter.at(1) + volumeAfter.at(2), volumeBefore.at(1) + volumeBefore.at(2),
                1e-9);
    EXPECT_NEAR(volumeAfter.at(2), volumeBefore.at(2) - std::sqrt(3.0) / 2 * 0.01 / 3, 1e-9);
  }
}

TEST(Optimize, RelabelsASliverWhereTheNewInterfaceCannotBeCheckedOnlyWhenThinnerThanTheFacetDistance) {
  // As above, but the corner tet is material 3: joining material 1 turns the cap's base into an
  // interface of 1 and 3, which the projection here cannot place (it fails). The cap (0.01 thick)
  // may still go when it is thinner than the facet distance (its faces then lie that close to
  // the ones they replace), not otherwise.
  for (const double facetDistance : {1.0, 0.005}) {
    CornerWithCap m(0.01, true);
    m.labels = {3, 2, 2};
    m.addBulk(-100, 1);
    m.addBulk(300, 3);
    m.closeIn(1);
    OptimizeInterfaces in;
    in.projectOntoInterface = [](int, int, Vec3&) { return false; };
    in.facetDistance = facetDistance;
    RunContext ctx;
    OptimizeParameters op;
    op.targetMinDihedral = 20;
    op.peelDistance = 0.05;
    op.minFragmentVoxels = 0;
    op.splitEdges = false;  // a split would halve the cap in its plane: relabelling is the subject
    const double before2 = labelVolumes(m.p, m.t, m.labels).at(2);
    const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, in, ctx);
    const double cap = std::sqrt(3.0) / 2 * 0.01 / 3;
    if (facetDistance > 0.5) {
      EXPECT_GE(r.relabelledTets, 1u);
      EXPECT_NEAR(labelVolumes(m.p, m.t, m.labels).at(2), before2 - cap, 1e-9) << "the cap left";
    } else {
      EXPECT_EQ(r.relabelledTets, 0u);
      bool capStayed = false;  // (its vertices, junction points, may move a little)
      for (size_t i = 0; i < m.t.size(); ++i) {
        auto T = m.t[i];
        std::sort(T.begin(), T.end());
        capStayed |= m.labels[i] == 2 && T == std::array<int32_t, 4>{1, 2, 3, 4};
      }
      EXPECT_TRUE(capStayed);
    }
  }
}

namespace {

/// A sliver (A, B, C, D) lying on the plane z = 0 (edge AC on it, edge BD `lift` above), its two
/// lower faces on two tets reaching down to E, and a far bulk tet: material 1 throughout. The
/// sliver's upper faces, and the lower tets' other faces, are the outer boundary.
struct SliverOnPlane {
  std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, -1}};
  Tets t = {{0, 1, 2, 3}, {0, 2, 1, 4}, {0, 3, 2, 4}};
  std::vector<int32_t> labels = {1, 1, 1};
  explicit SliverOnPlane(double lift) {
    p[1][2] = p[3][2] = lift;
    for (auto& T : t) orientPositively(p, T);
    addBulkTet(p, t, labels, 100, 1);
  }
  /// The smooth boundary: the plane z = 0, the interface of the background (0) alone.
  static OptimizeInterfaces boundary(double facetDistance) {
    OptimizeInterfaces in;
    in.projectOntoInterface = [](int a, int, Vec3& q) {
      q[2] = 0;
      return a == 0;
    };
    in.facetDistance = facetDistance;
    return in;
  }
  /// Peeling by the facet distance alone: a tiny peel distance, no interface moves or insertion.
  static OptimizeParameters peeling() {
    OptimizeParameters op;
    op.targetMinDihedral = 20;
    op.peelDistance = 0.001;
    op.minFragmentVoxels = 0;
    op.moveInterfaces = false;
    op.insertVertices = false;
    return op;
  }
};

}  // namespace

TEST(Optimize, PeelsAThickerBoundarySliverWhenTheSurfaceBelowIsWithinTheFacetDistance) {
  // The sliver is 0.05 above the plane, far thicker than the peel distance: it goes only when the
  // faces that come to the surface (centroids 0.05 / 3 off the plane) are within the facet
  // distance of the smooth boundary, here the plane z = 0.
  for (const double facetDistance : {0.05, 0.01}) {
    SliverOnPlane m(0.05);
    ASSERT_GT(minOver(m.p, m.t), 0);
    ASSERT_LT(minOver(m.p, m.t), 10);
    const OptimizeInterfaces in = SliverOnPlane::boundary(facetDistance);
    RunContext ctx;
    OptimizeParameters op = SliverOnPlane::peeling();
    op.minDihedralWarning = 20;  // below the warning: peeling is tried before the flips
    const double volumeBefore = labelVolumes(m.p, m.t, m.labels).at(1);
    const auto r = optimizeTetMesh(m.p, m.t, m.labels, op, in, ctx);
    if (facetDistance > 0.05 / 3) {
      EXPECT_EQ(r.peeledTets, 1u);
      EXPECT_EQ(m.t.size(), 3u);
      EXPECT_GE(minOver(m.p, m.t), 20) << "what is left is the two tets below and the bulk";
    } else {  // edge AC may be flipped away instead (a 3-to-2 flip inside material 1)
      EXPECT_EQ(r.peeledTets, 0u);
      EXPECT_NEAR(labelVolumes(m.p, m.t, m.labels).at(1), volumeBefore, 1e-9);
    }
  }
}

TEST(Optimize, NeverPeelsABoundarySliverWhenThatWouldPinchTheBoundary) {
  // The two lower tets reach down to two different points: edge AC is on the outer boundary
  // already, and peeling the sliver would leave it with four outer faces (a non-manifold
  // boundary), so it stays.
  SliverOnPlane m(0.05);
  m.p.push_back({0.5, 0.5, -1.2});
  for (int32_t& v : m.t[2])
    if (v == 4) v = int32_t(m.p.size() - 1);
  RunContext ctx;
  const auto r = optimizeTetMesh(m.p, m.t, m.labels, SliverOnPlane::peeling(), SliverOnPlane::boundary(1),
                                 ctx);
  EXPECT_EQ(r.peeledTets, 0u);
  EXPECT_EQ(m.t.size(), 4u);
}

TEST(Optimize, MovesAJunctionOfFourMaterialsWithinAQuarterOfTheFacetDistance) {
  // Eight tets around the centre of an octahedron, two of each of four materials; the centre
  // sits near the +x corner, so the tets on it are flat. Every interface "projection" succeeds
  // where it is (no distance bound), except onto the background and onto triple lines.
  for (const double facetDistance : {2.0, 0.2}) {
    std::vector<Vec3> p = {{0.8, 0.05, 0.03}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                           {0, -1, 0},        {0, 0, 1}, {0, 0, -1}};
    Tets t;
    std::vector<int32_t> labels;
    for (int32_t x : {1, 2})
      for (int32_t y : {3, 4})
        for (int32_t z : {5, 6}) {
          std::array<int32_t, 4> T{0, x, y, z};
          if (tetMinDihedral(p[size_t(T[0])], p[size_t(T[1])], p[size_t(T[2])], p[size_t(T[3])]) < 0)
            std::swap(T[2], T[3]);
          t.push_back(T);
          labels.push_back(1 + (x == 1 ? 0 : 2) + (y == 3 ? 0 : 1));
        }
    // Far bulk tets, one per material, so that the move is within the materials' volume budget.
    for (int32_t label = 1; label <= 4; ++label) addBulkTet(p, t, labels, 100.0 * label, label);
    ASSERT_GT(minOver(p, t), 0);
    const double before = minOver(p, t);
    const std::vector<Vec3> start = p;
    OptimizeInterfaces in;
    in.projectOntoInterface = [](int a, int, Vec3&) { return a != 0; };
    in.projectOntoJunction = [](const std::array<int, 3>&, Vec3&) { return false; };
    in.facetDistance = facetDistance;
    RunContext ctx;
    OptimizeParameters op;
    op.targetMinDihedral = 30;
    op.peelDistance = 0;
    op.minFragmentVoxels = 0;
    op.collapseEdges = false;
    op.insertVertices = false;
    const auto r = optimizeTetMesh(p, t, labels, op, in, ctx);
    EXPECT_GE(r.junctionVertices, 1u);
    EXPECT_GT(minOver(p, t), before);
    // The corners are junctions too: their own four materials and the background.
    for (size_t i = 0; i < 7; ++i)
      EXPECT_LE(norm(sub(p[i], start[i])), 0.25 * facetDistance + 1e-9) << "vertex " << i;
  }
}

// The octahedron above with facet distance 0.2: the regular rounds move the centre by at most a
// quarter of it; the inserting rounds' last resort (off-interface move) by up to 0.95 of it,
// which lifts the worst tet further (frogtissue's junctions of three materials and the outside).
TEST(Optimize, InsertingRoundsMoveAJunctionOfFourMaterialsWithinTheFacetDistance) {
  const double facetDistance = 0.2;
  double worst[2] = {0, 0}, moved[2] = {0, 0};
  for (const bool inserting : {false, true}) {
    std::vector<Vec3> p = {{0.8, 0.05, 0.03}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                           {0, -1, 0},        {0, 0, 1}, {0, 0, -1}};
    Tets t;
    std::vector<int32_t> labels;
    for (int32_t x : {1, 2})
      for (int32_t y : {3, 4})
        for (int32_t z : {5, 6}) {
          std::array<int32_t, 4> T{0, x, y, z};
          orientPositively(p, T);
          t.push_back(T);
          labels.push_back(1 + (x == 1 ? 0 : 2) + (y == 3 ? 0 : 1));
        }
    for (int32_t label = 1; label <= 4; ++label) addBulkTet(p, t, labels, 100.0 * label, label);
    const Vec3 start = p[0];
    OptimizeInterfaces in;
    in.projectOntoInterface = [](int a, int, Vec3&) { return a != 0; };
    in.projectOntoJunction = [](const std::array<int, 3>&, Vec3&) { return false; };
    in.facetDistance = facetDistance;
    RunContext ctx;
    OptimizeParameters op;
    op.targetMinDihedral = 30;
    op.peelDistance = 0;
    op.minFragmentVoxels = 0;
    op.collapseEdges = false;
    op.splitEdges = false;
    op.insertVertices = inserting;
    const auto r = optimizeTetMesh(p, t, labels, op, in, ctx);
    worst[inserting] = minOver(p, t);
    moved[inserting] = norm(sub(p[0], start));
    if (inserting) EXPECT_GE(r.offInterfaceMoves, 1u);
  }
  EXPECT_LE(moved[0], 0.25 * facetDistance + 1e-9);
  EXPECT_GT(moved[1], 0.25 * facetDistance + 1e-6);
  EXPECT_LE(moved[1], 0.95 * facetDistance + 1e-9);
  EXPECT_GT(worst[1], worst[0] + 1) << "moving farther should lift the worst tet clearly";
}

// A thin wedge of material 3 (8 degrees) ending between materials 1 and 2 on the y axis, the
// triple line: a ring of nine points around the axis, fanned to four axis points (the two inner
// ones, A and B, are triple-line vertices with closed stars). Every tet of the wedge has its 8
// degree dihedral at the axis, and the three sheets are nearly parallel, so the line has no
// reliable direction: only a move of A and B off the line, into the wedge, helps (colin27's
// worst tet, 8.28 degrees before). The moved vertices stay within 0.95 facet distance of the line
// and every interface triangle within the facet distance of its plane. In the second run the
// wedge's own interfaces cannot be found within 0.34 of the axis (as where the third material
// leads in a real wedge): the triangles there are measured to the triple line instead.
TEST(Optimize, MovesATripleLineVertexIntoAThinWedgeOffTheLine) {
  for (const bool nearAxisFound : {true, false}) {
    SCOPED_TRACE(nearAxisFound ? "wedge interfaces found everywhere" : "not near the axis");
    const double half = 4 * M_PI / 180;
    std::vector<Vec3> p = {{0, -1, 0}, {0, 0, 0}, {0, 1, 0}, {0, 2, 0}};  // A', A, B, B'
    const std::vector<double> ring = {-half, half,         M_PI / 4,     M_PI / 2,    3 * M_PI / 4,
                                      M_PI,  5 * M_PI / 4, 3 * M_PI / 2, 7 * M_PI / 4};
    for (double phi : ring) p.push_back({std::cos(phi), 0.5, std::sin(phi)});
    Tets t;
    std::vector<int32_t> labels;
    for (size_t i = 0; i < ring.size(); ++i) {
      const int32_t r0 = int32_t(4 + i), r1 = int32_t(4 + (i + 1) % ring.size());
      const double mid = ring[i] + (i + 1 < ring.size() ? ring[i + 1] : ring[0] + 2 * M_PI);
      const int32_t label = i == 0 ? 3 : (std::sin(mid / 2) > 0 ? 1 : 2);
      for (int32_t a = 0; a < 3; ++a) {
        std::array<int32_t, 4> T{a, a + 1, r0, r1};
        orientPositively(p, T);
        t.push_back(T);
        labels.push_back(label);
      }
    }
    for (int32_t label = 1; label <= 3; ++label) addBulkTet(p, t, labels, 100.0 * label, label);
    ASSERT_GT(minOver(p, t), 0);
    const double before = minOver(p, t);
    ASSERT_LT(before, 8.1);
    const double facetDistance = 0.5, tanHalf = std::tan(half);
    OptimizeInterfaces in;
    in.facetDistance = facetDistance;
    // Projections along z: the plane z = 0 between 1 and 2, the wedge's planes z = +-x tan 4deg.
    in.projectOntoInterface = [tanHalf, nearAxisFound](int a, int b, Vec3& x) {
      if (b == 3 && !nearAxisFound && x[0] < 0.34) return false;
      if (a == 1 && b == 2) {
        x[2] = 0;
      } else if (a == 1 && b == 3) {
        x[2] = tanHalf * x[0];
      } else if (a == 2 && b == 3) {
        x[2] = -tanHalf * x[0];
      } else {
        return false;
      }
      return true;
    };
    in.projectOntoJunction = [](const std::array<int, 3>& abc, Vec3& x) {
      if (abc != std::array<int, 3>{{1, 2, 3}}) return false;
      x[0] = x[2] = 0;
      return true;
    };
    const std::vector<Vec3> start = p;
    RunContext ctx;
    OptimizeParameters op;
    op.targetMinDihedral = 30;
    op.peelDistance = 0;
    op.minFragmentVoxels = 0;
    op.collapseEdges = false;
    op.splitEdges = false;
    const auto r = optimizeTetMesh(p, t, labels, op, in, ctx);
    EXPECT_GE(r.offInterfaceMoves, 1u);
    EXPECT_GT(minOver(p, t), 10.0) << "before " << before;
    for (size_t i : {size_t(1), size_t(2)}) {  // A and B: off the line, within 0.95 facet distance
      EXPECT_GT(p[i][0], 0.05) << "vertex " << i << " did not move into the wedge";
      EXPECT_LE(std::hypot(p[i][0], p[i][2]), 0.95 * facetDistance + 1e-9) << "vertex " << i;
    }
    // A' and B' are junctions with the outside: within 0.95 facet distance (the inserting rounds).
    for (size_t i : {size_t(0), size_t(3)})
      EXPECT_LE(norm(sub(p[i], start[i])), 0.95 * facetDistance + 1e-9) << "outer vertex " << i;
  }
}

TEST(Optimize, PhantomMeshKeepsItsMaterialInterfacesAndLosesSlivers) {
  const LabelVolume v = makePhantom();
  MeshingParameters p;
  p.optimize.targetMinDihedral = 0;  // TetGen's mesh as it is
  p.run.computeFidelity = false;
  RunContext ctx;
  auto raw = runPipeline(v, p, ctx);
  ASSERT_TRUE(raw.isOk()) << raw.status().message();
  const TetMesh& before = raw->mesh;
  const double spacing = std::min({v.spacing[0], v.spacing[1], v.spacing[2]});

  OptimizeParameters op;
  op.targetMinDihedral = 15;
  op.peelDistance = 0.1 * spacing;
  auto run = [&](TetMesh& m) {
    RunContext c;
    return optimizeTetMesh(m.points, m.tets, m.tetLabels, op, c);
  };
  TetMesh after = before, again = before;
  const OptimizeResult r = run(after);
  run(again);

  expectConformal(after);
  EXPECT_EQ(materialInterfaces(after), materialInterfaces(before))
      << "a triangle between two materials changed";
  EXPECT_EQ(meshLabels(after), meshLabels(before));
  EXPECT_EQ(after.points, again.points) << "not deterministic";
  EXPECT_EQ(after.tets, again.tets) << "not deterministic";

  const double minBefore = minOver(before.points, before.tets);
  const double minAfter = minOver(after.points, after.tets);
  EXPECT_GE(minAfter, minBefore);
  EXPECT_NEAR(r.minDihedralBefore, minBefore, 1e-9);
  EXPECT_NEAR(r.minDihedralAfter, minAfter, 1e-9);
  const size_t belowBefore = countBelow(before.points, before.tets, 15);
  const size_t belowAfter = countBelow(after.points, after.tets, 15);
  EXPECT_EQ(r.tetsBelowTargetBefore, belowBefore);
  EXPECT_EQ(r.tetsBelowTargetAfter, belowAfter);
  ASSERT_GT(belowBefore, 0u) << "nothing to optimise: the test would prove nothing";
  EXPECT_LT(double(belowAfter), 0.75 * double(belowBefore));  // measured: 1198 -> 589
  EXPECT_GT(r.edgeRemovals + r.faceFlips, 0u);
  // Material volumes change only by what the peeled flat tets held and the boundary slides:
  // within the stage's budget (Optimize.h: 0.5 % of a material's volume; measured 0.12 % on
  // label 4).
  const auto vb = volumes(before), va = volumes(after);
  for (const auto& [label, vol] : vb) EXPECT_NEAR(va.at(label), vol, 5e-3 * vol) << label;
  // Vertex insertion is what helps where nothing else does.
  EXPECT_GT(r.insertedVertices, 0u);
  TetMesh without = before;
  op.insertVertices = false;
  const OptimizeResult r0 = run(without);
  EXPECT_EQ(r0.insertedVertices, 0u);
  EXPECT_LT(belowAfter, countBelow(without.points, without.tets, 15));
  std::printf("[optimize] phantom: below 15deg %zu -> %zu (%zu without insertion), min dihedral "
              "%.4f -> %.4f, edge removals %zu, face flips %zu, smoothed %zu, peeled %zu, "
              "inserted %zu\n",
              belowBefore, belowAfter, r0.tetsBelowTargetAfter, minBefore, minAfter,
              r.edgeRemovals, r.faceFlips, r.smoothedVertices, r.peeledTets, r.insertedVertices);
}

// A one-voxel plate at default settings: edge splits (on interfaces too) are what lifts the tets
// no other operation helps; the mesh stays conformal and the material volumes stay. The plate's
// worst tet swings by degrees with the sampling, so splits are judged over eight particle seeds:
// fewer tets below the target in all and a higher mean worst angle than without (2026-11-27,
// seeds 1-8: 67 against 167 tets below 15 degrees, mean worst 13.71 against 12.65 degrees; seed 1
// alone 11.7 against 12.6).
TEST(Optimize, EdgeSplitsOnAOneVoxelPlateLiftTheTetsNothingElseHelps) {
  const LabelVolume v = femesher::test::oneVoxelPlate();
  auto run = [&](bool split, uint64_t seed) {
    MeshingParameters p;
    p.optimize.splitEdges = split;
    p.run.computeFidelity = false;
    p.run.seed = seed;
    RunContext ctx;
    auto r = runPipeline(v, p, ctx);
    EXPECT_TRUE(r.isOk()) << r.status().message();
    return std::move(r).value();
  };
  auto count = [](const PipelineResult& r, const std::string& name) {
    for (const auto& [key, value] : r.counts)
      if (key == name) return value;
    ADD_FAILURE() << "no count " << name;
    return -1.0;
  };
  double belowWith = 0, belowWithout = 0, worstWith = 0, worstWithout = 0, splits = 0;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    const PipelineResult with = run(true, seed), without = run(false, seed);
    EXPECT_EQ(count(without, "optimize_split_edges"), 0);
    splits += count(with, "optimize_split_edges");
    expectConformal(with.mesh);
    EXPECT_EQ(meshLabels(with.mesh), meshLabels(without.mesh));
    const auto vw = volumes(with.mesh), vo = volumes(without.mesh);
    for (const auto& [label, vol] : vo) EXPECT_NEAR(vw.at(label), vol, 5e-3 * vol) << label;
    belowWith += count(with, "optimize_tets_below_target_after");
    belowWithout += count(without, "optimize_tets_below_target_after");
    worstWith += count(with, "optimize_min_dihedral_after") / 8;
    worstWithout += count(without, "optimize_min_dihedral_after") / 8;
  }
  EXPECT_GT(splits, 0);
  EXPECT_LT(belowWith, belowWithout);
  // The mean worst angle over the seeds no longer rises with the splits (2026-11-28, after the
  // insertions into cavities that were not balls and the 3-to-2 flips onto an existing triangle,
  // which left triangles of three tets on thin parts, were refused: 13.76 without, 13.43 with;
  // 12.65 and 13.71 before): it may not drop by more than half a degree.
  EXPECT_GT(worstWith, worstWithout - 0.5);
  std::printf("[optimize] plate over seeds 1-8, %g edge splits: below target %g -> %g, mean worst "
              "%.2f -> %.2f deg\n",
              splits, belowWithout, belowWith, worstWithout, worstWith);
}

TEST(Optimize, OffLeavesTheMeshAlone) {
  std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 0.001}};
  Tets t = {{0, 1, 2, 3}};
  std::vector<int32_t> labels = {1};
  const auto p0 = p;
  RunContext ctx;
  OptimizeParameters op;
  op.targetMinDihedral = 0;
  const auto r = optimizeTetMesh(p, t, labels, op, ctx);
  EXPECT_EQ(p, p0);
  EXPECT_EQ(r.passes, 0);
}

namespace {

/// n^3 unit cubes on [0, n]^3, each split into six tets along its main diagonal (conformal);
/// material 1 below z = n / 2, 2 above. The interface vertices off the box are shifted within the
/// plane z = n / 2 (deterministically), which leaves flat tets on both sides of it.
struct PlaneInterfaceMesh {
  std::vector<Vec3> p;
  Tets t;
  std::vector<int32_t> labels;
  explicit PlaneInterfaceMesh(int n) {
    auto id = [n](int i, int j, int k) { return int32_t(i + (n + 1) * (j + (n + 1) * k)); };
    for (int k = 0; k <= n; ++k)
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
          Vec3 x{double(i), double(j), double(k)};
          if (2 * k == n && i > 0 && j > 0 && i < n && j < n) {
            x[0] += 0.3 * std::sin(3.1 * i + 1.7 * j);
            x[1] += 0.3 * std::cos(2.3 * i - 1.3 * j);
          }
          p.push_back(x);
        }
    const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int k = 0; k < n; ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
          for (const auto& a : perm) {
            int c[3] = {i, j, k};
            std::array<int32_t, 4> T;
            T[0] = id(c[0], c[1], c[2]);
            for (int s = 0; s < 3; ++s) {
              ++c[a[s]];
              T[size_t(s + 1)] = id(c[0], c[1], c[2]);
            }
            orientPositively(p, T);
            t.push_back(T);
            labels.push_back(2 * k < n ? 1 : 2);
          }
  }
};

/// The interfaces of PlaneInterfaceMesh(n): materials 1 and 2 meet on the plane z = n / 2 (the
/// projection onto it counts its calls in `calls` when given), the box is [0, n]^3, the facet
/// distance 0.1.
OptimizeInterfaces planeInterfaces(int n, int* calls = nullptr) {
  OptimizeInterfaces in;
  in.projectOntoInterface = [n, calls](int a, int b, Vec3& x) {
    if (calls) ++*calls;
    if (a != 1 || b != 2) return false;  // the box faces are no interface of these tests
    x[2] = n / 2.0;
    return true;
  };
  in.hasBox = true;
  in.boxLo = {0, 0, 0};
  in.boxHi = {double(n), double(n), double(n)};
  in.boxTolerance = 1e-9;
  in.facetDistance = 0.1;
  return in;
}

/// Every face of the tets (sorted vertex triple) with the labels of the tets holding it.
std::map<std::array<int32_t, 3>, std::vector<int32_t>> faceLabels(const Tets& tets,
                                                                  const std::vector<int32_t>& labels) {
  std::map<std::array<int32_t, 3>, std::vector<int32_t>> faces;
  for (size_t t = 0; t < tets.size(); ++t)
    for (int k = 0; k < 4; ++k) {
      std::array<int32_t, 3> f;
      int c = 0;
      for (int q = 0; q < 4; ++q)
        if (q != k) f[size_t(c++)] = tets[t][size_t(q)];
      std::sort(f.begin(), f.end());
      faces[f].push_back(labels[t]);
    }
  return faces;
}

}  // namespace

TEST(Optimize, MovesInterfaceVerticesWithinTheirPlaneOnly) {
  const int n = 4;
  PlaneInterfaceMesh mesh(n);
  ASSERT_GT(minOver(mesh.p, mesh.t), 0);
  const double before = minOver(mesh.p, mesh.t);
  int calls = 0;
  OptimizeInterfaces in = planeInterfaces(n, &calls);
  OptimizeParameters op;
  op.targetMinDihedral = 30;
  op.peelDistance = 0;  // flat tets on the box would be peeled, which changes the volumes
  RunContext ctx;
  // Interfaces fixed (no callbacks): the flat tets at the shifted plane stay below the target.
  PlaneInterfaceMesh fixed(n);
  const auto r0 = optimizeTetMesh(fixed.p, fixed.t, fixed.labels, op, ctx);
  EXPECT_EQ(r0.interfaceVertices, 0u);
  const auto volumes0 = labelVolumes(mesh.p, mesh.t, mesh.labels);
  for (const auto& [label, v] : volumes0) ASSERT_NEAR(v, n * n * n / 2.0, 1e-9) << "tets overlap";
  const auto r = optimizeTetMesh(mesh.p, mesh.t, mesh.labels, op, in, ctx);
  EXPECT_GT(calls, 0);
  EXPECT_GE(r.interfaceVertices, 1u);
  EXPECT_EQ(r.tripleLineVertices, 0u);
  EXPECT_EQ(r.peeledTets, 0u);
  EXPECT_GT(minOver(mesh.p, mesh.t), before);
  EXPECT_GT(minOver(mesh.p, mesh.t), minOver(fixed.p, fixed.t) + 1)
      << "moving the interface vertices should do clearly better than leaving them";
  // Nothing dropped, the interface stays the plane, box vertices stay, volumes are exact.
  ASSERT_EQ(mesh.p.size(), size_t((n + 1) * (n + 1) * (n + 1)));
  size_t movedOnPlane = 0, movedOnBox = 0;
  PlaneInterfaceMesh start(n);
  for (size_t i = 0; i < mesh.p.size(); ++i) {
    const Vec3& s = start.p[i];
    if (s[2] == n / 2.0) {
      EXPECT_EQ(mesh.p[i][2], n / 2.0) << "interface vertex " << i << " left the plane";
      movedOnPlane += mesh.p[i] != s;
      // On one box face: along the interface's trace on it (the box's edges stay).
      const int onFaces = (s[0] == 0 || s[0] == n) + (s[1] == 0 || s[1] == n);
      if (onFaces == 2) EXPECT_EQ(mesh.p[i], s) << "box-edge vertex " << i << " moved";
      movedOnBox += onFaces == 1 && mesh.p[i] != s;
    }
    for (int a = 0; a < 3; ++a)  // box vertices stay on their faces
      if (s[a] == 0 || s[a] == n) EXPECT_EQ(mesh.p[i][a], s[a]) << "box vertex " << i << " left its face";
  }
  EXPECT_GT(movedOnPlane, 0u);
  EXPECT_GT(movedOnBox, 0u) << "no interface vertex on a box face moved";
  const auto volumes1 = labelVolumes(mesh.p, mesh.t, mesh.labels);
  for (const auto& [label, v] : volumes0) EXPECT_NEAR(volumes1.at(label), v, 1e-9 * v);
  // Every face is held by one tet (box) or two (inside a material or on the interface).
  for (const auto& [f, held] : faceLabels(mesh.t, mesh.labels)) EXPECT_LE(held.size(), 2u);
  // A refused facet distance (0) leaves the interface vertices where they are.
  PlaneInterfaceMesh strict(n);
  in.facetDistance = 0;
  const auto r2 = optimizeTetMesh(strict.p, strict.t, strict.labels, op, in, ctx);
  EXPECT_EQ(r2.interfaceVertices, 0u);
}

// Two interface vertices 0.02 apart on the plane between the materials, and one on a box face
// 0.02 from one on a box edge: the short edges are collapsed onto one end (never moving a box
// vertex off a box plane), the interface stays the plane, volumes stay exact, no face is held by three tets, the worst angle
// rises; with collapseEdges off nothing is collapsed.
TEST(Optimize, CollapsesAShortInterfaceEdgeAndKeepsTheInterface) {
  const int n = 4;
  auto build = [n] {
    PlaneInterfaceMesh m(n);
    auto id = [n](int i, int j, int k) { return size_t(i + (n + 1) * (j + (n + 1) * k)); };
    for (int j = 1; j < n; ++j)  // an undisturbed plane, then one vertex next to its neighbour
      for (int i = 1; i < n; ++i) m.p[id(i, j, n / 2)] = {double(i), double(j), n / 2.0};
    m.p[id(1, 1, n / 2)] = {1.98, 1.0, n / 2.0};
    // On the box face x = 0, next to the vertex on the box edge x = y = 0.
    m.p[id(0, 1, n / 2)] = {0.0, 0.02, n / 2.0};
    // In the tets of that edge the face vertex comes first (an even permutation keeps the
    // orientation), so the first collapse tried is the edge vertex's, which must be refused.
    const int32_t inner = int32_t(id(0, 1, n / 2)), box = int32_t(id(0, 0, n / 2));
    for (auto& T : m.t) {
      const auto at = [&T](int32_t v) { return std::find(T.begin(), T.end(), v) - T.begin(); };
      if (at(inner) == 4 || at(box) == 4) continue;
      while (at(inner) > at(box)) {  // the 3-cycle of positions 1, 2, 3, then 0, 1, 2
        const int a = at(inner) == 0 || at(box) == 0 ? 0 : 1;
        const int32_t x = T[size_t(a)];
        T[size_t(a)] = T[size_t(a + 2)];
        T[size_t(a + 2)] = T[size_t(a + 1)];
        T[size_t(a + 1)] = x;
      }
    }
    return m;
  };
  PlaneInterfaceMesh mesh = build();
  const double before = minOver(mesh.p, mesh.t);
  ASSERT_GT(before, 0) << "the start must be a valid mesh";
  ASSERT_LT(before, 2);
  const size_t points = mesh.p.size();
  const OptimizeInterfaces in = planeInterfaces(n);  // collapses edges up to 0.1
  OptimizeParameters op;
  op.targetMinDihedral = 15;
  op.insertVertices = false;
  op.peelDistance = 0;  // peeling would take the flat tets on the box face instead
  RunContext ctx;
  const auto volumes0 = labelVolumes(mesh.p, mesh.t, mesh.labels);
  const auto r = optimizeTetMesh(mesh.p, mesh.t, mesh.labels, op, in, ctx);
  EXPECT_GE(r.collapsedEdges, 1u);
  EXPECT_EQ(mesh.p.size(), points - r.collapsedEdges) << "each collapse drops one vertex";
  EXPECT_GT(minOver(mesh.p, mesh.t), before + 5);
  const auto volumes1 = labelVolumes(mesh.p, mesh.t, mesh.labels);
  for (const auto& [label, v] : volumes0) EXPECT_NEAR(volumes1.at(label), v, 1e-9 * v);
  const auto faces = faceLabels(mesh.t, mesh.labels);
  size_t interfaceFaces = 0;
  for (const auto& [f, held] : faces) {
    EXPECT_LE(held.size(), 2u);
    if (held.size() != 2 || held[0] == held[1]) continue;
    ++interfaceFaces;
    for (int32_t v : f) EXPECT_EQ(mesh.p[size_t(v)][2], n / 2.0) << "interface face off the plane";
  }
  EXPECT_EQ(interfaceFaces > 0, true);
  // The box stays exact: its six faces are still covered by outer triangles lying on them (the
  // box-edge vertex collapsed onto the one at y = 0.02 would tilt some of them).
  for (int a = 0; a < 3; ++a)
    for (double plane : {0.0, double(n)}) {
      double area = 0;
      for (const auto& [f, held] : faces) {
        if (held.size() != 1) continue;
        const Vec3 &A = mesh.p[size_t(f[0])], &B = mesh.p[size_t(f[1])], &C = mesh.p[size_t(f[2])];
        if (A[a] == plane && B[a] == plane && C[a] == plane) area += norm(cross(sub(B, A), sub(C, A))) / 2;
      }
      EXPECT_NEAR(area, double(n * n), 1e-9) << "box face " << a << " at " << plane;
    }
  PlaneInterfaceMesh off = build();
  op.collapseEdges = false;
  EXPECT_EQ(optimizeTetMesh(off.p, off.t, off.labels, op, in, ctx).collapsedEdges, 0u);
}

// An interface vertex moved 0.6 along the plane between the materials, 0.4 from its neighbour:
// the edge is four facet distances long, so the short-edge collapse leaves it; the long collapse
// of the inserting rounds takes it when every interface triangle then around the kept end lies
// within the facet distance of the interface, and refuses it (leaving the mesh as it was) where
// the interface cannot be found at those triangles.
TEST(Optimize, CollapsesALongInterfaceEdgeOnlyWhereTheTrianglesLeftAreWithinTheFacetDistance) {
  using namespace femesher::optimize_detail;
  const int n = 4;
  auto id = [n](int i, int j, int k) { return int32_t(i + (n + 1) * (j + (n + 1) * k)); };
  PlaneInterfaceMesh mesh(n);
  for (int j = 1; j < n; ++j)
    for (int i = 1; i < n; ++i) mesh.p[size_t(id(i, j, n / 2))] = {double(i), double(j), n / 2.0};
  const int32_t gone = id(1, 1, n / 2), keep = id(2, 1, n / 2);
  mesh.p[size_t(gone)] = {1.6, 1.0, n / 2.0};
  Editor m(mesh.p, mesh.t, mesh.labels);
  uint32_t t = 0;
  double worst = 180;
  for (uint32_t s : m.around[size_t(gone)]) worst = std::min(worst, m.quality(s));
  for (uint32_t s : m.around[size_t(gone)])
    if (m.has(s, keep) && m.quality(s) == worst) t = s;
  ASSERT_TRUE(m.has(t, keep)) << "the worst tet around the moved vertex holds the short edge";
  auto liveVolumes = [&m] {
    std::map<int32_t, double> v;
    for (uint32_t s = 0; s < m.tets.size(); ++s)
      if (m.alive[s]) v[m.labels[s]] += m.volume(s);
    return v;
  };
  const auto volumes0 = liveVolumes();
  const size_t live0 = size_t(std::count(m.alive.begin(), m.alive.end(), 1));
  OptimizeInterfaces in = planeInterfaces(n);
  std::vector<uint32_t> fresh;
  EXPECT_FALSE(collapseEdge(m, t, in.facetDistance, in, false, fresh)) << "0.4 is no short edge";
  // The interface is not found left of x = 1.5 (a third material would lead there): the
  // triangles that would reach x = 1 from the kept vertex cannot be checked.
  OptimizeInterfaces unsure = in;
  unsure.projectOntoInterface = [n](int a, int b, Vec3& x) {
    if (a != 1 || b != 2 || x[0] < 1.5) return false;
    x[2] = n / 2.0;
    return true;
  };
  EXPECT_FALSE(collapseEdge(m, t, 8 * in.facetDistance, unsure, true, fresh));
  EXPECT_TRUE(fresh.empty());
  EXPECT_EQ(size_t(std::count(m.alive.begin(), m.alive.end(), 1)), live0) << "a refusal undoes";
  EXPECT_EQ(liveVolumes(), volumes0);
  ASSERT_TRUE(collapseEdge(m, t, 8 * in.facetDistance, in, true, fresh));
  EXPECT_FALSE(m.alive[t]);
  EXPECT_TRUE(m.around[size_t(gone)].empty() || m.around[size_t(keep)].empty());
  double after = 180;
  for (uint32_t s : fresh) after = std::min(after, m.quality(s));
  EXPECT_GT(after, worst + 5);
  const auto volumes1 = liveVolumes();
  for (const auto& [label, v] : volumes0) EXPECT_NEAR(volumes1.at(label), v, 1e-9 * v);
  Tets live;
  std::vector<int32_t> liveLabels;
  for (uint32_t s = 0; s < m.tets.size(); ++s)
    if (m.alive[s]) live.push_back(m.tets[s]), liveLabels.push_back(m.labels[s]);
  for (const auto& [f, held] : faceLabels(live, liveLabels)) {
    EXPECT_LE(held.size(), 2u);
    if (held.size() == 2 && held[0] != held[1])
      for (int32_t v : f) EXPECT_EQ(mesh.p[size_t(v)][2], n / 2.0) << "interface face off the plane";
  }
}

// One budget per material for every operation that changes its volume: peeling takes at most
// kPeelBudget of it, and the net moved volume (either sign) and the peeled one together at most
// kVolumeBudget, so a material that peeling left alone may move more.
TEST(Optimize, PeelingAndInterfaceMovesShareOneVolumeBudgetPerMaterial) {
  using namespace femesher::optimize_detail;
  TetMesh grid = femesher::test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3& g) {
    return g[2] < 2 ? 1 : 2;
  });
  Editor m(grid.points, grid.tets, grid.tetLabels);
  ASSERT_NEAR(m.startVolume[1], 32.0, 1e-12);
  const double all = kVolumeBudget * 32, peel = kPeelBudget * 32;
  ASSERT_LT(peel, all);
  EXPECT_TRUE(m.moveFits(1, 0.99 * all));
  EXPECT_TRUE(m.moveFits(1, -0.99 * all));
  EXPECT_FALSE(m.moveFits(1, -1.01 * all));
  EXPECT_TRUE(m.peelFits(1, 0.99 * peel, 1.0));
  EXPECT_FALSE(m.peelFits(1, 1.01 * peel, 1.0));
  EXPECT_FALSE(m.peelFits(1, 0.99 * peel, 0.75)) << "the share of the peel budget";
  m.peeledVolume[1] = 0.99 * peel;  // what peeling took
  EXPECT_TRUE(m.moveFits(1, 0.99 * (all - m.peeledVolume[1])));
  EXPECT_FALSE(m.moveFits(1, -1.01 * (all - m.peeledVolume[1])));
  EXPECT_TRUE(m.moveFits(2, 0.99 * all)) << "material 2 has its own budget";
  m.peeledVolume[1] = 0;
  m.movedVolume[1] = -0.9 * all;  // what the moves took: peeling gets only the rest
  EXPECT_FALSE(m.peelFits(1, 0.2 * all, 1.0));
  EXPECT_TRUE(m.peelFits(1, 0.09 * all, 1.0));
}

// Vertex insertion joins the faces of its cavity to one new vertex: only a cavity bounded by a
// sphere may be used. Two tets sharing only an edge or only a vertex (a cavity that touched
// itself around a thin rod) would give a triangle held by three or more tets.
TEST(Optimize, InsertionCavityMustBeBoundedByASphere) {
  using optimize_detail::sphereShell;
  using Shell = std::vector<std::pair<std::array<int32_t, 4>, int>>;
  auto facesOf = [](const std::vector<std::array<int32_t, 4>>& cavity) {
    Shell shell;
    for (const auto& T : cavity)
      for (int k = 0; k < 4; ++k) shell.push_back({T, k});
    return shell;
  };
  EXPECT_TRUE(sphereShell(facesOf({{0, 1, 2, 3}})));
  EXPECT_FALSE(sphereShell(facesOf({{0, 1, 2, 3}, {0, 1, 4, 5}}))) << "two tets on one edge";
  EXPECT_FALSE(sphereShell(facesOf({{0, 1, 2, 3}, {0, 4, 5, 6}}))) << "two tets at one vertex";
  // Two tets sharing a face: the shell is their six outer faces, a sphere.
  Shell two = facesOf({{0, 1, 2, 3}, {1, 2, 3, 4}});
  two.erase(std::remove_if(two.begin(), two.end(),
                           [](const auto& f) {
                             return (f.first[0] == 0 && f.second == 0) ||
                                    (f.first[0] == 1 && f.second == 3);
                           }),
            two.end());
  ASSERT_EQ(two.size(), 6u);
  EXPECT_TRUE(sphereShell(two));
  Shell open = facesOf({{0, 1, 2, 3}});
  open.pop_back();
  EXPECT_FALSE(sphereShell(open)) << "an open shell";
}

// Should an operation ever leave a triangle held by three tets, the stage stops with a clear
// error instead of returning a mesh that is not conformal (here the input already has one: a tet
// on one side of a triangle, two on the other).
TEST(Optimize, StopsRatherThanReturnAMeshThatIsNotConformal) {
  std::vector<Vec3> p{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 1}, {0.3, 0.3, -1},
                      {0.35, 0.3, -0.02}};
  std::vector<std::array<int32_t, 4>> t{{0, 1, 2, 3}, {0, 2, 1, 4}, {0, 2, 1, 5}};
  std::vector<int32_t> labels{1, 2, 3};  // three materials: no flip joins them
  for (auto& T : t) orientPositively(p, T);
  OptimizeParameters op;
  op.targetMinDihedral = 15;  // the third tet is flat: the rounds run
  op.peelDistance = 0;         // and nothing takes it away
  op.minDihedralWarning = 0;
  op.minFragmentVoxels = 0;
  op.smooth = false;
  op.insertVertices = false;
  op.splitEdges = false;
  op.collapseEdges = false;
  RunContext ctx;
  try {
    optimizeTetMesh(p, t, labels, op, ctx);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::MeshingFailed);
    EXPECT_NE(std::string(e.what()).find("shared by three or more tets"), std::string::npos)
        << e.what();
  }
}

// A vertex move found ahead on a copy of part of the mesh (the rounds' speculative moves) is used
// only when the budgets, as they are then, answer every question it asked on the way the same:
// the log replays the questions after the bookings made before each.
TEST(Optimize, BudgetLogReplaysTheQuestionsOfAMoveFoundAhead) {
  using namespace femesher::optimize_detail;
  TetMesh grid = femesher::test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3& g) {
    return g[2] < 2 ? 1 : 2;
  });
  Editor m(grid.points, grid.tets, grid.tetLabels);
  const double all = kVolumeBudget * 32;
  std::vector<Editor::BudgetEvent> log;
  {
    Editor copy(grid.points, grid.tets, grid.tetLabels);
    copy.budgetLog = &log;
    EXPECT_TRUE(copy.moveFits(1, 0.5 * all));
    copy.bookMove(1, 0.5 * all);
    EXPECT_FALSE(copy.moveFits(1, 0.6 * all)) << "0.5 + 0.6 of the budget";
    EXPECT_TRUE(copy.moveFits(1, 0.4 * all));
    EXPECT_TRUE(copy.moveFits(2, 0.9 * all)) << "material 2 has its own budget";
    EXPECT_TRUE(copy.moveFits(1, 0.0)) << "no change always fits";
  }
  ASSERT_EQ(log.size(), 5u) << "no change asks nothing";
  EXPECT_TRUE(m.budgetsAgree(log));
  m.movedVolume[1] = -0.15 * all;  // 0.5 + 0.6 - 0.15 now fits: the second answer changes
  EXPECT_FALSE(m.budgetsAgree(log));
  m.movedVolume[1] = -0.05 * all;  // every answer as before
  EXPECT_TRUE(m.budgetsAgree(log));
  m.peeledVolume[2] = 0.2 * all;  // material 2's question now fails
  EXPECT_FALSE(m.budgetsAgree(log));
  m.peeledVolume[2] = 0;
  m.replayBookings(log);
  EXPECT_DOUBLE_EQ(m.movedVolume[1], -0.05 * all + 0.5 * all);
  EXPECT_EQ(m.movedVolume[2], 0.0);
}

TEST(Optimize, FlipsAnInterfaceEdgeWhenTheNewTrianglesStayWithinTheFacetDistance) {
  // A sliver (A, B, C, D) of material 1 lies on the plane interface z = 0 with material 2: its
  // lower faces ABC, ACD (edge AC on the plane, B and D `lift` above it) are on two tets of
  // material 2 reaching down to E; its upper faces are on two tets of material 1 whose apexes
  // lean outwards, so that no flip inside material 1 reaches the sliver. Giving the sliver to
  // material 2 and removing AC makes ABD and BCD the interface: their centroids are 2/3 lift
  // above the plane, which the facet distance must allow (the whole bound, not a quarter of it).
  const double lift = 0.1;
  for (const double facetDistance : {0.2, 0.05}) {
    std::vector<Vec3> p = {{0, 0, 0}, {1, 0, lift}, {1, 1, 0},    {0, 1, lift},
                           {0.5, 0.5, -1}, {-0.5, -0.5, 0.5}, {1.5, 1.5, 0.5}};
    Tets t = {{0, 1, 2, 3}, {0, 2, 1, 4}, {0, 3, 2, 4}, {0, 1, 3, 5}, {1, 2, 3, 6}};
    std::vector<int32_t> labels = {1, 2, 2, 1, 1};
    for (auto& T : t) orientPositively(p, T);
    addBulkTet(p, t, labels, 100, 1);
    addBulkTet(p, t, labels, -100, 2);
    OptimizeInterfaces in;
    in.projectOntoInterface = [](int a, int b, Vec3& q) {
      q[2] = 0;
      return a == 1 && b == 2;
    };
    in.facetDistance = facetDistance;
    OptimizeParameters op;
    op.targetMinDihedral = 20;
    op.peelDistance = 0.001;
    op.minFragmentVoxels = 0;
    op.insertVertices = false;
    op.collapseEdges = false;
    const double before = minOver(p, t);
    ASSERT_NEAR(before, 11.36, 0.01);
    const auto volumeBefore = labelVolumes(p, t, labels);
    RunContext ctx;
    const auto r = optimizeTetMesh(p, t, labels, op, in, ctx);
    const auto volumeAfter = labelVolumes(p, t, labels);
    if (facetDistance < 2.0 / 3 * lift) {  // the new triangles would be too far: nothing changes
      EXPECT_EQ(r.interfaceFlips, 0u);
      EXPECT_DOUBLE_EQ(minOver(p, t), before);
      continue;
    }
    EXPECT_EQ(r.interfaceFlips, 1u);
    EXPECT_GT(minOver(p, t), 20) << "the sliver is gone";
    EXPECT_NEAR(volumeAfter.at(1), volumeBefore.at(1) - lift / 3, 1e-9);
    EXPECT_NEAR(volumeAfter.at(1) + volumeAfter.at(2), volumeBefore.at(1) + volumeBefore.at(2), 1e-9);
  }
}

// Interior coarsening on a 6^3 lattice of cubes (six tets each; interior vertices shifted a
// little) split by the plane z = 3 into two materials: interior vertices go, while every interface and outer triangle, every material's
// volume and the mesh's conformity stay exactly as they were; no new edge is longer than
// coarsenLongEdge × the size, and no tet falls below coarsenMinDihedral. A size below the
// lattice's edges, or coarsening off, changes nothing.
TEST(Optimize, CoarsensTheInteriorWithinTheSizeAndQualityBoundsAndKeepsEveryInterface) {
  const int n = 6;
  auto build = [n] {
    PlaneInterfaceMesh m(n);
    auto id = [n](int i, int j, int k) { return size_t(i + (n + 1) * (j + (n + 1) * k)); };
    for (int j = 1; j < n; ++j)  // an undisturbed plane
      for (int i = 1; i < n; ++i) m.p[id(i, j, n / 2)] = {double(i), double(j), n / 2.0};
    // Interior vertices shifted a little (deterministically): in the exact lattice, every
    // collapse onto a neighbour would leave flat tets, as faces of the star are coplanar with it.
    for (int k = 1; k < n; ++k)
      for (int j = 1; j < n; ++j)
        for (int i = 1; i < n; ++i)
          if (2 * k != n)
            m.p[id(i, j, k)] = {i + 0.12 * std::sin(1.3 * i + 2.1 * j + 0.7 * k),
                                j + 0.12 * std::cos(0.9 * i - 1.7 * j + 2.3 * k),
                                k + 0.12 * std::sin(2.9 * i + 0.4 * j - 1.1 * k)};
    return m;
  };
  // Triangles held by one tet (outer) or by two of different materials (interface), as sorted
  // coordinates: they must not change.
  auto constrainedFaces = [](const PlaneInterfaceMesh& m) {
    std::set<std::vector<double>> out;
    for (const auto& [f, held] : faceLabels(m.t, m.labels)) {
      if (held.size() == 2 && held[0] == held[1]) continue;
      std::vector<Vec3> v{m.p[size_t(f[0])], m.p[size_t(f[1])], m.p[size_t(f[2])]};
      std::sort(v.begin(), v.end());
      std::vector<double> key{double(held.size())};
      for (const auto& x : v) key.insert(key.end(), x.begin(), x.end());
      out.insert(key);
    }
    return out;
  };
  const PlaneInterfaceMesh start = build();
  const double worst0 = minOver(start.p, start.t);
  ASSERT_GT(worst0, 25) << "the lattice should be good";
  OptimizeParameters op;
  op.targetMinDihedral = 15;
  op.coarsenMinDihedral = 20;
  op.coarsenShortEdge = 1.3;
  op.coarsenLongEdge = 1.5;
  op.sizeAt = [](const Vec3&) { return 2.0; };
  RunContext ctx;
  PlaneInterfaceMesh mesh = build(), again = build();
  const auto r = optimizeTetMesh(mesh.p, mesh.t, mesh.labels, op, ctx);
  optimizeTetMesh(again.p, again.t, again.labels, op, ctx);
  EXPECT_EQ(mesh.p, again.p) << "not deterministic";
  EXPECT_EQ(mesh.t, again.t) << "not deterministic";
  const size_t interior = size_t((n - 1) * (n - 1) * (n - 2));  // off the box and the plane
  EXPECT_GT(r.coarsenedVertices, interior / 4) << "the lattice is dense for a size of 2";
  EXPECT_LE(r.coarsenedVertices, interior);
  EXPECT_EQ(mesh.p.size(), start.p.size() - r.coarsenedVertices);
  EXPECT_LT(mesh.t.size(), start.t.size());
  EXPECT_EQ(constrainedFaces(mesh), constrainedFaces(start)) << "an interface or outer face changed";
  const auto v0 = labelVolumes(start.p, start.t, start.labels);
  const auto v1 = labelVolumes(mesh.p, mesh.t, mesh.labels);
  for (const auto& [label, v] : v0) EXPECT_NEAR(v1.at(label), v, 1e-9 * v) << label;
  for (const auto& [f, held] : faceLabels(mesh.t, mesh.labels)) EXPECT_LE(held.size(), 2u);
  EXPECT_GE(minOver(mesh.p, mesh.t), op.coarsenMinDihedral);
  double longest = 0;
  for (const auto& T : mesh.t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        longest = std::max(longest, norm(sub(mesh.p[size_t(T[size_t(a)])], mesh.p[size_t(T[size_t(b)])])));
  EXPECT_LE(longest, op.coarsenLongEdge * 2.0 + 1e-9);
  EXPECT_GT(longest, std::sqrt(3.0) + 0.1) << "coarsening should have made longer edges";
  std::printf("[optimize] coarsening: %zu of %zu interior vertices removed, tets %zu -> %zu, "
              "worst %.1f -> %.1f deg, longest edge %.2f\n",
              r.coarsenedVertices, interior, start.t.size(), mesh.t.size(), worst0,
              minOver(mesh.p, mesh.t), longest);
  // A size at which the lattice's edges (1 and longer) are not short: nothing goes.
  PlaneInterfaceMesh fine = build();
  op.sizeAt = [](const Vec3&) { return 0.7; };
  EXPECT_EQ(optimizeTetMesh(fine.p, fine.t, fine.labels, op, ctx).coarsenedVertices, 0u);
  EXPECT_EQ(fine.t, start.t);
  // Off.
  PlaneInterfaceMesh off = build();
  op.sizeAt = [](const Vec3&) { return 2.0; };
  op.coarsenMinDihedral = 0;
  EXPECT_EQ(optimizeTetMesh(off.p, off.t, off.labels, op, ctx).coarsenedVertices, 0u);
  EXPECT_EQ(off.t, start.t);
}

namespace {

/// Material 1 in the cells x < 2 of the Kuhn grid on [0, 4]^3 (the background beyond the plane
/// x = 2, the box [0, 4]^3), with the interface vertex (2, 2, 1) lowered to (2, 2, h): the tet
/// (1,1,0) (2,1,0) (2,2,0) (2,2,h) is then a flat cap with one face on the box plane z = 0 and
/// one on the interface x = 2.
struct BoxCapMesh {
  std::vector<Vec3> p;
  Tets t;
  std::vector<int32_t> labels;
  int32_t apex = -1;
  explicit BoxCapMesh(double h) {
    TetMesh m = femesher::test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3& c) { return c[0] < 2 ? 1 : 0; });
    p = m.points;
    apex = int32_t(2 + 5 * (2 + 5 * 1));  // (2, 2, 1)
    p[size_t(apex)][2] = h;
    for (size_t q = 0; q < m.tets.size(); ++q)
      if (m.tetLabels[q] == 1) {  // the background has no tets
        auto T = m.tets[q];
        orientPositively(p, T);
        t.push_back(T);
        labels.push_back(1);
      }
  }
  /// Whether a tet has exactly these corners (by position: the optimiser renumbers vertices).
  bool hasTet(std::array<Vec3, 4> q) const {
    std::sort(q.begin(), q.end());
    for (const auto& T : t) {
      std::array<Vec3, 4> c{{p[size_t(T[0])], p[size_t(T[1])], p[size_t(T[2])], p[size_t(T[3])]}};
      std::sort(c.begin(), c.end());
      if (c == q) return true;
    }
    return false;
  }
};

/// Material 1 fills {x <= 2} within the box [0, 4]^3: its interface with the background is the
/// nearest point of that region's boundary (the plane x = 2 or a box face), as the run's clipped
/// indicator functions make it.
OptimizeInterfaces boxCapInterfaces(double facetDistance) {
  OptimizeInterfaces in;
  in.projectOntoInterface = [](int a, int b, Vec3& x) {
    if (a != 0 || b != 1) return false;
    const double d[6] = {std::fabs(x[0] - 2), x[0], x[1], 4 - x[1], x[2], 4 - x[2]};
    const int m = int(std::min_element(d, d + 6) - d);
    if (m == 0) x[0] = 2;
    if (m == 1) x[0] = 0;
    if (m == 2) x[1] = 0;
    if (m == 3) x[1] = 4;
    if (m == 4) x[2] = 0;
    if (m == 5) x[2] = 4;
    return true;
  };
  in.hasBox = true;
  in.boxLo = {0, 0, 0};
  in.boxHi = {4, 4, 4};
  in.boxTolerance = 1e-9;
  in.facetDistance = facetDistance;
  return in;
}

}  // namespace

// A flat cap on the volume's box (one face on a box plane, one on the interface with the
// background) is peeled when its apex is within the facet distance of the box plane, and kept
// when it is not: the box stays flat to the facet distance.
TEST(Optimize, FlatCapOnTheBoxIsPeeledWithinTheFacetDistanceOfTheBoxPlane) {
  const double h = 0.08;
  OptimizeParameters op;
  op.targetMinDihedral = 30;
  op.peelDistance = 1e-4;  // far thinner than the cap: only the facet-distance rule can peel it
  op.moveInterfaces = false;  // the apex would otherwise simply move back up its interface
  op.smooth = false;          // or slide up its flat outer patch
  op.insertVertices = false;
  op.splitEdges = false;
  op.collapseEdges = false;
  op.minDihedralWarning = 0;  // no last resort beyond the budget for what the rules above leave
  RunContext ctx;
  const std::array<Vec3, 4> cap{{{1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {2, 2, h}}};
  for (double facetDistance : {0.1, 0.05}) {
    BoxCapMesh mesh(h);
    ASSERT_TRUE(mesh.hasTet(cap));
    const double before = labelVolumes(mesh.p, mesh.t, mesh.labels).at(1);
    const auto r = optimizeTetMesh(mesh.p, mesh.t, mesh.labels, op, boxCapInterfaces(facetDistance), ctx);
    const double after = labelVolumes(mesh.p, mesh.t, mesh.labels).at(1);
    for (const auto& [f, held] : faceLabels(mesh.t, mesh.labels)) EXPECT_LE(held.size(), 2u);
    if (facetDistance > h) {
      EXPECT_FALSE(mesh.hasTet(cap)) << "the cap's apex is " << h << " from the box plane";
      EXPECT_GE(r.peeledTets, 1u);
      EXPECT_LT(before - after, 0.1) << "only flat tets go";
      EXPECT_GE(before - after, 0.0);
    } else {
      EXPECT_TRUE(mesh.hasTet(cap)) << "an apex beyond the facet distance keeps the box face";
    }
  }
}
