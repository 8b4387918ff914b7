// SPDX-License-Identifier: GPL-3.0-or-later
// Stage 10 (Optimize): sliver removal keeps every interface between materials exactly, never
// lowers the worst angle, peels only thin boundary tets, smooths interior vertices.
#include "MeshInvariants.h"
#include "TetMeasures.h"

#include <femesher/Phantom.h>
#include <femesher/Pipeline.h>
#include <femesher/RunContext.h>
#include <femesher/stages/Optimize.h>

#include <gtest/gtest.h>

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

TEST(Optimize, PeelsAFlatBoundaryCapOnlyWhenThinnerThanTheTolerance) {
  // A corner tet and a cap on its slanted face, lifted by `lift` along the face normal.
  for (const double lift : {0.01, 0.2}) {
    std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const double s = 1.0 / 3.0, n = 1.0 / std::sqrt(3.0);
    p.push_back({s + lift * n, s + lift * n, s + lift * n});
    Tets t = {{0, 1, 2, 3}, {1, 2, 3, 4}};
    if (tetMinDihedral(p[1], p[2], p[3], p[4]) < 0) std::swap(t[1][0], t[1][1]);
    ASSERT_GT(tetMinDihedral(p[t[1][0]], p[t[1][1]], p[t[1][2]], p[t[1][3]]), 0);
    std::vector<int32_t> labels = {1, 1};
    RunContext ctx;
    OptimizeParameters op;
    op.peelDistance = 0.05;
    op.targetMinDihedral = 20;
    const auto r = optimizeTetMesh(p, t, labels, op, ctx);
    if (lift < op.peelDistance) {
      EXPECT_EQ(r.peeledTets, 1u);
      EXPECT_EQ(t.size(), 1u);
      EXPECT_EQ(p.size(), 4u) << "the cap's apex is dropped with it";
    } else {
      EXPECT_EQ(r.peeledTets, 0u);
      EXPECT_EQ(t.size(), 2u);
    }
  }
}

TEST(Optimize, NeverPeelsAMaterialsLastTetNorWithZeroTolerance) {
  std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 0.001}};
  Tets t = {{0, 1, 2, 3}};
  std::vector<int32_t> labels = {4};
  RunContext ctx;
  OptimizeParameters op;
  op.peelDistance = 1;
  auto r = optimizeTetMesh(p, t, labels, op, ctx);
  EXPECT_EQ(t.size(), 1u);
  EXPECT_EQ(r.peeledTets, 0u);
}

TEST(Optimize, SmoothsAnInteriorVertexBackToTheMiddle) {
  // Unit cube: its 8 corners and one interior vertex, 12 tets (a fan over the 12 face triangles).
  std::vector<Vec3> p;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) p.push_back({double(i), double(j), double(k)});
  p.push_back({0.5, 0.5, 0.03});  // pushed against the bottom face
  const int faces[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                           {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  Tets t;
  for (const auto& f : faces)
    for (const auto& tri : {std::array<int, 3>{f[0], f[1], f[2]}, std::array<int, 3>{f[0], f[2], f[3]}}) {
      std::array<int32_t, 4> T{tri[0], tri[1], tri[2], 8};
      if (tetMinDihedral(p[T[0]], p[T[1]], p[T[2]], p[T[3]]) < 0) std::swap(T[0], T[1]);
      t.push_back(T);
    }
  ASSERT_GT(minOver(p, t), 0);
  const double before = minOver(p, t);
  ASSERT_LT(before, 5);
  const auto corners = std::vector<Vec3>(p.begin(), p.begin() + 8);
  std::vector<int32_t> labels(t.size(), 2);
  RunContext ctx;
  OptimizeParameters op;
  op.targetMinDihedral = 30;
  const auto r = optimizeTetMesh(p, t, labels, op, ctx);
  EXPECT_GE(r.smoothedVertices, 1u);
  EXPECT_GT(minOver(p, t), 20) << "the interior vertex should move well away from the face";
  EXPECT_EQ(std::vector<Vec3>(p.begin(), p.begin() + 8), corners) << "boundary vertices moved";
  EXPECT_EQ(r.peeledTets, 0u);
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
  // Material volumes change only by what the peeled flat tets held and the boundary slides.
  const auto vb = volumes(before), va = volumes(after);
  for (const auto& [label, vol] : vb) EXPECT_NEAR(va.at(label), vol, 1e-3 * vol) << label;
  std::printf("[optimize] phantom: below 15deg %zu -> %zu, min dihedral %.4f -> %.4f, edge "
              "removals %zu, face flips %zu, smoothed %zu, peeled %zu\n",
              belowBefore, belowAfter, minBefore, minAfter, r.edgeRemovals, r.faceFlips,
              r.smoothedVertices, r.peeledTets);
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
            if (tetMinDihedral(p[T[0]], p[T[1]], p[T[2]], p[T[3]]) < 0) std::swap(T[0], T[1]);
            t.push_back(T);
            labels.push_back(2 * k < n ? 1 : 2);
          }
  }
};

}  // namespace

