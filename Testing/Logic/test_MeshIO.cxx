// SPDX-License-Identifier: GPL-3.0-or-later
// Mesh export and read-back: every format written from a small labelled mesh built in code
// (a 3x3x3 block of cubes, 6 tets each, two or three materials), read back where FEMesher can
// (.vtu, .vtk, .msh, .mesh) and checked exactly; INP/FEBio/STL structure checked by parsing.
#include <femesher/Version.h>
#include <femesher/io/AtomicFile.h>
#include <femesher/io/MeshIO.h>

#include "TestShapes.h"

#include <gtest/gtest.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkFieldData.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkUnstructuredGrid.h>
#include <vtkUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridReader.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <sys/resource.h>

namespace fs = std::filesystem;
using namespace femesher;
using femesher::test::cubeGridMesh;

namespace {

/// Two materials split by the plane between the 2nd and 3rd layer of cubes, non-round coordinates so that the
/// full-precision round trip is meaningful.
TetMesh twoMaterialCube() {
  const double h = 1.0 / 3.0 + 1, x0 = -12.345678901234567;
  TetMesh m = cubeGridMesh(3, h, {x0, 0.1, 1e-7},
                           [=](const Vec3& g) { return g[0] < x0 + 2 * h ? 2 : 5; });
  m.materials[0].name = "trabecular bone";
  m.materials[1].name = "Implant (Ti-6Al-4V) \"grade 5\" <special> & long name that goes on and on "
                        "and on well beyond eighty characters of text";
  m.materials[1].color = {0.1, 0.2, 0.3};
  return m;
}

std::string tmpDir() {
  const fs::path d = fs::path(FEMESHER_TEST_TMP_DIR) / "MeshIO";
  fs::create_directories(d);
  return d.string();
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

/// (sorted vertex ids, label) per tet, sorted: compares meshes whose tet order may differ.
std::vector<std::pair<std::array<int32_t, 4>, int32_t>> tetKeys(const TetMesh& m) {
  std::vector<std::pair<std::array<int32_t, 4>, int32_t>> k;
  for (size_t t = 0; t < m.tets.size(); ++t) k.push_back({m.tets[t], m.tetLabels[t]});
  std::sort(k.begin(), k.end());
  return k;
}

void expectSameMesh(const TetMesh& a, const TetMesh& b, bool sameOrder, const std::string& what) {
  ASSERT_EQ(a.points.size(), b.points.size()) << what;
  for (size_t i = 0; i < a.points.size(); ++i)
    for (int k = 0; k < 3; ++k)
      ASSERT_EQ(a.points[i][k], b.points[i][k]) << what << ": point " << i << " not bit-identical";
  ASSERT_EQ(a.tets.size(), b.tets.size()) << what;
  if (sameOrder) {
    EXPECT_EQ(a.tets, b.tets) << what;
    EXPECT_EQ(a.tetLabels, b.tetLabels) << what;
  } else {
    EXPECT_EQ(tetKeys(a), tetKeys(b)) << what << ": tets or labels differ";
  }
  ASSERT_EQ(a.materials.size(), b.materials.size()) << what;
  for (size_t i = 0; i < a.materials.size(); ++i) EXPECT_EQ(a.materials[i].id, b.materials[i].id) << what;
}

bool anyFileStartingWith(const std::string& dir, const std::string& stem) {
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.find(stem) != std::string::npos) return true;
  }
  return false;
}

}  // namespace

TEST(MeshIO, TestMeshIsConformalWithInterfacesAndBoundary) {
  const TetMesh m = twoMaterialCube();
  ASSERT_EQ(m.tets.size(), 27u * 6u);
  for (size_t t = 0; t < m.tets.size(); ++t) ASSERT_GT(m.tetVolume(t), 0);
  const auto tris = extractInterfaces(m);
  size_t inner = 0, outer = 0;
  for (const auto& t : tris) (t.labelB == kExteriorLabel ? outer : inner)++;
  EXPECT_EQ(outer, 6u * 9u * 2u);  // 6 faces x 9 squares x 2 triangles
  EXPECT_EQ(inner, 9u * 2u);       // the plane x = 2 cube widths
}

TEST(MeshIO, SupportedExtensionsAndOptions) {
  const auto exts = supportedMeshExtensions();
  for (const char* e : {".vtu", ".inp", ".msh", ".mesh", ".feb", ".stl"})
    EXPECT_NE(std::find(exts.begin(), exts.end(), e), exts.end()) << e;
  MeshingParameters p;
  p.defaultMaterial.youngsModulus = 1234;
  p.materialProperties[5].youngsModulus = 110000;
  const ExportOptions o = exportOptionsFrom(p);
  EXPECT_EQ(o.defaultMaterial.youngsModulus, 1234);
  EXPECT_EQ(o.materialProperties.at(5).youngsModulus, 110000);
}

