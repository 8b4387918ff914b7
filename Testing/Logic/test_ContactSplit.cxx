// SPDX-License-Identifier: GPL-3.0-or-later
// ContactSplit: splitting chosen material interfaces into two coincident surfaces with their own
// nodes, and the node sets of the scan box's faces, on generated Kuhn cube-grid meshes.
#include <femesher/Parameters.h>
#include <femesher/Status.h>
#include <femesher/io/ContactSplit.h>
#include <femesher/io/MeshIO.h>

#include "TestShapes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

using namespace femesher;

namespace {

std::map<int32_t, double> volumesByLabel(const TetMesh& m) {
  std::map<int32_t, double> v;
  for (size_t t = 0; t < m.tets.size(); ++t) v[m.tetLabels[t]] += m.tetVolume(t);
  return v;
}

std::set<int32_t> nodesOf(const TetMesh& m, int32_t label) {
  std::set<int32_t> s;
  for (size_t t = 0; t < m.tets.size(); ++t)
    if (m.tetLabels[t] == label) s.insert(m.tets[t].begin(), m.tets[t].end());
  return s;
}

/// Interface triangle counts per (labelA, labelB), boundary included (labelB = -1).
std::map<std::pair<int32_t, int32_t>, size_t> patchCounts(const TetMesh& m) {
  std::map<std::pair<int32_t, int32_t>, size_t> c;
  for (const auto& tri : extractInterfaces(m)) ++c[{tri.labelA, tri.labelB}];
  return c;
}

std::array<int32_t, 3> faceNodes(const TetMesh& m, const ElementFace& f) {
  std::array<int32_t, 3> k{};
  for (int i = 0, n = 0; i < 4; ++i)
    if (i != f.opposite) k[size_t(n++)] = m.tets[size_t(f.tet)][size_t(i)];
  return k;
}

Vec3 faceCentroid(const TetMesh& m, const ElementFace& f) {
  Vec3 c{0, 0, 0};
  for (int32_t v : faceNodes(m, f))
    for (int a = 0; a < 3; ++a) c[a] += m.points[size_t(v)][a] / 3;
  return c;
}

/// Each side's faces are the triangles it had: same positions, pairwise coincident, and every
/// orientation still positive.
void expectCoincidentSides(const TetMesh& m, const ContactSurfacePair& cp) {
  ASSERT_EQ(cp.facesA.size(), cp.facesB.size());
  for (size_t i = 0; i < cp.facesA.size(); ++i) {
    EXPECT_EQ(m.tetLabels[size_t(cp.facesA[i].tet)], cp.labelA);
    EXPECT_EQ(m.tetLabels[size_t(cp.facesB[i].tet)], cp.labelB);
    const Vec3 a = faceCentroid(m, cp.facesA[i]), b = faceCentroid(m, cp.facesB[i]);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(a[k], b[k], 1e-12);
    std::set<int32_t> na, nbs;
    for (int32_t v : faceNodes(m, cp.facesA[i])) na.insert(v);
    for (int32_t v : faceNodes(m, cp.facesB[i])) nbs.insert(v);
    EXPECT_NE(na, nbs);
  }
  for (size_t t = 0; t < m.tets.size(); ++t) EXPECT_GT(m.tetVolume(t), 0);
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Data lines after the line `header` up to the next keyword line.
size_t dataLinesAfter(const std::string& text, const std::string& header) {
  const auto at = text.find(header + "\n");
  if (at == std::string::npos) return 0;
  std::istringstream in(text.substr(at + header.size() + 1));
  size_t n = 0;
  for (std::string line; std::getline(in, line) && !line.empty() && line[0] != '*';) ++n;
  return n;
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST(ContactSplit, ParsesPairs) {
  const auto p = parseContactPairs(" 2:4, 6 : 5 ");
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0], std::make_pair(2, 4));
  EXPECT_EQ(p[1], std::make_pair(6, 5));
  EXPECT_EQ(contactPairsText(p), "2:4,6:5");
  EXPECT_TRUE(parseContactPairs("").empty());
  for (const char* bad : {"2", "2:", "a:b", "2:2", "2:4,4:2", "2:4,", "2;4"})
    EXPECT_THROW(parseContactPairs(bad), Error) << bad;
  // The parameter: --set text, its JSON round trip, a bad value refused with InvalidArgument.
  MeshingParameters params;
  ASSERT_TRUE(setParameter(params, "contact_pairs", "2:4, 6:5").isOk());
  EXPECT_EQ(getParameter(params, "contact_pairs"), "2:4,6:5");
  const auto back = parametersFromJson(parametersToJson(params));
  ASSERT_TRUE(bool(back));
  EXPECT_EQ(back.value().contactPairs, params.contactPairs);
  EXPECT_EQ(setParameter(params, "contact_pairs", "2:x").code(), ErrorCode::InvalidArgument);
  EXPECT_EQ(params.contactPairs.size(), 2u) << "a refused value leaves the pairs alone";
}

TEST(ContactSplit, TwoBoxesTouchingGetTwoSurfacesWithTheirOwnNodes) {
  TetMesh m = test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3& g) { return g[0] < 2 ? 1 : 2; });
  const auto volumes = volumesByLabel(m);
  const size_t points = m.points.size();
  const auto before = patchCounts(m);
  ASSERT_EQ(before.at({1, 2}), 32u);  // 4 x 4 squares of two triangles on the plane x = 2
  const auto pairs = splitContactInterfaces(m, {{2, 1}});
  ASSERT_EQ(pairs.size(), 1u);
  const ContactSurfacePair& cp = pairs[0];
  EXPECT_EQ(cp.labelA, 2);
  EXPECT_EQ(cp.labelB, 1);
  EXPECT_EQ(cp.facesA.size(), 32u);
  // Every one of the 5 x 5 nodes of the plane x = 2 gets one copy.
  EXPECT_EQ(cp.duplicatedNodes, 25u);
  EXPECT_EQ(m.points.size(), points + 25);
  // No node is shared by the two boxes any more.
  const auto n1 = nodesOf(m, 1), n2 = nodesOf(m, 2);
  for (int32_t v : n1) EXPECT_EQ(n2.count(v), 0u) << v;
  // The interface became the boundary of both boxes; the volumes did not change.
  const auto after = patchCounts(m);
  EXPECT_EQ(after.count({1, 2}), 0u);
  EXPECT_EQ(after.at({1, -1}), before.at({1, -1}) + 32);
  EXPECT_EQ(after.at({2, -1}), before.at({2, -1}) + 32);
  const auto v2 = volumesByLabel(m);
  for (const auto& [l, v] : volumes) EXPECT_NEAR(v2.at(l), v, 1e-12);
  expectCoincidentSides(m, cp);
}

