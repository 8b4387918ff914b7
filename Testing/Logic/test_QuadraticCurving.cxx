// SPDX-License-Identifier: GPL-3.0-or-later
// Curved mid-edge nodes (QuadraticCurving): on an analytic sphere between two materials, the
// interface nodes land on the sphere, interior ones stay straight, every element keeps its
// Jacobian above the bound at its 11 check points, nodes on a box plane stay in it, moves that
// would fold elements are halved or refused, and the writers put the curved nodes in the files.
#include <femesher/QuadraticCurving.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>
#include <femesher/io/MeshIO.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "TestShapes.h"

namespace fs = std::filesystem;
using namespace femesher;

namespace {

constexpr int kN = 6;       // cubes per side, edge 1 mm
constexpr double kR = 2.3;  // sphere radius, mm

/// Material 1 inside the sphere of radius kR around `c`, 2 outside; the cube is the volume's box.
/// As a mesher would, the interface vertices near the sphere are put on it (radially; a vertex
/// on a box plane through `c` stays in it).
TetMesh ballMesh(const Vec3& c) {
  TetMesh m = test::cubeGridMesh(kN, 1.0, {0, 0, 0},
                                 [c](const Vec3& g) { return norm(sub(g, c)) < kR ? 1 : 2; });
  std::set<int32_t> onInterface;
  for (const InterfaceTriangle& f : extractInterfaces(m))
    if (f.labelB != kExteriorLabel) onInterface.insert(f.v.begin(), f.v.end());
  for (int32_t v : onInterface) {
    Vec3& p = m.points[size_t(v)];
    const double r = norm(sub(p, c));
    if (std::fabs(r - kR) < 0.3) p = add(c, scale(sub(p, c), kR / r));
  }
  return m;
}

/// Whether both ends of the edge `key` lie on the sphere.
bool onSphere(const TetMesh& m, uint64_t key, const Vec3& c) {
  for (int32_t v : {int32_t(key >> 32), int32_t(key & 0xffffffffu)})
    if (std::fabs(norm(sub(m.points[size_t(v)], c)) - kR) > 1e-9) return false;
  return true;
}

/// The sphere as the interface of materials 1 and 2 (radial projection), the cube as the box.
OptimizeInterfaces sphereInterfaces(const Vec3& c) {
  OptimizeInterfaces in;
  in.projectOntoInterface = [c](int a, int b, Vec3& p) {
    if (a != 1 || b != 2) return false;
    const Vec3 d = sub(p, c);
    const double r = norm(d);
    if (r < 1e-9) return false;
    p = add(c, scale(d, kR / r));
    return true;
  };
  in.hasBox = true;
  in.boxLo = {0, 0, 0};
  in.boxHi = {kN, kN, kN};
  in.boxTolerance = 1e-6;
  in.facetDistance = 0.5;
  return in;
}

/// Mean |distance to the sphere| of the mid-edge nodes of the 1|2 interface edges: straight
/// midpoints and the nodes as curved.
std::pair<double, double> meanSphereDistance(const TetMesh& m, const MidEdgePositions& curved,
                                             const Vec3& c) {
  double straight = 0, bent = 0;
  size_t n = 0;
  for (const InterfaceTriangle& f : extractInterfaces(m)) {
    if (f.labelB == kExteriorLabel) continue;
    for (int k = 0; k < 3; ++k) {
      const int32_t a = f.v[size_t(k)], b = f.v[size_t((k + 1) % 3)];
      if (!onSphere(m, tetEdgeKey(a, b), c)) continue;
      const Vec3 mid = scale(add(m.points[size_t(a)], m.points[size_t(b)]), 0.5);
      const auto it = curved.find(tetEdgeKey(a, b));
      const Vec3 node = it == curved.end() ? mid : it->second;
      straight += std::fabs(norm(sub(mid, c)) - kR);
      bent += std::fabs(norm(sub(node, c)) - kR);
      ++n;
    }
  }
  return {straight / double(n), bent / double(n)};
}

}  // namespace