TEST(MeshIO, WritesEveryFormatAndReadsBackExactly) {
  const TetMesh m = twoMaterialCube();
  const std::string dir = tmpDir();
  ExportOptions o;
  o.provenance = "unit test\nsecond line";
  for (const auto& ext : supportedMeshExtensions()) {
    const std::string path = dir + "/two" + ext;
    fs::remove(path);
    const Status s = writeMesh(m, path, o);
    ASSERT_TRUE(s.isOk()) << ext << ": " << s.message();
    ASSERT_TRUE(fs::exists(path)) << ext;
    EXPECT_GT(fs::file_size(path), 1000u) << ext;
  }
  // Formats that keep the tet order.
  for (const char* ext : {".vtu", ".vtk", ".mesh"}) {
    auto back = readMesh(dir + "/two" + ext);
    ASSERT_TRUE(back.isOk()) << ext << ": " << back.status().message();
    expectSameMesh(m, back.value(), true, ext);
  }
  // MSH groups tets by material.
  auto msh = readMesh(dir + "/two.msh");
  ASSERT_TRUE(msh.isOk()) << msh.status().message();
  expectSameMesh(m, msh.value(), false, ".msh");
  // Names survive in VTU (field data) and MSH (physical names); colours in VTU.
  for (const char* ext : {".vtu", ".msh"}) {
    auto back = readMesh(dir + "/two" + ext);
    ASSERT_EQ(back->materials.size(), 2u);
    EXPECT_EQ(back->materials[0].name, "trabecular bone") << ext;
  }
  auto vtu = readMesh(dir + "/two.vtu");
  EXPECT_EQ(vtu->materials[1].name, m.materials[1].name);
  EXPECT_EQ(vtu->materials[1].color, m.materials[1].color);
  // VTU field data is in the file (appended binary, but the array names are in the XML header),
  // all of it numeric (meshio cannot parse String arrays) and without a SPACE tag.
  const std::string vtuText = slurp(dir + "/two.vtu");
  for (const char* name : {"\"MaterialIds\"", "\"MaterialNames\"", "\"FEMesherVersion\"",
                           "\"Provenance\"", "\"labels\""})
    EXPECT_NE(vtuText.find(name), std::string::npos) << name;
  EXPECT_EQ(vtuText.find("\"SPACE\""), std::string::npos);
  EXPECT_EQ(vtuText.find("type=\"String\""), std::string::npos);
  EXPECT_NE(slurp(dir + "/two.vtk").find("SPACE=LPS"), std::string::npos);
}

// What 3D Slicer's model storage node gets from our files, read with VTK's own readers (the ones
// vtkMRMLModelStorageNode uses): the tets, their int cell array `labels`, and for the coordinate
// system either nothing in the .vtu (Slicer then takes the file as LPS: it reads a SPACE tag only
// from a vtkStringArray, which meshio cannot parse) or the legacy header "SPACE=LPS" in the .vtk.
TEST(MeshIO, VtkReadersLoadTheFilesAsSlicerDoes) {
  const TetMesh m = twoMaterialCube();
  const std::string dir = tmpDir();
  ASSERT_TRUE(writeMesh(m, dir + "/slicer.vtu").isOk());
  ASSERT_TRUE(writeMesh(m, dir + "/slicer.vtk").isOk());
  auto checkGrid = [&](vtkUnstructuredGrid* g, const char* what) {
    ASSERT_NE(g, nullptr) << what;
    ASSERT_EQ(g->GetNumberOfPoints(), vtkIdType(m.points.size())) << what;
    ASSERT_EQ(g->GetNumberOfCells(), vtkIdType(m.tets.size())) << what;
    for (vtkIdType i = 0; i < g->GetNumberOfPoints(); ++i) {
      double p[3];
      g->GetPoint(i, p);
      for (int k = 0; k < 3; ++k) ASSERT_EQ(p[k], m.points[size_t(i)][k]) << what << " point " << i;
    }
    auto* labels = vtkIntArray::SafeDownCast(g->GetCellData()->GetArray("labels"));
    ASSERT_NE(labels, nullptr) << what << ": int cell array 'labels'";
    for (vtkIdType c = 0; c < g->GetNumberOfCells(); ++c) {
      ASSERT_EQ(g->GetCellType(c), VTK_TETRA) << what;
      ASSERT_EQ(labels->GetValue(c), m.tetLabels[size_t(c)]) << what << " tet " << c;
    }
    vtkFieldData* fd = g->GetFieldData();
    EXPECT_EQ(fd->GetAbstractArray("SPACE"), nullptr) << what;
    for (int a = 0; a < fd->GetNumberOfArrays(); ++a)
      EXPECT_NE(vtkDataArray::SafeDownCast(fd->GetAbstractArray(a)), nullptr)
          << what << ": field array " << fd->GetAbstractArray(a)->GetName() << " is not numeric";
  };
  vtkNew<vtkXMLUnstructuredGridReader> xml;
  xml->SetFileName((dir + "/slicer.vtu").c_str());
  xml->Update();
  EXPECT_EQ(xml->GetErrorCode(), 0);
  checkGrid(xml->GetOutput(), ".vtu");
  EXPECT_NE(xml->GetOutput()->GetFieldData()->GetAbstractArray("MaterialNames"), nullptr);
  vtkNew<vtkUnstructuredGridReader> legacy;
  legacy->SetFileName((dir + "/slicer.vtk").c_str());
  legacy->Update();
  checkGrid(legacy->GetOutput(), ".vtk");
  ASSERT_NE(legacy->GetHeader(), nullptr);
  EXPECT_NE(std::string(legacy->GetHeader()).find("SPACE=LPS"), std::string::npos);
}

TEST(MeshIO, NonPositiveLabelsRoundTrip) {
  // Label 0 (a map without background) and a negative label must survive every readable format.
  TetMesh m = cubeGridMesh(3, 2.0, {0, 0, 0}, [](const Vec3& g) {
    return g[2] < 2 ? 0 : g[2] < 4 ? -3 : 200001;
  });
  const std::string dir = tmpDir();
  for (const char* ext : {".vtu", ".msh", ".mesh", ".inp", ".stl", ".feb"}) {
    const std::string path = dir + "/signed" + ext;
    ASSERT_TRUE(writeMesh(m, path).isOk()) << ext;
    if (std::string(ext) == ".inp" || std::string(ext) == ".stl" || std::string(ext) == ".feb") continue;
    auto back = readMesh(path);
    ASSERT_TRUE(back.isOk()) << ext << ": " << back.status().message();
    expectSameMesh(m, back.value(), std::string(ext) != ".msh", ext);
  }
  // Abaqus names carry no '-': the negative label is written N3.
  const std::string inp = slurp(dir + "/signed.inp");
  EXPECT_NE(inp.find("ELSET=MN3_LABEL_3"), std::string::npos);
  EXPECT_NE(inp.find("*SURFACE, NAME=IF_N3_0, TYPE=ELEMENT"), std::string::npos);
  for (const auto& l : lines(inp))
    if (l.rfind("*", 0) == 0 && l.rfind("**", 0) != 0) EXPECT_EQ(l.find('-'), std::string::npos) << l;
}

