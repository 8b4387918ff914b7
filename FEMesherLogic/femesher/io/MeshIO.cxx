// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Version.h>
#include <femesher/io/AtomicFile.h>
#include <femesher/io/MeshIO.h>

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkFieldData.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkUnstructuredGridWriter.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace femesher {

namespace {

const ElasticProperties& propsFor(const ExportOptions& o, int32_t label) {
  auto it = o.materialProperties.find(label);
  return it != o.materialProperties.end() ? it->second : o.defaultMaterial;
}

std::string materialName(const TetMesh& m, int32_t label) {
  const Material* mat = findMaterial(m.materials, label);
  return mat && !mat->name.empty() ? mat->name : "label " + std::to_string(label);
}

/// Upper-case A-Z0-9_ name, at most 80 characters (Abaqus/CalculiX identifiers).
std::string safeName(const std::string& s) {
  std::string o;
  for (char c : s) {
    const unsigned char u = static_cast<unsigned char>(c);
    o += std::isalnum(u) ? char(std::toupper(u)) : '_';
  }
  while (o.find("__") != std::string::npos) o.replace(o.find("__"), 2, "_");
  if (o.size() > 60) o.resize(60);
  return o;
}

std::vector<int32_t> meshLabels(const TetMesh& m) {
  std::set<int32_t> s(m.tetLabels.begin(), m.tetLabels.end());
  return {s.begin(), s.end()};
}

Status ioError(const std::string& path) {
  return {ErrorCode::WriteFailed, "Cannot write '" + path + "' (disk full or no permission?)"};
}

template <class F>
Status writeText(const std::string& path, F&& body) {
  return writeAtomically(path, [&](const std::string& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "w");
    if (!f) return ioError(path);
    body(f);
    const bool ok = std::ferror(f) == 0;
    if (std::fclose(f) != 0 || !ok) return ioError(path);
    return Status::ok();
  });
}

vtkSmartPointer<vtkUnstructuredGrid> toGrid(const TetMesh& m, const ExportOptions& o, bool fieldData);

Status writeVtu(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  auto ug = toGrid(m, o, true);
  return writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkXMLUnstructuredGridWriter> w;
    w->SetFileName(tmp.c_str());
    w->SetInputData(ug);
    w->SetDataModeToAppended();
    w->SetCompressorTypeToZLib();
    if (w->Write() != 1) return ioError(path);
    return Status::ok();
  });
}

/// Legacy VTK 4.2 with Slicer's header convention ("3D Slicer output. SPACE=LPS"): read by Slicer,
/// ParaView and readers that do not understand string field data (meshio).
Status writeLegacyVtk(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  auto ug = toGrid(m, o, false);
  return writeAtomically(path, [&](const std::string& tmp) {
    vtkNew<vtkUnstructuredGridWriter> w;
    w->SetFileName(tmp.c_str());
    w->SetInputData(ug);
    w->SetFileVersion(42);
    w->SetFileTypeToBinary();
    w->SetHeader("3D Slicer output. SPACE=LPS");
    if (w->Write() != 1) return ioError(path);
    return Status::ok();
  });
}

vtkSmartPointer<vtkUnstructuredGrid> toGrid(const TetMesh& m, const ExportOptions& o, bool fieldData) {
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(vtkIdType(m.points.size()));
  for (size_t i = 0; i < m.points.size(); ++i) pts->SetPoint(vtkIdType(i), m.points[i].data());
  auto ug = vtkSmartPointer<vtkUnstructuredGrid>::New();
  ug->SetPoints(pts);
  ug->Allocate(vtkIdType(m.tets.size()));
  for (const auto& t : m.tets) {
    const vtkIdType ids[4] = {t[0], t[1], t[2], t[3]};
    ug->InsertNextCell(VTK_TETRA, 4, ids);
  }
  vtkNew<vtkIntArray> labels;
  labels->SetName("labels");
  labels->SetNumberOfValues(vtkIdType(m.tetLabels.size()));
  for (size_t i = 0; i < m.tetLabels.size(); ++i) labels->SetValue(vtkIdType(i), m.tetLabels[i]);
  ug->GetCellData()->AddArray(labels);
  ug->GetCellData()->SetActiveScalars("labels");
  if (!fieldData) return ug;
  vtkNew<vtkStringArray> space;
  space->SetName("SPACE");
  space->InsertNextValue("LPS");
  ug->GetFieldData()->AddArray(space);
  vtkNew<vtkIntArray> ids;
  ids->SetName("MaterialIds");
  vtkNew<vtkStringArray> names;
  names->SetName("MaterialNames");
  for (const auto& mat : m.materials) {
    ids->InsertNextValue(mat.id);
    names->InsertNextValue(mat.name);
  }
  ug->GetFieldData()->AddArray(ids);
  ug->GetFieldData()->AddArray(names);
  vtkNew<vtkStringArray> version;
  version->SetName("FEMesherVersion");
  version->InsertNextValue(FEMESHER_VERSION);
  ug->GetFieldData()->AddArray(version);
  if (!o.provenance.empty()) {
    vtkNew<vtkStringArray> prov;
    prov->SetName("Provenance");
    prov->InsertNextValue(o.provenance);
    ug->GetFieldData()->AddArray(prov);
  }
  return ug;
}