TEST(QuadraticCurving, InterfaceNodesOnTheSphereElementsValid) {
  const Vec3 c{3.1, 2.9, 3.05};
  const TetMesh m = ballMesh(c);
  for (size_t t = 0; t < m.tets.size(); ++t) ASSERT_GT(m.tetVolume(t), 0) << t;
  RunContext ctx;
  const QuadraticCurvingParameters params;
  const QuadraticCurvingResult r = curveMidEdgeNodes(m, sphereInterfaces(c), params, ctx);
  const QuadraticTetMesh q = quadraticTets(m, &r.nodes);
  EXPECT_EQ(r.midEdgeNodes, q.points.size() - m.points.size());
  EXPECT_GT(r.curvedNodes, 50u);
  EXPECT_EQ(r.nodes.size(), r.curvedNodes + r.partlyCurvedNodes);
  EXPECT_EQ(r.surfaceNodes,
            r.curvedNodes + r.partlyCurvedNodes + r.straightKept + r.onInterfaceNodes);
  // Only interface edges move (the cube's faces are the box: flat, exact).
  const auto tris = extractInterfaces(m);
  std::set<uint64_t> interfaceEdges;
  for (const auto& f : tris)
    if (f.labelB != kExteriorLabel)
      for (int k = 0; k < 3; ++k)
        interfaceEdges.insert(tetEdgeKey(f.v[size_t(k)], f.v[size_t((k + 1) % 3)]));
  for (const auto& [key, p] : r.nodes) EXPECT_TRUE(interfaceEdges.count(key)) << key;
  // Fully curved nodes lie on the sphere; on average far closer than the straight midpoints.
  const auto [straight, bent] = meanSphereDistance(m, r.nodes, c);
  EXPECT_GT(straight, 0.02);
  EXPECT_LT(bent, 0.2 * straight) << "straight " << straight << " curved " << bent;
  // Every element positive at its 11 check points, above the bound, as the result reports.
  const Tet10Jacobian worst = worstTet10Jacobian(q.points, q.tets);
  EXPECT_GE(worst.minOverStraight, params.minJacobianFraction);
  EXPECT_GT(worst.minOverMax, 0);
  EXPECT_DOUBLE_EQ(worst.minOverStraight, r.worst.minOverStraight);
  EXPECT_DOUBLE_EQ(worst.minOverMax, r.worst.minOverMax);
  EXPECT_LT(r.worst.minOverMax, 1.0);  // something did curve
  EXPECT_GT(r.meanMove, 0);
  // Deterministic.
  const QuadraticCurvingResult again = curveMidEdgeNodes(m, sphereInterfaces(c), params, ctx);
  EXPECT_EQ(again.nodes, r.nodes);
}

TEST(QuadraticCurving, NodesOnABoxPlaneStayInIt) {
  // The ball is cut by the box face x = 0: its interface meets the box there.
  const Vec3 c{0.0, 3.1, 2.95};
  const TetMesh m = ballMesh(c);
  RunContext ctx;
  const QuadraticCurvingResult r = curveMidEdgeNodes(m, sphereInterfaces(c), {}, ctx);
  EXPECT_GT(r.boxPlaneNodes, 3u);
  size_t onPlane = 0;
  for (const auto& [key, p] : r.nodes) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(p[size_t(a)], 0.0);
      EXPECT_LE(p[size_t(a)], double(kN));
    }
    const int32_t u = int32_t(key >> 32), v = int32_t(key & 0xffffffffu);
    if (m.points[size_t(u)][0] == 0 && m.points[size_t(v)][0] == 0) {
      EXPECT_EQ(p[0], 0.0);
      // Towards the trace of the sphere on the plane.
      const Vec3 mid = scale(add(m.points[size_t(u)], m.points[size_t(v)]), 0.5);
      EXPECT_LT(std::fabs(norm(sub(p, c)) - kR), std::fabs(norm(sub(mid, c)) - kR));
      if (onSphere(m, key, c)) EXPECT_NEAR(norm(sub(p, c)), kR, 0.01);
      ++onPlane;
    }
  }
  EXPECT_GT(onPlane, 3u);
  const QuadraticTetMesh q = quadraticTets(m, &r.nodes);
  EXPECT_GE(worstTet10Jacobian(q.points, q.tets).minOverStraight, 0.2);
}