TEST(MeshIO, AbaqusInputIsCompleteAndConsistent) {
  const TetMesh m = twoMaterialCube();
  const std::string path = tmpDir() + "/abaqus.inp";
  ExportOptions o;
  o.defaultMaterial = {15000, 0.3, 1.8e-9};
  o.materialProperties[5] = {110000, 0.34, 4.43e-9};
  ASSERT_TRUE(writeMesh(m, path, o).isOk());
  const auto text = lines(slurp(path));

  std::map<int, Vec3> nodes;
  std::map<int, std::array<int, 4>> elements;
  std::map<std::string, std::vector<int>> elsets;
  std::map<std::string, std::vector<std::pair<int, int>>> surfaces;
  std::set<int> boundary;
  std::map<std::string, std::set<int>> nsets;  // every *NSET but BOUNDARY, by name
  std::map<std::string, std::string> sectionMaterial;
  std::map<std::string, std::pair<double, double>> elastic;
  std::map<std::string, double> density;
  std::string kw, current, material;
  for (const auto& l : text) {
    ASSERT_LE(l.size(), 132u) << "CalculiX reads at most 132 characters per line";
    if (l.rfind("**", 0) == 0) continue;
    if (l.rfind("*", 0) == 0) {
      EXPECT_EQ(l.find("*STEP"), std::string::npos) << "the model must not contain a step";
      kw = l;
      if (kw == "*HEADING") kw = "HEADING";
      auto grab = [&](const std::string& key) {
        const auto p = l.find(key + "=");
        if (p == std::string::npos) return std::string();
        const auto e = l.find(',', p);
        return l.substr(p + key.size() + 1, e == std::string::npos ? std::string::npos : e - p - key.size() - 1);
      };
      if (l.rfind("*ELEMENT", 0) == 0) {
        EXPECT_NE(l.find("TYPE=C3D4"), std::string::npos);
        current = grab("ELSET");
      } else if (l.rfind("*SURFACE", 0) == 0) {
        current = grab("NAME");
      } else if (l.rfind("*NSET", 0) == 0) {
        current = grab("NSET");
      } else if (l.rfind("*MATERIAL", 0) == 0) {
        material = grab("NAME");
      } else if (l.rfind("*SOLID SECTION", 0) == 0) {
        sectionMaterial[grab("ELSET")] = grab("MATERIAL");
      }
      for (const std::string& name : {grab("ELSET"), grab("NAME"), grab("MATERIAL")}) {
        EXPECT_LE(name.size(), 80u) << l;
        for (char c : name) EXPECT_TRUE(std::isupper(c) || std::isdigit(c) || c == '_') << l;
      }
      continue;
    }
    if (kw == "HEADING") continue;
    std::vector<std::string> f;
    std::stringstream ss(l);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    EXPECT_LE(f.size(), 16u) << "more than 16 entries on a data line: " << l;
    for (const auto& x : f) EXPECT_LE(x.size(), 21u) << "CalculiX reads at most 20 characters per field: " << l;
    if (kw.rfind("*NODE", 0) == 0) {
      ASSERT_EQ(f.size(), 4u);
      nodes[std::stoi(f[0])] = {std::stod(f[1]), std::stod(f[2]), std::stod(f[3])};
    } else if (kw.rfind("*ELEMENT", 0) == 0) {
      ASSERT_EQ(f.size(), 5u);
      elements[std::stoi(f[0])] = {std::stoi(f[1]), std::stoi(f[2]), std::stoi(f[3]), std::stoi(f[4])};
      elsets[current].push_back(std::stoi(f[0]));
    } else if (kw.rfind("*NSET, NSET=BOUNDARY", 0) == 0) {
      for (const auto& x : f) boundary.insert(std::stoi(x));
    } else if (kw.rfind("*NSET", 0) == 0) {
      for (const auto& x : f) nsets[current].insert(std::stoi(x));
    } else if (kw.rfind("*SURFACE", 0) == 0) {
      ASSERT_EQ(f.size(), 2u);
      surfaces[current].push_back({std::stoi(f[0]), std::stoi(f[1].substr(f[1].find('S') + 1))});
    } else if (kw == "*ELASTIC") {
      elastic[material] = {std::stod(f[0]), std::stod(f[1])};
    } else if (kw == "*DENSITY") {
      density[material] = std::stod(f[0]);
    }
  }
  // Nodes: every point, 1-based, coordinates to full precision.
  ASSERT_EQ(nodes.size(), m.points.size());
  for (size_t i = 0; i < m.points.size(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(nodes.at(int(i) + 1)[k], m.points[i][k]);
  // Elements: every tet once, ids = mesh index + 1, in the elset of its material.
  ASSERT_EQ(elements.size(), m.tets.size());
  for (size_t t = 0; t < m.tets.size(); ++t)
    for (int k = 0; k < 4; ++k) EXPECT_EQ(elements.at(int(t) + 1)[k], m.tets[t][k] + 1);
  for (const auto& [e, el] : elements) {
    const Vec3 &a = nodes.at(el[0]), &b = nodes.at(el[1]), &c = nodes.at(el[2]), &d = nodes.at(el[3]);
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]},
                 w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    EXPECT_GT(u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
                  u[2] * (v[0] * w[1] - v[1] * w[0]), 0) << "element " << e << " inverted for CalculiX";
  }
  ASSERT_EQ(elsets.size(), 2u);
  ASSERT_TRUE(elsets.count("M2_TRABECULAR_BONE"));
  for (int e : elsets.at("M2_TRABECULAR_BONE")) EXPECT_EQ(m.tetLabels[size_t(e) - 1], 2);
  std::string implant;
  for (const auto& kv : elsets)
    if (kv.first != "M2_TRABECULAR_BONE") implant = kv.first;
  EXPECT_EQ(implant.rfind("M5_IMPLANT_TI_6AL_4V_GRADE_5_SPECIAL", 0), 0u) << implant;
  for (int e : elsets.at(implant)) EXPECT_EQ(m.tetLabels[size_t(e) - 1], 5);
  // Sections and materials with the requested properties.
  ASSERT_EQ(sectionMaterial.size(), 2u);
  const std::string mat2 = sectionMaterial.at("M2_TRABECULAR_BONE"), mat5 = sectionMaterial.at(implant);
  EXPECT_EQ(elastic.at(mat2), std::make_pair(15000.0, 0.3));
  EXPECT_EQ(elastic.at(mat5), std::make_pair(110000.0, 0.34));
  EXPECT_DOUBLE_EQ(density.at(mat2), 1.8e-9);
  EXPECT_DOUBLE_EQ(density.at(mat5), 4.43e-9);
  // Boundary nodes: exactly the nodes on the cube's outer faces.
  const auto tris = extractInterfaces(m);
  std::set<int> expectBoundary;
  std::map<std::string, std::multiset<std::array<int, 3>>> expectFaces;
  for (const auto& t : tris) {
    std::array<int, 3> k{t.v[0] + 1, t.v[1] + 1, t.v[2] + 1};
    std::sort(k.begin(), k.end());
    if (t.labelB == kExteriorLabel) {
      expectBoundary.insert(k.begin(), k.end());
      expectFaces["OUTER_" + std::to_string(t.labelA)].insert(k);
    } else {
      expectFaces["IF_" + std::to_string(t.labelA) + "_" + std::to_string(t.labelB)].insert(k);
    }
  }
  EXPECT_EQ(boundary, expectBoundary);
  EXPECT_EQ(boundary.size(), size_t(4 * 4 * 4 - 2 * 2 * 2));
  // Node sets: N_<elset> holds exactly the nodes of the material's elements, N_<surface> exactly
  // the nodes of that surface's triangles; nothing else.
  std::map<std::string, std::set<int>> expectSets;
  for (const auto& [name, ids] : elsets)
    for (int e : ids) expectSets["N_" + name].insert(elements.at(e).begin(), elements.at(e).end());
  for (const auto& [name, faces] : expectFaces)
    for (const auto& k : faces) expectSets["N_" + name].insert(k.begin(), k.end());
  EXPECT_EQ(nsets, expectSets);
  // Surfaces: the face Sk of element e (Abaqus C3D4 numbering) is the interface triangle.
  static const int F[4][3] = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
  ASSERT_EQ(surfaces.size(), expectFaces.size());
  for (const auto& [name, faces] : surfaces) {
    ASSERT_TRUE(expectFaces.count(name)) << name;
    std::multiset<std::array<int, 3>> got;
    for (const auto& [e, s] : faces) {
      ASSERT_GE(s, 1);
      ASSERT_LE(s, 4);
      const auto& el = elements.at(e);
      std::array<int, 3> k{el[F[s - 1][0]], el[F[s - 1][1]], el[F[s - 1][2]]};
      std::sort(k.begin(), k.end());
      got.insert(k);
      // Faces are taken from the elements of the first label of the name (IF_<a>_<b>, OUTER_<a>).
      const int a = std::stoi(name.substr(name.find('_') + 1));
      EXPECT_EQ(m.tetLabels[size_t(e) - 1], a) << name;
    }
    EXPECT_EQ(got, expectFaces.at(name)) << name;
  }
  EXPECT_EQ(surfaces.at("IF_2_5").size(), 18u);
}