/// Abaqus C3D4 face numbering (1-based): S1 = 1-2-3, S2 = 1-4-2, S3 = 2-4-3, S4 = 3-4-1.
int abaqusFace(const std::array<int32_t, 4>& tet, const std::array<int32_t, 3>& tri) {
  static const int F[4][3] = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
  std::array<int32_t, 3> s = tri;
  std::sort(s.begin(), s.end());
  for (int f = 0; f < 4; ++f) {
    std::array<int32_t, 3> q{tet[F[f][0]], tet[F[f][1]], tet[F[f][2]]};
    std::sort(q.begin(), q.end());
    if (q == s) return f + 1;
  }
  return 0;
}

Status writeInp(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const auto labels = meshLabels(m);
  const auto tris = extractInterfaces(m);
  std::map<int32_t, std::string> elset;
  std::set<std::string> used;
  for (int32_t l : labels) {
    std::string n = "M" + std::to_string(l) + "_" + safeName(materialName(m, l));
    while (used.count(n)) n += "_";
    used.insert(n);
    elset[l] = n;
  }
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "*HEADING\nFEMesher %s conformal multi-material mesh, LPS mm%s%s\n",
                 FEMESHER_VERSION, o.provenance.empty() ? "" : ", ", o.provenance.c_str());
    std::fprintf(f, "** Units: mm, N, MPa, tonne/mm^3. Materials: elastic properties are defaults;\n"
                    "** override them with femesher --set material.<label>.E=... .nu=...\n");
    std::fprintf(f, "*NODE, NSET=ALLNODES\n");
    for (size_t i = 0; i < m.points.size(); ++i)
      std::fprintf(f, "%zu, %.17g, %.17g, %.17g\n", i + 1, m.points[i][0], m.points[i][1], m.points[i][2]);
    // Elements grouped by material, 1-based ids in mesh order.
    for (int32_t l : labels) {
      std::fprintf(f, "*ELEMENT, TYPE=C3D4, ELSET=%s\n", elset[l].c_str());
      for (size_t t = 0; t < m.tets.size(); ++t)
        if (m.tetLabels[t] == l)
          std::fprintf(f, "%zu, %d, %d, %d, %d\n", t + 1, m.tets[t][0] + 1, m.tets[t][1] + 1,
                       m.tets[t][2] + 1, m.tets[t][3] + 1);
    }
    // Outer boundary nodes.
    std::set<int32_t> boundary;
    for (const auto& t : tris)
      if (t.labelB == kExteriorLabel) boundary.insert(t.v.begin(), t.v.end());
    std::fprintf(f, "*NSET, NSET=BOUNDARY\n");
    int col = 0;
    for (int32_t v : boundary) {
      std::fprintf(f, "%d%s", v + 1, (++col % 16 == 0) ? "\n" : ", ");
    }
    if (col % 16 != 0) std::fprintf(f, "\n");
    // Element-based surfaces per interface (from the lower label's side) and outer boundary.
    std::map<std::pair<int32_t, int32_t>, std::vector<std::pair<int32_t, int>>> surfaces;
    for (const auto& t : tris) {
      const int face = abaqusFace(m.tets[size_t(t.tetA)], t.v);
      if (face > 0) surfaces[{t.labelA, t.labelB}].push_back({t.tetA, face});
    }
    for (const auto& [key, faces] : surfaces) {
      const std::string name = key.second == kExteriorLabel
                                   ? "OUTER_" + std::to_string(key.first)
                                   : "IF_" + std::to_string(key.first) + "_" + std::to_string(key.second);
      std::fprintf(f, "*SURFACE, NAME=%s, TYPE=ELEMENT\n", name.c_str());
      for (const auto& [tet, face] : faces) std::fprintf(f, "%d, S%d\n", tet + 1, face);
    }
    for (int32_t l : labels) {
      const ElasticProperties& p = propsFor(o, l);
      const std::string mat = "MAT_" + elset[l];
      std::fprintf(f, "*SOLID SECTION, ELSET=%s, MATERIAL=%s\n,\n", elset[l].c_str(), mat.c_str());
      std::fprintf(f, "*MATERIAL, NAME=%s\n*ELASTIC\n%.10g, %.10g\n*DENSITY\n%.10g\n", mat.c_str(),
                   p.youngsModulus, p.poissonRatio, p.density);
    }
  });
}