TEST(QuadraticCurving, FoldingMovesAreHalvedOrRefused) {
  // A "surface" that pulls every node by 0.45 of an edge along one direction folds thin elements:
  // those moves must be shortened or refused, and no element may end below the bound.
  const Vec3 c{3.1, 2.9, 3.05};
  const TetMesh m = ballMesh(c);
  OptimizeInterfaces in = sphereInterfaces(c);
  in.projectOntoInterface = [](int, int, Vec3& p) {
    p[2] += 0.45;
    return true;
  };
  RunContext ctx;
  QuadraticCurvingParameters params;
  params.minJacobianFraction = 0.6;
  const QuadraticCurvingResult r = curveMidEdgeNodes(m, in, params, ctx);
  EXPECT_GT(r.partlyCurvedNodes + r.straightKept, 0u);
  const QuadraticTetMesh q = quadraticTets(m, &r.nodes);
  EXPECT_GE(worstTet10Jacobian(q.points, q.tets).minOverStraight, 0.6);
  // Without a bound the same moves do fold (so the check above is what saved them).
  bool folds = false;
  MidEdgePositions all;
  for (const auto& f : extractInterfaces(m))
    if (f.labelB != kExteriorLabel)
      for (int k = 0; k < 3; ++k) {
        const int32_t a = f.v[size_t(k)], b = f.v[size_t((k + 1) % 3)];
        Vec3 p = scale(add(m.points[size_t(a)], m.points[size_t(b)]), 0.5);
        p[2] += 0.45;
        all[tetEdgeKey(a, b)] = p;
      }
  const QuadraticTetMesh bad = quadraticTets(m, &all);
  folds = worstTet10Jacobian(bad.points, bad.tets).minOverStraight < 0.6;
  EXPECT_TRUE(folds);
}

TEST(QuadraticCurving, WritersPutTheCurvedNodes) {
  const Vec3 c{3.1, 2.9, 3.05};
  const TetMesh m = ballMesh(c);
  RunContext ctx;
  const QuadraticCurvingResult r = curveMidEdgeNodes(m, sphereInterfaces(c), {}, ctx);
  ASSERT_FALSE(r.nodes.empty());
  const fs::path dir = fs::temp_directory_path() / "femesher_test_curving";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ExportOptions o;
  o.elementOrder = 2;
  o.midEdgeNodes = std::make_shared<MidEdgePositions>(r.nodes);
  ASSERT_TRUE(writeMesh(m, (dir / "m.inp").string(), o));
  // The .inp's node of the first curved edge (in quadraticTets' numbering) is the curved one.
  const QuadraticTetMesh q = quadraticTets(m, o.midEdgeNodes.get());
  const auto& [key, p] = *r.nodes.begin();
  const int32_t id = q.edgeNodes.at(key) + 1;
  std::ifstream in(dir / "m.inp");
  std::string line;
  bool found = false;
  while (std::getline(in, line))
    if (line.rfind(std::to_string(id) + ", ", 0) == 0) {
      double x, y, z;
      char comma;
      std::istringstream ss(line.substr(line.find(',') + 1));
      ss >> x >> comma >> y >> comma >> z;
      EXPECT_NEAR(x, p[0], 1e-9);
      EXPECT_NEAR(y, p[1], 1e-9);
      EXPECT_NEAR(z, p[2], 1e-9);
      found = true;
      break;
    }
  EXPECT_TRUE(found);
  // A table for another mesh is refused, not written.
  auto wrong = std::make_shared<MidEdgePositions>();
  (*wrong)[tetEdgeKey(0, int32_t(m.points.size()) - 1)] = Vec3{1, 1, 1};
  o.midEdgeNodes = wrong;
  const Status s = writeMesh(m, (dir / "w.inp").string(), o);
  EXPECT_EQ(s.code(), ErrorCode::Internal);
  EXPECT_FALSE(fs::exists(dir / "w.inp"));
  fs::remove_all(dir);
}