TEST(MeshIO, GmshFileHasNamedPhysicalGroupsAndEntities) {
  const TetMesh m = twoMaterialCube();
  const std::string path = tmpDir() + "/groups.msh";
  ASSERT_TRUE(writeMesh(m, path).isOk());
  const std::string text = slurp(path);
  EXPECT_EQ(text.rfind("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n", 0), 0u);
  EXPECT_NE(text.find("3 2 \"trabecular bone\""), std::string::npos);
  EXPECT_NE(text.find("\"interface_2_5\""), std::string::npos);
  EXPECT_NE(text.find("\"boundary_2\""), std::string::npos);
  EXPECT_NE(text.find("\"boundary_5\""), std::string::npos);
  // Quotes inside a material name cannot break the quoted physical name.
  const auto line5 = text.find("\n3 5 \"");
  ASSERT_NE(line5, std::string::npos);
  const auto eol = text.find('\n', line5 + 1);
  const std::string l = text.substr(line5 + 1, eol - line5 - 1);
  EXPECT_EQ(std::count(l.begin(), l.end(), '"'), 2) << l;
  // Element counts: tets + interface and boundary triangles.
  const auto tris = extractInterfaces(m);
  const auto p = text.find("$Elements\n");
  ASSERT_NE(p, std::string::npos);
  std::istringstream s(text.substr(p + 10));
  size_t blocks = 0, total = 0;
  s >> blocks >> total;
  EXPECT_EQ(blocks, 2u + 3u);  // 2 volumes, 3 patches (boundary_2, boundary_5, interface_2_5)
  EXPECT_EQ(total, m.tets.size() + tris.size());
}

