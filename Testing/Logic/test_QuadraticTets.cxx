// SPDX-License-Identifier: GPL-3.0-or-later
// 10-node tets (io/QuadraticTets, element_order 2): one shared mid-edge node per unique edge, at
// the edge midpoint, in C3D10/VTK order, every element with a positive Jacobian at its ten nodes;
// formats without 10-node tets refuse element order 2 without writing a file.
#include <femesher/io/MeshIO.h>
#include <femesher/io/QuadraticTets.h>
#include <gtest/gtest.h>

#include "TestShapes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>

namespace fs = std::filesystem;
using namespace femesher;

namespace {

/// n^3 unit cubes split into 6 tets each (Kuhn, conformal), interior vertices jittered by up to
/// 15 % of the edge (all tets stay positive), two materials split at x = n/2 (cube by cube).
TetMesh jitteredTwoMaterialMesh(int n) {
  TetMesh m = femesher::test::cubeGridMesh(n, 1.0, {0, 0, 0}, [n](const Vec3& g) {
    return 2 * int(g[0]) < n ? 1 : 2;  // the centroid lies inside its cube
  });
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.15, 0.15);
  for (auto& p : m.points) {
    const bool inner = std::all_of(p.begin(), p.end(), [n](double c) { return c > 0 && c < n; });
    if (inner)
      for (double& c : p) c += jitter(rng);
  }
  m.materials = {Material{1, "one", {1, 0, 0}}, Material{2, "two", {0, 1, 0}}};
  return m;
}

/// The library's first ten check points are the natural coordinates of the ten nodes (the
/// eleventh is the centroid).
constexpr size_t kNodes = 10;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(QuadraticTets, OneNodePerEdgeAtMidpointsPositiveJacobians) {
  const TetMesh m = jitteredTwoMaterialMesh(4);
  const QuadraticTetMesh q = quadraticTets(m);
  ASSERT_EQ(q.tets.size(), m.tets.size());
  ASSERT_EQ(q.cornerCount, m.points.size());
  std::set<std::pair<int32_t, int32_t>> edges;
  for (const auto& t : m.tets)
    for (const auto& e : kTet10Edges) edges.insert(std::minmax(t[size_t(e[0])], t[size_t(e[1])]));
  // One node per unique edge, shared by every tet around it, none for anything else.
  EXPECT_EQ(q.points.size(), m.points.size() + edges.size());
  EXPECT_EQ(q.edgeNodes.size(), edges.size());
  std::map<std::pair<int32_t, int32_t>, int32_t> nodeOfEdge;
  std::set<int32_t> usedMid;
  for (size_t ti = 0; ti < m.tets.size(); ++ti) {
    const auto& t = m.tets[ti];
    const auto& e10 = q.tets[ti];
    for (int k = 0; k < 4; ++k) EXPECT_EQ(e10[size_t(k)], t[size_t(k)]);
    for (size_t k = 0; k < 6; ++k) {
      const int32_t a = t[size_t(kTet10Edges[k][0])], b = t[size_t(kTet10Edges[k][1])];
      const int32_t mid = e10[4 + k];
      ASSERT_GE(size_t(mid), q.cornerCount);
      ASSERT_LT(size_t(mid), q.points.size());
      const auto key = std::minmax(a, b);
      const auto [it, added] = nodeOfEdge.emplace(key, mid);
      EXPECT_EQ(it->second, mid) << "edge " << a << "-" << b << " has two mid-edge nodes";
      EXPECT_EQ(q.midNode(a, b), mid);
      EXPECT_EQ(q.midNode(b, a), mid);
      usedMid.insert(mid);
      for (size_t c = 0; c < 3; ++c)
        EXPECT_DOUBLE_EQ(q.points[size_t(mid)][c],
                         0.5 * (m.points[size_t(a)][c] + m.points[size_t(b)][c]));
    }
    // Positively oriented and a positive Jacobian at every one of the ten nodes.
    EXPECT_GT(m.tetVolume(ti), 0);
    std::array<Vec3, 10> x;
    for (size_t k = 0; k < 10; ++k) x[k] = q.points[size_t(e10[k])];
    for (size_t k = 0; k < kNodes; ++k) {
      const auto& rst = kTet10CheckPoints[k];
      EXPECT_GT(tet10JacobianDeterminant(x, rst[0], rst[1], rst[2]), 0) << "tet " << ti;
    }
  }
  EXPECT_EQ(usedMid.size(), edges.size());
  // Two vertices that share no tet have no mid-edge node.
  EXPECT_THROW(q.midNode(0, int32_t(m.points.size()) - 1), Error);
}

TEST(QuadraticTets, JacobianCheckSeesSwappedMidNodes) {
  // The check above can fail: Gmsh's order (edges 2-3 and 1-3 swapped) read as C3D10 order
  // puts mid-edge nodes on the wrong edges and folds the element.
  const TetMesh m = jitteredTwoMaterialMesh(1);
  const QuadraticTetMesh q = quadraticTets(m);
  std::array<Vec3, 10> x;
  for (size_t k = 0; k < 10; ++k) x[k] = q.points[size_t(q.tets[0][size_t(kGmshTet10Order[k])])];
  bool negative = false;
  for (size_t k = 0; k < kNodes; ++k) {
    const auto& rst = kTet10CheckPoints[k];
    negative |= tet10JacobianDeterminant(x, rst[0], rst[1], rst[2]) <= 0;
  }
  EXPECT_TRUE(negative);
}