std::string interfaceName(const TetMesh& m, int32_t a, int32_t b) {
  if (b == kExteriorLabel) return "boundary_" + std::to_string(a);
  return "interface_" + std::to_string(a) + "_" + std::to_string(b);
}

Status writeMsh(const TetMesh& m, const std::string& path, const ExportOptions&) {
  const auto labels = meshLabels(m);
  const auto tris = extractInterfaces(m);
  std::map<std::pair<int32_t, int32_t>, std::vector<size_t>> patches;
  for (size_t i = 0; i < tris.size(); ++i) patches[{tris[i].labelA, tris[i].labelB}].push_back(i);
  // Tags: volumes 1..L (physical tag = label id when positive, else 10000+index), surfaces 1..P.
  std::map<int32_t, int> volTag, volPhys;
  int tag = 1;
  for (int32_t l : labels) {
    volTag[l] = tag++;
    volPhys[l] = l > 0 ? l : 100000 + volTag[l];
  }
  std::map<std::pair<int32_t, int32_t>, int> surfTag;
  tag = 1;
  for (const auto& kv : patches) surfTag[kv.first] = tag++;
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    std::fprintf(f, "$PhysicalNames\n%zu\n", labels.size() + patches.size());
    for (int32_t l : labels) std::fprintf(f, "3 %d \"%s\"\n", volPhys[l], materialName(m, l).c_str());
    for (const auto& kv : patches)
      std::fprintf(f, "2 %d \"%s\"\n", 200000 + surfTag[kv.first],
                   interfaceName(m, kv.first.first, kv.first.second).c_str());
    std::fprintf(f, "$EndPhysicalNames\n");
    // Entities with bounding boxes.
    auto bbox = [&](const std::vector<int32_t>& verts, double* b) {
      b[0] = b[1] = b[2] = 1e300;
      b[3] = b[4] = b[5] = -1e300;
      for (int32_t v : verts)
        for (int k = 0; k < 3; ++k) {
          b[k] = std::min(b[k], m.points[v][k]);
          b[3 + k] = std::max(b[3 + k], m.points[v][k]);
        }
    };
    std::fprintf(f, "$Entities\n0 0 %zu %zu\n", patches.size(), labels.size());
    for (const auto& [key, ids] : patches) {
      std::vector<int32_t> verts;
      for (size_t i : ids) verts.insert(verts.end(), tris[i].v.begin(), tris[i].v.end());
      double b[6];
      bbox(verts, b);
      std::fprintf(f, "%d %.17g %.17g %.17g %.17g %.17g %.17g 1 %d 0\n", surfTag[key], b[0], b[1],
                   b[2], b[3], b[4], b[5], 200000 + surfTag[key]);
    }
    for (int32_t l : labels) {
      std::vector<int32_t> verts;
      std::vector<int> bounding;
      for (size_t t = 0; t < m.tets.size(); ++t)
        if (m.tetLabels[t] == l) verts.insert(verts.end(), m.tets[t].begin(), m.tets[t].end());
      for (const auto& kv : patches)
        if (kv.first.first == l || kv.first.second == l) bounding.push_back(surfTag[kv.first]);
      double b[6];
      bbox(verts, b);
      std::fprintf(f, "%d %.17g %.17g %.17g %.17g %.17g %.17g 1 %d %zu", volTag[l], b[0], b[1],
                   b[2], b[3], b[4], b[5], volPhys[l], bounding.size());
      for (int s : bounding) std::fprintf(f, " %d", s);
      std::fprintf(f, "\n");
    }
    std::fprintf(f, "$EndEntities\n");
    // All nodes in one block attached to the first volume (allowed: nodes of a higher-dimensional
    // entity may be used by its boundary's elements too in a non-parametric mesh).
    const size_t np = m.points.size();
    std::fprintf(f, "$Nodes\n1 %zu 1 %zu\n3 %d 0 %zu\n", np, np, labels.empty() ? 1 : volTag[labels[0]], np);
    for (size_t i = 0; i < np; ++i) std::fprintf(f, "%zu\n", i + 1);
    for (size_t i = 0; i < np; ++i)
      std::fprintf(f, "%.17g %.17g %.17g\n", m.points[i][0], m.points[i][1], m.points[i][2]);
    std::fprintf(f, "$EndNodes\n");
    const size_t ne = tris.size() + m.tets.size();
    std::fprintf(f, "$Elements\n%zu %zu 1 %zu\n", patches.size() + labels.size(), ne, ne);
    size_t id = 1;
    for (const auto& [key, ids] : patches) {
      std::fprintf(f, "2 %d 2 %zu\n", surfTag[key], ids.size());
      for (size_t i : ids)
        std::fprintf(f, "%zu %d %d %d\n", id++, tris[i].v[0] + 1, tris[i].v[1] + 1, tris[i].v[2] + 1);
    }
    for (int32_t l : labels) {
      size_t count = 0;
      for (int32_t x : m.tetLabels) count += x == l;
      std::fprintf(f, "3 %d 4 %zu\n", volTag[l], count);
      for (size_t t = 0; t < m.tets.size(); ++t)
        if (m.tetLabels[t] == l)
          std::fprintf(f, "%zu %d %d %d %d\n", id++, m.tets[t][0] + 1, m.tets[t][1] + 1,
                       m.tets[t][2] + 1, m.tets[t][3] + 1);
    }
    std::fprintf(f, "$EndElements\n");
  });
}