TEST(MeshIO, MeditFebioAndStlStructure) {
  const TetMesh m = twoMaterialCube();
  const std::string dir = tmpDir();
  ASSERT_TRUE(writeMesh(m, dir + "/s.mesh").isOk());
  ASSERT_TRUE(writeMesh(m, dir + "/s.feb").isOk());
  ASSERT_TRUE(writeMesh(m, dir + "/s.stl").isOk());
  const auto tris = extractInterfaces(m);
  // Medit: interface triangles present.
  const std::string med = slurp(dir + "/s.mesh");
  EXPECT_NE(med.find("Triangles\n" + std::to_string(tris.size()) + "\n"), std::string::npos);
  EXPECT_NE(med.find("Tetrahedra\n" + std::to_string(m.tets.size()) + "\n"), std::string::npos);
  // FEBio 4.0: element ids 1..N over both domains, two domains, two named materials, surfaces.
  const std::string feb = slurp(dir + "/s.feb");
  EXPECT_NE(feb.find("<febio_spec version=\"4.0\">"), std::string::npos);
  size_t elems = 0, domains = 0, mats = 0, surfaces = 0, faces = 0;
  for (const auto& l : lines(feb)) {
    if (l.find("<elem id=\"") != std::string::npos) {
      ++elems;
      EXPECT_NE(l.find("<elem id=\"" + std::to_string(elems) + "\">"), std::string::npos) << l;
    }
    domains += l.find("<Elements type=\"tet4\" name=\"") != std::string::npos;
    mats += l.find("type=\"neo-Hookean\"") != std::string::npos;
    surfaces += l.find("<Surface name=\"") != std::string::npos;
    faces += l.find("<tri3 id=\"") != std::string::npos;
  }
  EXPECT_EQ(elems, m.tets.size());
  EXPECT_EQ(domains, 2u);
  EXPECT_EQ(mats, 2u);
  EXPECT_EQ(surfaces, 3u);  // boundary of each, their interface
  EXPECT_EQ(faces, tris.size());
  for (const char* s : {"<material id=\"1\" name=\"trabecular_bone\"",
                        "<material id=\"2\" name=\"Implant_Ti_6Al_4V_grade_5_special_long_name_that\"",
                        "<Surface name=\"trabecular_bone__Implant_Ti_6Al_4V_grade_5_special_long_name_that\">",
                        "<Surface name=\"trabecular_bone__boundary\">",
                        "<NodeSet name=\"nodes__trabecular_bone\">",
                        "<SolidDomain name=\"trabecular_bone\" mat=\"trabecular_bone\"/>",
                        "<Module type=\"solid\"/>", "<Control>", "<MeshDomains>", "</febio_spec>"})
    EXPECT_NE(feb.find(s), std::string::npos) << s;
  // STL: one solid per patch, facet normals unit length and consistent with the vertex order.
  size_t facets = 0, solids = 0;
  const auto sl = lines(slurp(dir + "/s.stl"));
  for (size_t i = 0; i < sl.size(); ++i) {
    if (sl[i].rfind("solid ", 0) == 0) ++solids;
    if (sl[i].find("facet normal") == std::string::npos) continue;
    ++facets;
    double n[3], v[3][3];
    ASSERT_EQ(std::sscanf(sl[i].c_str(), " facet normal %lf %lf %lf", &n[0], &n[1], &n[2]), 3);
    for (int k = 0; k < 3; ++k)
      ASSERT_EQ(std::sscanf(sl[i + 2 + size_t(k)].c_str(), " vertex %lf %lf %lf", &v[k][0], &v[k][1], &v[k][2]), 3);
    const double u[3] = {v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]};
    const double w[3] = {v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]};
    const double c[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    const double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6);
    EXPECT_NEAR((c[0] * n[0] + c[1] * n[1] + c[2] * n[2]) / len, 1.0, 1e-6);
  }
  EXPECT_EQ(facets, tris.size());
  EXPECT_EQ(solids, 3u);
}

// Names FEBio and Gmsh can use: identifiers for FEBio (letters, digits, underscore, a letter
// first, no "__", not a reserved word), unique in both formats even when materials share a name.
TEST(MeshIO, MaterialNamesAreSafeAndUniquePerFormat) {
  TetMesh m = cubeGridMesh(3, 1.0, {0, 0, 0}, [](const Vec3& g) { return 1 + int(g[0]) ; });
  ASSERT_EQ(m.materials.size(), 3u);
  m.materials[0].name = "bone";
  m.materials[1].name = "bone";
  m.materials[2].name = "3rd -- layer \xc3\xbc__x";
  const std::string dir = tmpDir();
  ASSERT_TRUE(writeMesh(m, dir + "/n.feb").isOk());
  ASSERT_TRUE(writeMesh(m, dir + "/n.msh").isOk());
  const std::string feb = slurp(dir + "/n.feb");
  for (const char* s : {"<material id=\"1\" name=\"bone\"", "<material id=\"2\" name=\"bone_2\"",
                        "<material id=\"3\" name=\"m_3rd_layer_x\"", "<Surface name=\"bone__bone_2\">"})
    EXPECT_NE(feb.find(s), std::string::npos) << s;
  for (const auto& l : lines(feb)) {  // ASCII only, and "--" only where the comment ends
    EXPECT_TRUE(std::all_of(l.begin(), l.end(), [](char c) { return static_cast<unsigned char>(c) < 0x80; })) << l;
    if (l != "-->" && l.rfind("<!--", 0) != 0) EXPECT_EQ(l.find("--"), std::string::npos) << l;
  }
  const std::string msh = slurp(dir + "/n.msh");
  EXPECT_NE(msh.find("3 1 \"bone (label 1)\""), std::string::npos);
  EXPECT_NE(msh.find("3 2 \"bone (label 2)\""), std::string::npos);
  m.materials[2].name = "boundary";
  ASSERT_TRUE(writeMesh(m, dir + "/r.feb").isOk());
  EXPECT_NE(slurp(dir + "/r.feb").find("<material id=\"3\" name=\"boundary_3\""), std::string::npos);
}