TEST(QuadraticTets, FormatsWithoutTet10RefuseOrderTwo) {
  const TetMesh m = jitteredTwoMaterialMesh(2);
  const fs::path dir = fs::temp_directory_path() / "femesher_test_quadratic";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ExportOptions o;
  o.elementOrder = 2;
  for (const char* name : {"m.mesh", "m.stl"}) {
    const Status s = writeMesh(m, (dir / name).string(), o);
    EXPECT_EQ(s.code(), ErrorCode::InvalidArgument) << name;
    EXPECT_NE(s.message().find("10-node"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(name), std::string::npos) << s.message();
    EXPECT_FALSE(fs::exists(dir / name));
  }
  o.elementOrder = 3;
  EXPECT_EQ(writeMesh(m, (dir / "m.inp").string(), o).code(), ErrorCode::InvalidArgument);
  EXPECT_FALSE(fs::exists(dir / "m.inp"));
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

TEST(QuadraticTets, WritersUseTenNodeElements) {
  const TetMesh m = jitteredTwoMaterialMesh(2);
  const QuadraticTetMesh q = quadraticTets(m);
  const fs::path dir = fs::temp_directory_path() / "femesher_test_quadratic_write";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ExportOptions o;
  o.elementOrder = 2;
  for (const char* name : {"m.inp", "m.msh", "m.feb", "m.vtu", "m.vtk"})
    ASSERT_TRUE(writeMesh(m, (dir / name).string(), o)) << name;
  const std::string inp = slurp(dir / "m.inp");
  EXPECT_NE(inp.find("TYPE=C3D10"), std::string::npos);
  EXPECT_EQ(inp.find("TYPE=C3D4"), std::string::npos);
  // The last node is the last mid-edge node.
  EXPECT_NE(inp.find("\n" + std::to_string(q.points.size()) + ", "), std::string::npos);
  const std::string msh = slurp(dir / "m.msh");
  EXPECT_NE(msh.find(" 11 " + std::to_string(m.tets.size() / 2) + "\n"), std::string::npos);
  const std::string feb = slurp(dir / "m.feb");
  EXPECT_NE(feb.find("type=\"tet10\""), std::string::npos);
  EXPECT_NE(feb.find("<tri6 id=\"1\">"), std::string::npos);
  EXPECT_EQ(feb.find("tet4"), std::string::npos);
  EXPECT_EQ(feb.find("<tri3"), std::string::npos);
  fs::remove_all(dir);
}

TEST(QuadraticTets, ReadersGiveBackCornersAndMidEdgeNodes) {
  // Written with some mid-edge nodes moved off their midpoints, read back from every format that
  // holds 10-node tets: the same corner mesh and the same mid-edge node of every edge.
  const TetMesh m = jitteredTwoMaterialMesh(2);
  auto curved = std::make_shared<MidEdgePositions>();
  const QuadraticTetMesh straight = quadraticTets(m);
  size_t i = 0;
  for (const auto& [key, node] : straight.edgeNodes)
    if (i++ % 3 == 0) {
      Vec3 p = straight.points[size_t(node)];
      p[2] += 0.01;
      (*curved)[key] = p;
    }
  const QuadraticTetMesh q = quadraticTets(m, curved.get());
  const fs::path dir = fs::temp_directory_path() / "femesher_test_quadratic_read";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ExportOptions o;
  o.elementOrder = 2;
  o.midEdgeNodes = curved;
  for (const char* name : {"m.vtu", "m.vtk", "m.msh", "m.inp"}) {
    const std::string path = (dir / name).string();
    ASSERT_TRUE(writeMesh(m, path, o)) << name;
    const Result<MeshFile> r = readMeshFile(path);
    ASSERT_TRUE(r) << name << ": " << r.status().message();
    EXPECT_EQ(r->elementOrder, 2) << name;
    ASSERT_EQ(r->mesh.points.size(), m.points.size()) << name;
    // The same tets with the same labels (.inp and .msh group them by material).
    std::multiset<std::pair<std::array<int32_t, 4>, int32_t>> want, got;
    for (size_t t = 0; t < m.tets.size(); ++t) want.insert({m.tets[t], m.tetLabels[t]});
    for (size_t t = 0; t < r->mesh.tets.size(); ++t)
      got.insert({r->mesh.tets[t], r->mesh.tetLabels[t]});
    EXPECT_EQ(got, want) << name;
    double err = 0;
    for (size_t p = 0; p < m.points.size(); ++p)
      for (size_t c = 0; c < 3; ++c)
        err = std::max(err, std::fabs(r->mesh.points[p][c] - m.points[p][c]));
    ASSERT_EQ(r->midEdgeNodes.size(), q.edgeNodes.size()) << name;
    for (const auto& [key, node] : q.edgeNodes)
      for (size_t c = 0; c < 3; ++c)
        err = std::max(err, std::fabs(r->midEdgeNodes.at(key)[c] - q.points[size_t(node)][c]));
    EXPECT_LT(err, 1e-12) << name;
    // readMesh gives the corner mesh.
    EXPECT_EQ(readMesh(path)->tets.size(), m.tets.size()) << name;
  }
  // A linear file reads as order 1 with no mid-edge nodes.
  ASSERT_TRUE(writeMesh(m, (dir / "l.msh").string(), ExportOptions{}));
  const Result<MeshFile> l = readMeshFile((dir / "l.msh").string());
  ASSERT_TRUE(l);
  EXPECT_EQ(l->elementOrder, 1);
  EXPECT_TRUE(l->midEdgeNodes.empty());
  fs::remove_all(dir);
}