Status writeMedit(const TetMesh& m, const std::string& path, const ExportOptions&) {
  const auto tris = extractInterfaces(m);
  std::map<std::pair<int32_t, int32_t>, int> ref;
  for (const auto& t : tris) ref.emplace(std::make_pair(t.labelA, t.labelB), int(ref.size()) + 1);
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "MeshVersionFormatted 2\nDimension 3\n");
    std::fprintf(f, "# FEMesher %s: tetrahedra ref = material label; triangle ref = interface:\n", FEMESHER_VERSION);
    for (const auto& [k, r] : ref)
      std::fprintf(f, "#   %d = %s\n", r, interfaceName(m, k.first, k.second).c_str());
    std::fprintf(f, "Vertices\n%zu\n", m.points.size());
    for (const auto& p : m.points) std::fprintf(f, "%.17g %.17g %.17g 0\n", p[0], p[1], p[2]);
    std::fprintf(f, "Triangles\n%zu\n", tris.size());
    for (const auto& t : tris)
      std::fprintf(f, "%d %d %d %d\n", t.v[0] + 1, t.v[1] + 1, t.v[2] + 1, ref[{t.labelA, t.labelB}]);
    std::fprintf(f, "Tetrahedra\n%zu\n", m.tets.size());
    for (size_t t = 0; t < m.tets.size(); ++t)
      std::fprintf(f, "%d %d %d %d %d\n", m.tets[t][0] + 1, m.tets[t][1] + 1, m.tets[t][2] + 1,
                   m.tets[t][3] + 1, m.tetLabels[t]);
    std::fprintf(f, "End\n");
  });
}