TEST(MeshIO, DefaultPropertiesWarningNamesTheMaterialsWithout) {
  const TetMesh m = twoMaterialCube();  // labels 2 and 5
  MeshingParameters params;
  ExportOptions o = exportOptionsFrom(params);
  const std::string w = defaultPropertiesWarning(m, "out/knee.inp", o);
  for (const char* s : {"'out/knee.inp'", "2 materials", "label 2 (trabecular bone)", "label 5 (Implant",
                        "E = 1000 MPa", "material.<label>.E"})
    EXPECT_NE(w.find(s), std::string::npos) << s << " in: " << w;
  EXPECT_NE(defaultPropertiesWarning(m, "k.feb", o), "");
  EXPECT_EQ(defaultPropertiesWarning(m, "k.vtu", o), "");  // not a solver deck
  EXPECT_EQ(defaultPropertiesWarning(m, "k.msh", o), "");
  ASSERT_TRUE(setParameter(params, "material.2.E", "300").isOk());
  o = exportOptionsFrom(params);
  const std::string one = defaultPropertiesWarning(m, "k.inp", o);
  EXPECT_NE(one.find("1 material has"), std::string::npos) << one;
  EXPECT_EQ(one.find("label 2"), std::string::npos) << one;
  ASSERT_TRUE(setParameter(params, "material.5.nu", "0.34").isOk());
  EXPECT_EQ(defaultPropertiesWarning(m, "k.inp", exportOptionsFrom(params)), "");
  MeshingParameters chosen;
  ASSERT_TRUE(setParameter(chosen, "default.E", "500").isOk());
  EXPECT_EQ(defaultPropertiesWarning(m, "k.inp", exportOptionsFrom(chosen)), "");
}

TEST(MeshIO, UnknownExtensionFailsAndLeavesNoFile) {
  const TetMesh m = twoMaterialCube();
  const std::string dir = tmpDir();
  for (const char* name : {"unknown.xyz", "noextension"}) {
    const std::string path = dir + "/" + name;
    fs::remove(path);
    const Status s = writeMesh(m, path);
    EXPECT_EQ(s.code(), ErrorCode::InvalidArgument) << name;
    EXPECT_NE(s.message().find(".vtu"), std::string::npos) << "lists the supported formats: " << s.message();
    EXPECT_NE(s.message().find(".inp"), std::string::npos) << s.message();
    EXPECT_FALSE(fs::exists(path));
    EXPECT_FALSE(anyFileStartingWith(dir, std::string(name).substr(0, 7) + ".tmp"));
  }
  // An empty mesh is refused too.
  EXPECT_EQ(writeMesh(TetMesh{}, dir + "/empty.vtu").code(), ErrorCode::InvalidArgument);
  EXPECT_FALSE(fs::exists(dir + "/empty.vtu"));
}

TEST(MeshIO, WriteIntoMissingFolderFailsAndLeavesNoFile) {
  const TetMesh m = twoMaterialCube();
  const std::string dir = tmpDir() + "/no_such_folder";
  fs::remove_all(dir);
  for (const auto& ext : supportedMeshExtensions()) {
    const Status s = writeMesh(m, dir + "/out" + ext);
    EXPECT_EQ(s.code(), ErrorCode::WriteFailed) << ext << ": " << s.message();
    EXPECT_NE(s.message().find("no_such_folder"), std::string::npos) << s.message();
  }
  EXPECT_FALSE(fs::exists(dir));
}

TEST(MeshIO, OverwriteIsAtomicAndLeavesNoTemporaryFiles) {
  const std::string dir = tmpDir() + "/atomic";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const TetMesh a = twoMaterialCube();
  const TetMesh b = cubeGridMesh(2, 1.0, {0, 0, 0}, [](const Vec3&) { return 7; });
  for (const auto& ext : supportedMeshExtensions()) {
    ASSERT_TRUE(writeMesh(a, dir + "/x" + ext).isOk());
    ASSERT_TRUE(writeMesh(b, dir + "/x" + ext).isOk());
  }
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    ++files;
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  }
  EXPECT_EQ(files, supportedMeshExtensions().size());
  auto back = readMesh(dir + "/x.vtu");
  ASSERT_TRUE(back.isOk());
  EXPECT_EQ(back->tets.size(), b.tets.size());
}

/// The files of `dir` (hidden ones too) with their content.
std::map<std::string, std::string> folderContent(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    files[e.path().filename().string()] = text.str();
  }
  return files;
}

TEST(MeshIO, EveryWriterDetectsAFullDiskAndLeavesNoFile) {
  // A file size limit makes writes past it fail (EFBIG), as a full disk makes them fail (ENOSPC).
  const std::string dir = tmpDir() + "/full";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const TetMesh m = twoMaterialCube();
  struct rlimit old {};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
  const auto previous = std::signal(SIGXFSZ, SIG_IGN);
  for (const auto& ext : supportedMeshExtensions()) {
    struct rlimit small = old;
    small.rlim_cur = 300;
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
    const Status s = writeMesh(m, dir + "/cut" + ext);
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &old), 0);
    EXPECT_EQ(s.code(), ErrorCode::WriteFailed) << ext << ": " << s.message();
    EXPECT_NE(s.message().find("'" + dir + "/cut" + ext + "'"), std::string::npos) << s.message();
    EXPECT_EQ(s.message().find(".tmp"), std::string::npos) << s.message();
    EXPECT_EQ(s.message().find('\n'), std::string::npos) << s.message();
  }
  std::signal(SIGXFSZ, previous);
  EXPECT_TRUE(folderContent(dir).empty());
}