TEST(ContactSplit, ThirdMaterialStaysAttachedToBothSidesOnTheTripleLine) {
  // 3 fills y > 2; below it 1 (x < 2) and 2 (x > 2) meet on the plane x = 2. 3 touches both
  // through faces; the triple line 1-2-3 is x = 2, y = 2.
  TetMesh m = test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3& g) {
    return g[1] > 2 ? 3 : (g[0] < 2 ? 1 : 2);
  });
  const auto volumes = volumesByLabel(m);
  const size_t points = m.points.size();
  const auto before = patchCounts(m);
  ASSERT_EQ(before.at({1, 2}), 16u);
  const auto pairs = splitContactInterfaces(m, {{1, 2}});
  ASSERT_EQ(pairs.size(), 1u);
  // The 3 x 5 nodes of the 1|2 interface: the 5 on the triple line stay (3 holds 1 and 2
  // together there), the other 10 get a copy each.
  EXPECT_EQ(pairs[0].duplicatedNodes, 10u);
  EXPECT_EQ(m.points.size(), points + 10);
  const auto after = patchCounts(m);
  EXPECT_EQ(after.count({1, 2}), 0u);
  // 3 is still face-connected to both sides: its interfaces are unchanged.
  EXPECT_EQ(after.at({1, 3}), before.at({1, 3}));
  EXPECT_EQ(after.at({2, 3}), before.at({2, 3}));
  EXPECT_EQ(after.at({3, -1}), before.at({3, -1}));
  // 1 and 2 share only nodes that 3 has too (the triple line), none across the split faces.
  const auto n1 = nodesOf(m, 1), n2 = nodesOf(m, 2), n3 = nodesOf(m, 3);
  size_t shared = 0;
  for (int32_t v : n1)
    if (n2.count(v)) {
      ++shared;
      EXPECT_EQ(n3.count(v), 1u) << v;
      EXPECT_NEAR(m.points[size_t(v)][0], 2.0, 1e-12);
      EXPECT_NEAR(m.points[size_t(v)][1], 2.0, 1e-12);
    }
  EXPECT_EQ(shared, 5u);
  const auto v2 = volumesByLabel(m);
  for (const auto& [l, v] : volumes) EXPECT_NEAR(v2.at(l), v, 1e-12);
  expectCoincidentSides(m, pairs[0]);
}