std::string xmlEscape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else if (c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

Status writeFeb(const TetMesh& m, const std::string& path, const ExportOptions& o) {
  const auto labels = meshLabels(m);
  return writeText(path, [&](std::FILE* f) {
    std::fprintf(f, "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n");
    std::fprintf(f, "<!-- FEMesher %s: LPS mm; materials neo-Hookean from E and nu -->\n", FEMESHER_VERSION);
    std::fprintf(f, "<febio_spec version=\"2.5\">\n\t<Module type=\"solid\"/>\n\t<Material>\n");
    int matId = 1;
    std::map<int32_t, int> mid;
    for (int32_t l : labels) {
      const ElasticProperties& p = propsFor(o, l);
      mid[l] = matId;
      std::fprintf(f, "\t\t<material id=\"%d\" name=\"%s\" type=\"neo-Hookean\">\n", matId,
                   xmlEscape(materialName(m, l)).c_str());
      std::fprintf(f, "\t\t\t<density>%.10g</density>\n\t\t\t<E>%.10g</E>\n\t\t\t<v>%.10g</v>\n",
                   p.density, p.youngsModulus, p.poissonRatio);
      std::fprintf(f, "\t\t</material>\n");
      ++matId;
    }
    std::fprintf(f, "\t</Material>\n\t<Geometry>\n\t\t<Nodes name=\"AllNodes\">\n");
    for (size_t i = 0; i < m.points.size(); ++i)
      std::fprintf(f, "\t\t\t<node id=\"%zu\">%.17g,%.17g,%.17g</node>\n", i + 1, m.points[i][0],
                   m.points[i][1], m.points[i][2]);
    std::fprintf(f, "\t\t</Nodes>\n");
    for (int32_t l : labels) {
      std::fprintf(f, "\t\t<Elements type=\"tet4\" mat=\"%d\" name=\"%s\">\n", mid[l],
                   ("M" + std::to_string(l) + "_" + safeName(materialName(m, l))).c_str());
      for (size_t t = 0; t < m.tets.size(); ++t)
        if (m.tetLabels[t] == l)
          std::fprintf(f, "\t\t\t<elem id=\"%zu\">%d,%d,%d,%d</elem>\n", t + 1, m.tets[t][0] + 1,
                       m.tets[t][1] + 1, m.tets[t][2] + 1, m.tets[t][3] + 1);
      std::fprintf(f, "\t\t</Elements>\n");
    }
    std::fprintf(f, "\t</Geometry>\n</febio_spec>\n");
  });
}

Status writeStl(const TetMesh& m, const std::string& path, const ExportOptions&) {
  const auto tris = extractInterfaces(m);
  std::map<std::pair<int32_t, int32_t>, std::vector<size_t>> patches;
  for (size_t i = 0; i < tris.size(); ++i) patches[{tris[i].labelA, tris[i].labelB}].push_back(i);
  return writeText(path, [&](std::FILE* f) {
    for (const auto& [key, ids] : patches) {
      const std::string name = interfaceName(m, key.first, key.second);
      std::fprintf(f, "solid %s\n", name.c_str());
      for (size_t i : ids) {
        const Vec3 &a = m.points[tris[i].v[0]], &b = m.points[tris[i].v[1]], &c = m.points[tris[i].v[2]];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (l > 0)
          for (double& x : n) x /= l;
        std::fprintf(f, "facet normal %g %g %g\nouter loop\n", n[0], n[1], n[2]);
        for (const Vec3* p : {&a, &b, &c}) std::fprintf(f, "vertex %.17g %.17g %.17g\n", (*p)[0], (*p)[1], (*p)[2]);
        std::fprintf(f, "endloop\nendfacet\n");
      }
      std::fprintf(f, "endsolid %s\n", name.c_str());
    }
  });
}

Result<TetMesh> readVtu(const std::string& path) {
  vtkNew<vtkXMLUnstructuredGridReader> r;
  if (!r->CanReadFile(path.c_str()))
    return Result<TetMesh>(ErrorCode::UnreadableFile, "'" + path + "' is not a VTK XML unstructured grid.");
  r->SetFileName(path.c_str());
  r->Update();
  vtkUnstructuredGrid* ug = r->GetOutput();
  if (!ug || ug->GetNumberOfCells() == 0)
    return Result<TetMesh>(ErrorCode::CorruptFile, "'" + path + "' holds no cells.");
  vtkDataArray* labels = ug->GetCellData()->GetArray("labels");
  if (!labels)
    return Result<TetMesh>(ErrorCode::UnreadableFile,
                           "'" + path + "' has no cell array 'labels' (not a labelled FEMesher mesh).");
  TetMesh m;
  m.points.resize(size_t(ug->GetNumberOfPoints()));
  for (vtkIdType i = 0; i < ug->GetNumberOfPoints(); ++i) ug->GetPoint(i, m.points[size_t(i)].data());
  for (vtkIdType c = 0; c < ug->GetNumberOfCells(); ++c) {
    if (ug->GetCellType(c) != VTK_TETRA)
      return Result<TetMesh>(ErrorCode::UnreadableFile, "'" + path + "' holds cells that are not tetrahedra.");
    vtkNew<vtkIdList> ids;
    ug->GetCellPoints(c, ids);
    m.tets.push_back({int32_t(ids->GetId(0)), int32_t(ids->GetId(1)), int32_t(ids->GetId(2)), int32_t(ids->GetId(3))});
    m.tetLabels.push_back(int32_t(labels->GetTuple1(c)));
  }
  auto* ids = vtkIntArray::SafeDownCast(ug->GetFieldData()->GetAbstractArray("MaterialIds"));
  auto* names = vtkStringArray::SafeDownCast(ug->GetFieldData()->GetAbstractArray("MaterialNames"));
  std::set<int32_t> present(m.tetLabels.begin(), m.tetLabels.end());
  for (int32_t l : present) {
    Material mat{l, "label " + std::to_string(l), defaultLabelColor(l)};
    if (ids && names)
      for (vtkIdType k = 0; k < ids->GetNumberOfValues() && k < names->GetNumberOfValues(); ++k)
        if (ids->GetValue(k) == l) mat.name = names->GetValue(k);
    m.materials.push_back(mat);
  }
  return m;
}

Result<TetMesh> readMedit(const std::string& path) {
  std::ifstream in(path);
  TetMesh m;
  std::string word;
  while (in >> word) {
    if (word[0] == '#') {
      std::getline(in, word);
      continue;
    }
    if (word == "Vertices") {
      size_t n;
      in >> n;
      m.points.resize(n);
      int ref;
      for (auto& p : m.points) in >> p[0] >> p[1] >> p[2] >> ref;
    } else if (word == "Triangles") {
      size_t n;
      in >> n;
      int a, b, c, r;
      for (size_t i = 0; i < n; ++i) in >> a >> b >> c >> r;
    } else if (word == "Tetrahedra") {
      size_t n;
      in >> n;
      for (size_t i = 0; i < n; ++i) {
        std::array<int32_t, 4> t;
        int32_t r;
        in >> t[0] >> t[1] >> t[2] >> t[3] >> r;
        for (auto& x : t) --x;
        m.tets.push_back(t);
        m.tetLabels.push_back(r);
      }
    }
    if (!in) break;
  }
  if (m.tets.empty())
    return Result<TetMesh>(ErrorCode::UnreadableFile, "'" + path + "' holds no tetrahedra.");
  for (int32_t l : std::set<int32_t>(m.tetLabels.begin(), m.tetLabels.end()))
    m.materials.push_back({l, "label " + std::to_string(l), defaultLabelColor(l)});
  return m;
}

Result<TetMesh> readMsh(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  TetMesh m;
  std::map<int, int32_t> entityPhys;  // volume entity tag -> physical tag
  std::map<int, std::string> physNames;
  std::map<size_t, size_t> nodeIndex;
  while (std::getline(in, line)) {
    if (line == "$PhysicalNames") {
      size_t n;
      in >> n;
      for (size_t i = 0; i < n; ++i) {
        int dim, tag;
        std::string name;
        in >> dim >> tag;
        std::getline(in, name);
        const auto a = name.find('"'), b = name.rfind('"');
        if (dim == 3 && a != std::string::npos && b > a) physNames[tag] = name.substr(a + 1, b - a - 1);
      }
    } else if (line == "$Entities") {
      size_t np, nc, ns, nv;
      in >> np >> nc >> ns >> nv;
      std::getline(in, line);
      for (size_t i = 0; i < np + nc + ns; ++i) std::getline(in, line);
      for (size_t i = 0; i < nv; ++i) {
        std::getline(in, line);
        std::istringstream s(line);
        int tag, nphys;
        double b[6];
        s >> tag >> b[0] >> b[1] >> b[2] >> b[3] >> b[4] >> b[5] >> nphys;
        int32_t phys = tag;
        if (nphys > 0) s >> phys;
        entityPhys[tag] = phys;
      }
    } else if (line == "$Nodes") {
      size_t blocks, total, mn, mx;
      in >> blocks >> total >> mn >> mx;
      for (size_t b = 0; b < blocks; ++b) {
        int dim, tag, param;
        size_t n;
        in >> dim >> tag >> param >> n;
        std::vector<size_t> tags(n);
        for (auto& t : tags) in >> t;
        for (size_t i = 0; i < n; ++i) {
          Vec3 p;
          in >> p[0] >> p[1] >> p[2];
          nodeIndex[tags[i]] = m.points.size();
          m.points.push_back(p);
        }
      }
    } else if (line == "$Elements") {
      size_t blocks, total, mn, mx;
      in >> blocks >> total >> mn >> mx;
      for (size_t b = 0; b < blocks; ++b) {
        int dim, tag, type;
        size_t n;
        in >> dim >> tag >> type >> n;
        const int nn = type == 4 ? 4 : type == 2 ? 3 : type == 1 ? 2 : 1;
        for (size_t i = 0; i < n; ++i) {
          size_t id, v[4];
          in >> id;
          for (int k = 0; k < nn; ++k) in >> v[k];
          if (type == 4) {
            m.tets.push_back({int32_t(nodeIndex[v[0]]), int32_t(nodeIndex[v[1]]),
                              int32_t(nodeIndex[v[2]]), int32_t(nodeIndex[v[3]])});
            m.tetLabels.push_back(entityPhys.count(tag) ? entityPhys[tag] : tag);
          }
        }
      }
    }
  }
  if (m.tets.empty())
    return Result<TetMesh>(ErrorCode::UnreadableFile, "'" + path + "' holds no tetrahedra (MSH 4.1 expected).");
  for (int32_t l : std::set<int32_t>(m.tetLabels.begin(), m.tetLabels.end()))
    m.materials.push_back({l, physNames.count(l) ? physNames[l] : "label " + std::to_string(l),
                           defaultLabelColor(l)});
  return m;
}

}  // namespace