TEST(MeshIO, OutputTransactionWritesAllOrNothing) {
  const std::string dir = tmpDir() + "/transaction";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir + "/old.vtu") << "old";
  const auto before = folderContent(dir);
  const TetMesh m = twoMaterialCube();
  auto mesh = [&](const std::string& tmp) { return writeMesh(m, tmp); };
  {  // the second output fails: nothing is written, the existing file is kept
    OutputTransaction t;
    ASSERT_TRUE(t.stage(dir + "/old.vtu", mesh).isOk());
    const Status s = t.stage(dir + "/new.inp", [&](const std::string& tmp) {
      return Status(ErrorCode::WriteFailed, "Cannot write '" + tmp + "': disk full");
    });
    EXPECT_EQ(s.code(), ErrorCode::WriteFailed);
    EXPECT_NE(s.message().find("'" + dir + "/new.inp'"), std::string::npos) << s.message();
    EXPECT_EQ(t.commit().code(), ErrorCode::WriteFailed);
  }
  EXPECT_EQ(folderContent(dir), before);
  {  // abandoned before commit: nothing is written
    OutputTransaction t;
    ASSERT_TRUE(t.stage(dir + "/old.vtu", mesh).isOk());
    ASSERT_TRUE(t.stage(dir + "/new.msh", mesh).isOk());
  }
  EXPECT_EQ(folderContent(dir), before);
  {  // a rename fails half way (the second target became a folder): the first is put back
    OutputTransaction t;
    ASSERT_TRUE(t.stage(dir + "/old.vtu", mesh).isOk());
    ASSERT_TRUE(t.stage(dir + "/new.vtu", mesh).isOk());
    ASSERT_TRUE(t.stage(dir + "/blocked.inp", mesh).isOk());
    fs::create_directories(dir + "/blocked.inp/inside");
    const Status s = t.commit();
    EXPECT_EQ(s.code(), ErrorCode::WriteFailed);
    EXPECT_NE(s.message().find("blocked.inp"), std::string::npos) << s.message();
    fs::remove_all(dir + "/blocked.inp");
  }
  EXPECT_EQ(folderContent(dir), before);
  {  // all succeed: all renamed, no temporary or backup file left
    OutputTransaction t;
    ASSERT_TRUE(t.stage(dir + "/old.vtu", mesh).isOk());
    ASSERT_TRUE(t.stage(dir + "/new.inp", mesh).isOk());
    ASSERT_TRUE(t.commit().isOk());
  }
  const auto after = folderContent(dir);
  EXPECT_EQ(after.size(), 2u);
  EXPECT_TRUE(readMesh(dir + "/old.vtu").isOk());
  EXPECT_TRUE(readMesh(dir + "/new.inp").isOk());
}

TEST(MeshIO, OutputTransactionHonoursCancelUpToTheLastRename) {
  const std::string dir = tmpDir() + "/transaction_cancel";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir + "/old.vtu") << "old";
  const auto before = folderContent(dir);
  const TetMesh m = twoMaterialCube();
  std::atomic<bool> cancel{false};
  auto mesh = [&](const std::string& tmp) { return writeMesh(m, tmp); };
  {  // canceled between two writes: the next stage writes nothing, commit refuses
    OutputTransaction t;
    t.setCancelFlag(&cancel);
    ASSERT_TRUE(t.stage(dir + "/old.vtu", mesh).isOk());
    cancel = true;
    bool wrote = false;
    const Status s = t.stage(dir + "/new.inp", [&](const std::string& tmp) {
      wrote = true;
      return writeMesh(m, tmp);
    });
    EXPECT_EQ(s.code(), ErrorCode::Canceled);
    EXPECT_FALSE(wrote);
    EXPECT_EQ(t.commit().code(), ErrorCode::Canceled);
  }
  EXPECT_EQ(folderContent(dir), before);
  cancel = false;
  {  // canceled after every write, before the renames
    OutputTransaction t;
    t.setCancelFlag(&cancel);
    ASSERT_TRUE(t.stage(dir + "/old.vtu", mesh).isOk());
    ASSERT_TRUE(t.stage(dir + "/new.inp", mesh).isOk());
    cancel = true;
    EXPECT_EQ(t.commit().code(), ErrorCode::Canceled);
  }
  EXPECT_EQ(folderContent(dir), before);
}