TEST(ContactSplit, TwoPairsAroundOneMaterial) {
  // 1 | 2 | 3 in slabs along x: both interfaces split, 2 gets its own nodes on both sides.
  TetMesh m = test::cubeGridMesh(3, 1.0, {0, 0, 0}, [](const Vec3& g) {
    return g[0] < 1 ? 1 : (g[0] < 2 ? 2 : 3);
  });
  const size_t points = m.points.size();
  const auto pairs = splitContactInterfaces(m, {{1, 2}, {3, 2}});
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].duplicatedNodes, 16u);
  EXPECT_EQ(pairs[1].duplicatedNodes, 16u);
  EXPECT_EQ(m.points.size(), points + 32);
  const auto n1 = nodesOf(m, 1), n2 = nodesOf(m, 2), n3 = nodesOf(m, 3);
  for (int32_t v : n2) EXPECT_TRUE(!n1.count(v) && !n3.count(v)) << v;
  expectCoincidentSides(m, pairs[0]);
  expectCoincidentSides(m, pairs[1]);
}

TEST(ContactSplit, RefusesAbsentLabelsAndPairsWithoutInterface) {
  TetMesh m = test::cubeGridMesh(3, 1.0, {0, 0, 0}, [](const Vec3& g) {
    return g[0] < 1 ? 1 : (g[0] < 2 ? 2 : 3);
  });
  const TetMesh original = m;
  try {
    splitContactInterfaces(m, {{1, 7}});
    ADD_FAILURE() << "label 7 is not in the mesh";
  } catch (const Error& e) {
    EXPECT_EQ(e.status().code(), ErrorCode::InvalidArgument);
    EXPECT_NE(e.status().message().find("label 7 is not in the mesh"), std::string::npos);
  }
  try {
    splitContactInterfaces(m, {{1, 3}});
    ADD_FAILURE() << "1 and 3 do not touch";
  } catch (const Error& e) {
    EXPECT_EQ(e.status().code(), ErrorCode::InvalidArgument);
    EXPECT_NE(e.status().message().find("share no interface"), std::string::npos);
  }
  EXPECT_EQ(m.points.size(), original.points.size());
  EXPECT_EQ(m.tets, original.tets);
}

TEST(ContactSplit, BoxFaceNodeSetsInTheImageAxesOfAnObliqueImage) {
  // The image: 4 x 4 x 6 voxels of 0.5 x 1 x 2 mm, rotated 30 degrees about L-P's normal and
  // shifted. The mesh fills the index box [-0.5, 3.5] x [-0.5, 3.5] x [-0.5, 3.5]: it reaches the
  // image's X and Y faces and Z's minimum, not Z's maximum (dims 6: plane 5.5).
  LabelVolume g;
  g.dims = {4, 4, 6};
  g.spacing = {0.5, 1, 2};
  g.origin = {10, -20, 30};
  const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
  g.direction = {c, -s, 0, s, c, 0, 0, 0, 1};
  TetMesh m = test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3&) { return 1; });
  for (Vec3& p : m.points) p = g.indexToPhysical({p[0] - 0.5, p[1] - 0.5, p[2] - 0.5});
  const auto sets = boxFaceNodeSets(m, g);
  std::vector<std::string> names;
  for (const auto& ns : sets) names.push_back(ns.name);
  EXPECT_EQ(names, (std::vector<std::string>{"BOX_XMIN", "BOX_XMAX", "BOX_YMIN", "BOX_YMAX",
                                             "BOX_ZMIN"}));
  for (const auto& ns : sets) {
    EXPECT_EQ(ns.nodes.size(), 25u) << ns.name;
    const int axis = ns.name[4] - 'X';
    const double plane = ns.name.substr(5) == "MIN" ? -0.5 : 3.5;
    for (int32_t v : ns.nodes) EXPECT_NEAR(g.physicalToIndex(m.points[size_t(v)])[axis], plane, 1e-9);
  }
}