ExportOptions exportOptionsFrom(const MeshingParameters& params) {
  ExportOptions o;
  o.defaultMaterial = params.defaultMaterial;
  o.materialProperties = params.materialProperties;
  return o;
}

std::vector<std::string> supportedMeshExtensions() {
  return {".vtu", ".vtk", ".inp", ".msh", ".mesh", ".feb", ".stl"};
}

Status writeMesh(const TetMesh& mesh, const std::string& path, const ExportOptions& options) {
  const std::string ext = fileExtension(path);
  if (mesh.tets.empty()) return {ErrorCode::InvalidArgument, "Cannot write '" + path + "': the mesh is empty."};
  try {
    if (ext == ".vtu") return writeVtu(mesh, path, options);
    if (ext == ".vtk") return writeLegacyVtk(mesh, path, options);
    if (ext == ".inp") return writeInp(mesh, path, options);
    if (ext == ".msh") return writeMsh(mesh, path, options);
    if (ext == ".mesh") return writeMedit(mesh, path, options);
    if (ext == ".feb") return writeFeb(mesh, path, options);
    if (ext == ".stl") return writeStl(mesh, path, options);
  } catch (const Error& e) {
    return e.status();
  }
  return {ErrorCode::InvalidArgument,
          "Cannot write '" + path + "': unknown extension '" + ext +
              "'. Supported: .vtu .vtk .inp .msh .mesh .feb .stl"};
}

Result<TetMesh> readMesh(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    return Result<TetMesh>(ErrorCode::FileNotFound, "'" + path + "' does not exist.");
  const std::string ext = fileExtension(path);
  if (ext == ".vtu") return readVtu(path);
  if (ext == ".mesh") return readMedit(path);
  if (ext == ".msh") return readMsh(path);
  return Result<TetMesh>(ErrorCode::UnreadableFile,
                         "'" + path + "': reading meshes supports .vtu, .msh (4.1) and .mesh.");
}

}  // namespace femesher