TEST(MeshIO, TemporaryFilesNameTheirProcessAndStaleOnesAreRemoved) {
  EXPECT_EQ(temporaryFileOwner(".mesh.femesher-tmp-1234-0.vtu"), 1234);
  EXPECT_EQ(temporaryFileOwner(".knee.femesher-bak-77-12.nii.gz"), 77);
  EXPECT_EQ(temporaryFileOwner("..m.femesher-tmp-5-0.femesher-tmp-5-1.vtu"), 5);  // nested
  EXPECT_EQ(temporaryFileOwner(".report.femesher-tmp-9-0"), 9);                   // no extension
  for (const char* other : {"mesh.femesher-tmp-1234-0.vtu", ".mesh.tmp1234_0.vtu",
                            ".mesh.femesher-tmp-x-0.vtu", ".mesh.femesher-tmp-12-0.vtu~",
                            ".mesh.femesher-tmp-12-0.a.b.c", ".femesher-tmp-12-0.vtu"})
    EXPECT_EQ(temporaryFileOwner(other), 0) << other;
  // The names a transaction makes are the pattern, with this process's id.
  const std::string dir = tmpDir() + "/stale";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const long self = long(::getpid());
  std::vector<long> owners;
  EXPECT_TRUE(writeAtomically(dir + "/a.nii.gz", [&](const std::string& tmp) {
                owners.push_back(temporaryFileOwner(fs::path(tmp).filename().string()));
                std::ofstream(tmp) << "x";
                return Status::ok();
              }).isOk());
  EXPECT_EQ(owners, std::vector<long>{self});
  // A process that has ended: fork a child and reap it.
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  int ws = 0;
  ::waitpid(dead, &ws, 0);
  const std::string stale = ".m.femesher-tmp-" + std::to_string(dead) + "-0.vtu";
  const std::string mine = ".m.femesher-tmp-" + std::to_string(self) + "-0.vtu";
  const std::string parent = ".m.femesher-tmp-" + std::to_string(::getppid()) + "-0.vtu";
  for (const auto& n : {stale, mine, parent, std::string("m.femesher-tmp-") + std::to_string(dead) + "-0.vtu"})
    std::ofstream(dir + "/" + n) << "x";
  const auto removed = removeStaleTemporaries({dir + "/out.vtu"});
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_EQ(fs::path(removed[0]).filename().string(), stale);
  EXPECT_FALSE(fs::exists(dir + "/" + stale));
  EXPECT_TRUE(fs::exists(dir + "/" + mine));
  EXPECT_TRUE(fs::exists(dir + "/" + parent));
}

TEST(MeshIO, TwoOutputsThatAreOneFileAreRefused) {
  const std::string dir = tmpDir() + "/distinct";
  fs::create_directories(dir);
  EXPECT_TRUE(checkDistinctOutputs({dir + "/a.vtu", dir + "/a.inp", "", ""}).isOk());
  const Status s = checkDistinctOutputs({dir + "/a.vtu", dir + "/../distinct/./a.vtu"});
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  EXPECT_NE(s.message().find("'" + dir + "/a.vtu'"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("'" + dir + "/../distinct/./a.vtu'"), std::string::npos) << s.message();
  fs::remove(dir + "/link.vtu");
  std::ofstream(dir + "/target.vtu") << "x";
  fs::create_symlink("target.vtu", dir + "/link.vtu");
  EXPECT_EQ(checkDistinctOutputs({dir + "/link.vtu", dir + "/target.vtu"}).code(),
            ErrorCode::InvalidArgument);
}

TEST(MeshIO, BadFilesGiveClearErrors) {
  const std::string dir = tmpDir() + "/bad";
  fs::create_directories(dir);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + "/" + name, std::ios::binary) << text;
    return dir + "/" + name;
  };
  auto expectError = [](const std::string& path, ErrorCode code, const std::string& hint) {
    auto r = readMesh(path);
    ASSERT_FALSE(r.isOk()) << path;
    EXPECT_EQ(r.status().code(), code) << path << ": " << r.status().message();
    EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find(hint), std::string::npos) << r.status().message();
  };
  expectError(dir + "/missing.vtu", ErrorCode::FileNotFound, "does not exist");
  expectError(write("garbage.vtu", "this is not xml"), ErrorCode::UnreadableFile, "VTK XML");
  expectError(write("x.obj", "v 0 0 0"), ErrorCode::UnreadableFile, ".msh");
  expectError(write("v2.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"), ErrorCode::UnreadableFile, "4.1");
  expectError(write("bin.msh", "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n"), ErrorCode::UnreadableFile, "binary");
  expectError(write("notmsh.msh", "hello"), ErrorCode::CorruptFile, "outside a section");
  expectError(write("nonodes.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"), ErrorCode::CorruptFile, "$Nodes");
  expectError(write("nomedit.mesh", "solid x\n"), ErrorCode::UnreadableFile, "unknown Medit keyword");
  expectError(write("noheader.mesh", "Dimension 3\nVertices\n0\nEnd\n"), ErrorCode::UnreadableFile,
              "MeshVersionFormatted");
  expectError(write("badindex.mesh",
                    "MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n"
                    "Tetrahedra\n1\n1 2 3 9 1\nEnd\n"),
              ErrorCode::CorruptFile, "vertex 9");
  expectError(write("dim2.mesh", "MeshVersionFormatted 2\nDimension 2\n"), ErrorCode::UnreadableFile, "2-D");

  // Truncated copies of good files.
  const TetMesh m = twoMaterialCube();
  for (const char* ext : {".msh", ".mesh", ".vtu"}) {
    const std::string good = dir + "/good" + ext;
    ASSERT_TRUE(writeMesh(m, good).isOk());
    const std::string text = slurp(good);
    const std::string cut = write(std::string("cut") + ext, text.substr(0, text.size() / 2));
    auto r = readMesh(cut);
    ASSERT_FALSE(r.isOk()) << ext;
    EXPECT_EQ(r.status().code(), ErrorCode::CorruptFile) << ext << ": " << r.status().message();
  }
  // A VTU without the `labels` array.
  {
    std::string text = slurp(dir + "/good.vtu");
    for (size_t p; (p = text.find("Name=\"labels\"")) != std::string::npos;) text.replace(p, 13, "Name=\"nolabs\"");
    expectError(write("nolabels.vtu", text), ErrorCode::UnreadableFile, "labels");
  }
}

TEST(MeshIO, VersionAndProvenanceInFiles) {
  const TetMesh m = twoMaterialCube();
  const std::string dir = tmpDir();
  ExportOptions o;
  o.provenance = "femesher test run";
  ASSERT_TRUE(writeMesh(m, dir + "/prov.inp", o).isOk());
  const std::string inp = slurp(dir + "/prov.inp");
  EXPECT_NE(inp.find(std::string("FEMesher ") + FEMESHER_VERSION), std::string::npos);
  EXPECT_NE(inp.find("femesher test run"), std::string::npos);
}