TEST(ContactSplit, DecksCarryTheContactPairAndTheNodeSets) {
  // Two boxes split on x = 2, written as .inp and .feb with a node set, in both element orders.
  TetMesh m = test::cubeGridMesh(4, 1.0, {0, 0, 0}, [](const Vec3& g) { return g[0] < 2 ? 1 : 2; });
  ExportOptions o;
  o.contacts = splitContactInterfaces(m, {{2, 1}});
  NamedNodeSet xmin{"BOX_XMIN", {}};
  for (size_t i = 0; i < m.points.size(); ++i)
    if (m.points[i][0] == 0) xmin.nodes.push_back(int32_t(i));
  ASSERT_EQ(xmin.nodes.size(), 25u);
  o.nodeSets = {xmin};
  const auto dir = std::filesystem::path(FEMESHER_TEST_TMP_DIR) / "ContactSplit";
  std::filesystem::create_directories(dir);
  for (int order : {1, 2}) {
    o.elementOrder = order;
    const std::string inp = (dir / ("boxes" + std::to_string(order) + ".inp")).string();
    const std::string feb = (dir / ("boxes" + std::to_string(order) + ".feb")).string();
    ASSERT_TRUE(writeMesh(m, inp, o).isOk()) << order;
    ASSERT_TRUE(writeMesh(m, feb, o).isOk()) << order;
    const std::string a = slurp(inp), f = slurp(feb);
    EXPECT_EQ(dataLinesAfter(a, "*SURFACE, NAME=CONTACT_2_1_S, TYPE=ELEMENT"), 32u);
    EXPECT_EQ(dataLinesAfter(a, "*SURFACE, NAME=CONTACT_2_1_M, TYPE=ELEMENT"), 32u);
    EXPECT_NE(a.find("*SURFACE INTERACTION, NAME=SI_2_1\n*SURFACE BEHAVIOR, "
                     "PRESSURE-OVERCLOSURE=LINEAR\n"),
              std::string::npos);
    EXPECT_NE(a.find("*CONTACT PAIR, INTERACTION=SI_2_1, TYPE=SURFACE TO SURFACE\n"
                     "CONTACT_2_1_S, CONTACT_2_1_M\n"),
              std::string::npos);
    // 25 corners; with order 2 also the mid-edge nodes of the face's 56 edges (40 grid edges, 16
    // diagonals).
    size_t ids = 0;
    {
      const auto at = a.find("*NSET, NSET=BOX_XMIN\n");
      ASSERT_NE(at, std::string::npos);
      std::istringstream in(a.substr(at + 21));
      for (std::string line; std::getline(in, line) && !line.empty() && line[0] != '*';) ids += count(line, ",") + 1;
    }
    EXPECT_EQ(ids, order == 1 ? 25u : 25u + 56u) << order;
    // FEBio: the two Surfaces (tri3 or tri6), the pair, the contact, the node set.
    const char* tri = order == 1 ? "<tri3 " : "<tri6 ";
    for (const char* side : {"label_2", "label_1"}) {
      const std::string open = "<Surface name=\"contact__label_2__label_1__" + std::string(side) + "\">";
      const auto at = f.find(open);
      ASSERT_NE(at, std::string::npos) << side;
      EXPECT_EQ(count(f.substr(at, f.find("</Surface>", at) - at), tri), 32u) << side << order;
    }
    EXPECT_NE(f.find("<SurfacePair name=\"contact__label_2__label_1\">\n\t\t\t<primary>contact__label_2__"
                     "label_1__label_2</primary>\n\t\t\t<secondary>contact__label_2__label_1__label_1"
                     "</secondary>"),
              std::string::npos);
    EXPECT_NE(f.find("<contact type=\"sliding-elastic\" name=\"contact__label_2__label_1\" "
                     "surface_pair=\"contact__label_2__label_1\">"),
              std::string::npos);
    EXPECT_NE(f.find("<NodeSet name=\"BOX_XMIN\">"), std::string::npos);
  }
  // Tables that do not belong to the mesh are refused.
  ExportOptions bad = o;
  bad.elementOrder = 1;
  bad.contacts[0].facesA[0].tet = int32_t(m.tets.size());
  EXPECT_FALSE(writeMesh(m, (dir / "bad.inp").string(), bad).isOk());
  bad = o;
  bad.elementOrder = 1;
  bad.nodeSets[0].nodes.push_back(int32_t(m.points.size()));
  EXPECT_FALSE(writeMesh(m, (dir / "bad.feb").string(), bad).isOk());
}