TEST(Optimize, MovesInterfaceVerticesWithinTheirPlaneOnly) {
  const int n = 4;
  PlaneInterfaceMesh mesh(n);
  ASSERT_GT(minOver(mesh.p, mesh.t), 0);
  const double before = minOver(mesh.p, mesh.t);
  OptimizeInterfaces in;
  int calls = 0;
  in.projectOntoInterface = [&](int a, int b, Vec3& x) {
    ++calls;
    if (a != 1 || b != 2) return false;  // the box faces are no interface of this test
    x[2] = n / 2.0;
    return true;
  };
  in.hasBox = true;
  in.boxLo = {0, 0, 0};
  in.boxHi = {double(n), double(n), double(n)};
  in.boxTolerance = 1e-9;
  in.facetDistance = 0.1;
  OptimizeParameters op;
  op.targetMinDihedral = 30;
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
  size_t movedOnPlane = 0;
  PlaneInterfaceMesh start(n);
  for (size_t i = 0; i < mesh.p.size(); ++i) {
    const Vec3& s = start.p[i];
    if (s[2] == n / 2.0) {
      EXPECT_EQ(mesh.p[i][2], n / 2.0) << "interface vertex " << i << " left the plane";
      movedOnPlane += mesh.p[i] != s;
    }
    for (int a = 0; a < 3; ++a)  // box vertices stay on their faces
      if (s[a] == 0 || s[a] == n) EXPECT_EQ(mesh.p[i][a], s[a]) << "box vertex " << i << " left its face";
  }
  EXPECT_EQ(movedOnPlane > 0, true);
  const auto volumes1 = labelVolumes(mesh.p, mesh.t, mesh.labels);
  for (const auto& [label, v] : volumes0) EXPECT_NEAR(volumes1.at(label), v, 1e-9 * v);
  // Every face is held by one tet (box) or two (inside a material or on the interface).
  std::map<std::array<int32_t, 3>, int> faceCount;
  for (const auto& T : mesh.t)
    for (int k = 0; k < 4; ++k) {
      std::array<int32_t, 3> f;
      int c = 0;
      for (int q = 0; q < 4; ++q)
        if (q != k) f[size_t(c++)] = T[size_t(q)];
      std::sort(f.begin(), f.end());
      ++faceCount[f];
    }
  for (const auto& [f, c] : faceCount) EXPECT_LE(c, 2);
  // A refused facet distance (0) leaves the interface vertices where they are.
  PlaneInterfaceMesh strict(n);
  in.facetDistance = 0;
  const auto r2 = optimizeTetMesh(strict.p, strict.t, strict.labels, op, in, ctx);
  EXPECT_EQ(r2.interfaceVertices, 0u);
}
